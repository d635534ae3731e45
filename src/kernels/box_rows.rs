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

/// Per pixel: `2R+1` taps × (validity test, add).
pub fn flops_per_pixel(radius: u32) -> f64 {
    (2.0 * radius as f64 + 1.0) * 2.0
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
        push.width,
        push.height,
        flops_per_pixel(push.radius),
    )
}
