//! `box_rows`: the row part of a box sum (or count) over valid pixels; the
//! outlier redistribution's column kernels finish it (spec §4.4 step 4).
//! Twin: [`crate::reference::box_rows`].

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/box_rows.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "box_rows",
    bindings: &[read("value"), read("spp"), write("out_p")],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Pixels per invocation (`SPAN` in the shader): one full window sum, then
/// a running sum.
pub const SPAN: u32 = 16;

/// Per invocation: `2R+1` taps for the first pixel, then 2 per pixel, × 2
/// (validity test, add).
pub fn flops_per_invocation(radius: u32) -> f64 {
    ((2.0 * radius as f64 + 1.0) + 2.0 * SPAN as f64) * 2.0
}

/// Records `out = row sum of value` (`push.mode` 0) or the valid count (1).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    value: BufferSlice,
    spp: BufferSlice,
    out: BufferSlice,
) -> Result<()> {
    batch.dispatch(
        &DECL,
        precision,
        &[value, spp, out],
        bytemuck::bytes_of(push),
        push.width.div_ceil(SPAN),
        push.height,
        flops_per_invocation(push.radius),
    )
}
