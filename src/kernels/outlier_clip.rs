//! `outlier_clip`: one round of OUTLIER-CLIP (ours, spec §4.4 step 1): a
//! pixel whose grey is more than `k·sd` above the mean of its window's kept
//! pixels (from [`super::outlier_rows`]' summaries of the kept keys) and
//! either more than `k·se` above it (signal by OUTLIER-NOISE) or more than
//! `CLIP_FAR·sd` leaves the statistics: its key becomes 0, in place. Twin:
//! `reference::outlier_clip`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_clip.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_clip",
    bindings: &[
        write("keys"),
        read("wn"),
        read("wm"),
        read("wq"),
        read("xn"),
        read("xm"),
        read("xq"),
        read("vr"),
        read("vg"),
        read("vb"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Per pixel: `2R+1` merges of row summaries (≈ 12 flops each), the
/// standard error (3 square roots and adds, ≈ 8) and the tests.
pub fn flops_per_pixel(radius: u32) -> f64 {
    (2.0 * radius as f64 + 1.0) * 12.0 + 12.0
}

/// Records one round on the kept keys `keys` (from [`super::outlier_grey`],
/// 0: invalid or clipped), whose summaries [`super::outlier_rows`] wrote
/// into `rows`; `var` is the colour's variance.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    keys: BufferSlice,
    rows: [BufferSlice; 6],
    var: [BufferSlice; 3],
) -> Result<()> {
    super::dispatch_image(
        batch,
        &DECL,
        precision,
        push,
        &[&[keys], &rows, &var],
        flops_per_pixel(push.radius),
    )
}
