//! `sanitize_quads`: stage 0 of the input sanitation (spec §0.4 steps 1–2,
//! [`super::sanitize`]) for an image whose width is a multiple of 4, four
//! pixels per invocation through vec4 loads and stores. Its output and
//! counters are `sanitize`'s bit for bit; it exists because llvmpipe pays
//! per storage-buffer access, so a quarter of the accesses makes the stage
//! that much cheaper. Bindings and push constants are `sanitize`'s.
//! Twin: `reference::sanitize_quads`.

use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SanitizePush;

/// Declaration of `spirv/sanitize_quads.comp`: the bindings of
/// [`super::sanitize::BINDINGS`] and the size of [`SanitizePush`]; checked
/// against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "sanitize_quads",
    bindings: super::sanitize::BINDINGS,
    push_size: std::mem::size_of::<SanitizePush>() as u32,
};

/// Whether an image of this width can use this kernel.
pub fn fits(width: u32) -> bool {
    width > 0 && width % 4 == 0
}

/// Records stage 0 over one channel like [`super::sanitize::record`] with
/// `push.stage == 0`, on a grid of `width / 4` invocations per row; an
/// error unless [`fits`]`(push.width)`.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: SanitizePush,
    planes: [BufferSlice; 5],
    counters: BufferSlice,
) -> Result<()> {
    if !fits(push.width) || push.stage != 0 {
        return Err(Error::InvalidArgument(format!(
            "sanitize_quads: stage {} at width {} (stage 0 at a multiple of 4 only)",
            push.stage, push.width
        )));
    }
    let grid = (push.width / 4, 4.0 * super::sanitize::flops_per_pixel(0));
    super::sanitize::record_grid(batch, &DECL, precision, push, planes, counters, grid)
}
