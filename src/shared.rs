//! Structs shared between the host and the GLSL kernels: push constants.
//!
//! Each is `#[repr(C)]` + [`bytemuck::Pod`] and mirrors one `push_constant`
//! block in `spirv/` (named in its doc). Sizes and offsets are tested in
//! `tests/layout.rs`; push-constant sizes are also checked against the SPIR-V
//! by reflection (`tests/reflect.rs`).

use bytemuck::{Pod, Zeroable};

/// `spirv/finalize_stats.comp` and `spirv/finalize_covariance.comp`, block `Push`.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FinalizePush {
    pub width: u32,
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    pub _pad: u32,
}

/// `spirv/sanitize.comp`, block `Push` (spec §0.4).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SanitizePush {
    pub width: u32,
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// 0: steps 1–2 (non-finite values, variance clamp); 1: step 3 (spp < 2);
    /// 2: step 4 (variance layer missing: MAD estimate).
    pub stage: u32,
    /// 1 if the channel has a variance plane (stage 0 only reads it then).
    pub has_var: u32,
    pub _pad: [u32; 3],
}

/// `spirv/tsvd_debug.comp`, block `Push` (spec §0.6).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TsvdPush {
    pub width: u32,
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Window radius R (5 or 9 in the spec; any value ≥ 1 works).
    pub radius: u32,
}
