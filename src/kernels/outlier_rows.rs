//! `outlier_rows`: the row part of the outlier statistics (spec §4.4 step 1):
//! per pixel, (count, mean, M2) of grey over the row segment of radius R,
//! with and without the pixel itself, from [`super::outlier_grey`]'s keys.
//! Twin: [`crate::reference::outlier_rows`].

use crate::error::{Error, Result};
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::reference::outliers::DETECT_RADIUS;
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

/// Pixels per invocation (`ROWS_PX` in the shader): the keys of their joint
/// segment are loaded once.
pub const PX: u32 = 8;

/// Per pixel: `2R` neighbours × two passes × (test, 2 FMAs) ≈ 4 each, a
/// share of the joint segment's loads and decodes (≈ 2 each), and three
/// merges (≈ 12 each).
pub fn flops_per_pixel(radius: u32) -> f64 {
    let r = radius as f64;
    2.0 * r * 2.0 * 4.0 + 2.0 * (PX as f64 + 2.0 * r) / PX as f64 + 36.0
}

/// Records the row summaries of grey (`keys` from [`super::outlier_grey`])
/// into `out`: count, mean, M2 with the pixel, then without it. The
/// shader's radius is [`DETECT_RADIUS`] (unrolled); another `push.radius`
/// is an error.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    keys: BufferSlice,
    out: [BufferSlice; 6],
) -> Result<()> {
    if push.radius as usize != DETECT_RADIUS {
        return Err(Error::InvalidArgument(format!(
            "outlier_rows is compiled for radius {DETECT_RADIUS}, not {}",
            push.radius
        )));
    }
    let size = (push.width.div_ceil(PX), push.height);
    let flops = flops_per_pixel(push.radius) * PX as f64;
    super::dispatch_groups(batch, &DECL, precision, push, size, &[&[keys], &out], flops)
}
