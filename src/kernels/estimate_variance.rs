//! `estimate_variance`: spec §0.4 step 4 (the variance layer is missing: MAD
//! estimate from local residuals). Bindings, push constants and `record` are
//! shared with [`super::sanitize`] (call `sanitize::record` with stage 2).
//! Twin: `reference::estimate_variance`.

use crate::gpu::KernelDecl;
use crate::shared::SanitizePush;

/// Declaration of `spirv/estimate_variance.comp`: the bindings all three
/// sanitation stages share ([`super::sanitize::BINDINGS`]) and the size of
/// [`SanitizePush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "estimate_variance",
    bindings: super::sanitize::BINDINGS,
    push_size: std::mem::size_of::<SanitizePush>() as u32,
};
