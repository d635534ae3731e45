//! `outlier_rows`: the row part of the outlier statistics (spec §4.4 step 1):
//! per pixel, (count, mean, M2) of grey over the row segment of radius R,
//! with and without the pixel itself, from [`super::outlier_grey`]'s keys.
//! Twin: `reference::outlier_rows`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_rows.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_rows",
    bindings: &[
        read("keys"),
        write("wn"),
        write("wm"),
        write("wq"),
        write("xn"),
        write("xm"),
        write("xq"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Per pixel: `2R` neighbours × two passes × (load, decode, test, 2 FMAs)
/// ≈ 5 each, and three merges (≈ 12 each).
pub fn flops_per_pixel(radius: u32) -> f64 {
    2.0 * radius as f64 * 2.0 * 5.0 + 36.0
}

/// Records the row summaries of grey (`keys` from [`super::outlier_grey`])
/// into `out`: count, mean, M2 with the pixel, then without it.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    keys: BufferSlice,
    out: [BufferSlice; 6],
) -> Result<()> {
    super::dispatch_image(
        batch,
        &DECL,
        precision,
        push,
        &[&[keys], &out],
        flops_per_pixel(push.radius),
    )
}
