//! `sample_upsample`: a coarse sample map's priority copied to the fine
//! pixels of each 2×2 block (MAP-COARSE). Twin: `reference::sample_upsample`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::PyramidPush;

/// Declaration of `spirv/sample_upsample.comp`; checked against the SPIR-V
/// by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "sample_upsample",
    bindings: &[read("coarse").sized_by_record(), write("dst")],
    push_size: std::mem::size_of::<PyramidPush>() as u32,
};

/// Per fine pixel: two index halvings, two clamps (a copy otherwise).
pub const FLOPS_PER_PIXEL: f64 = 4.0;

/// Records the copy of the coarse priority plane `coarse` (the push's
/// `other_width × other_height`) into the fine plane `dst` (its
/// `width × height`).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &PyramidPush,
    coarse: BufferSlice,
    dst: BufferSlice,
) -> Result<()> {
    DECL.require(
        0,
        &coarse,
        4 * push.other_width as u64 * push.other_height as u64,
    )?;
    let groups: [&[BufferSlice]; 1] = [&[coarse, dst]];
    super::dispatch_image(batch, &DECL, precision, push, &groups, FLOPS_PER_PIXEL)
}
