//! `sanitize_low_spp`: spec §0.4 step 3 (variance of pixels with spp < 2).
//! Bindings, push constants and `record` are shared with
//! [`super::sanitize`] (call `sanitize::record` with stage 1).
//! Twin: `reference::sanitize_low_spp`.

use crate::gpu::KernelDecl;
use crate::shared::SanitizePush;

/// Declaration of `spirv/sanitize_low_spp.comp`: the bindings all three
/// sanitation stages share ([`super::sanitize::BINDINGS`]) and the size of
/// [`SanitizePush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "sanitize_low_spp",
    bindings: super::sanitize::BINDINGS,
    push_size: std::mem::size_of::<SanitizePush>() as u32,
};
