//! `outlier_rows`: the row part of the outlier statistics (spec §4.4 step 1):
//! per pixel, (count, mean, M2) of grey over the left and right row segments
//! of radius R. Twin: [`crate::reference::outlier_rows`].

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_rows.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_rows",
    bindings: &[
        read("cr"),
        read("cg"),
        read("cb"),
        read("spp"),
        write("ln"),
        write("lm"),
        write("lq"),
        write("rn"),
        write("rm"),
        write("rq"),
        write("keys"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Per pixel: `2R` neighbours × two passes × (3 loads, grey, 2 FMAs) ≈ 8 each.
pub fn flops_per_pixel(radius: u32) -> f64 {
    2.0 * radius as f64 * 2.0 * 8.0
}

/// Records the half-row summaries of `color` into `out` (6 planes) and the
/// grey keys (u32 per pixel) into `keys`.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    color: [BufferSlice; 3],
    spp: BufferSlice,
    out: [BufferSlice; 6],
    keys: BufferSlice,
) -> Result<()> {
    super::dispatch_outlier(
        batch,
        &DECL,
        precision,
        push,
        &[&color, &[spp], &out, &[keys]],
        flops_per_pixel(push.radius),
    )
}
