//! `outlier_detect`: outlier detection and replacement (spec §4.4 steps 1–3)
//! from `outlier_rows`' summaries; the median (a 32-step radix selection over
//! the window) runs only at detected pixels. Twin:
//! [`crate::reference::outlier_detect`].

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_detect.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_detect",
    bindings: &[
        read("cr"),
        read("cg"),
        read("cb"),
        read("vr"),
        read("vg"),
        read("vb"),
        read("spp"),
        read("ln"),
        read("lm"),
        read("lq"),
        read("rn"),
        read("rm"),
        read("rq"),
        read("keys"),
        write("out_r"),
        write("out_g"),
        write("out_b"),
        write("out_vr"),
        write("out_vg"),
        write("out_vb"),
        write("er"),
        write("eg"),
        write("eb"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Fraction of pixels assumed detected, for the cost estimate (measured on
/// 4-spp renders of the built-in scenes: well under 1 %).
pub const DETECTED_FRACTION: f64 = 0.01;

/// Per pixel: `2R+1` merges of three summaries (≈ 12 flops each), plus at the
/// detected fraction 33 scans of the `(2R+1)²` window (≈ 6 each).
pub fn flops_per_pixel(radius: u32) -> f64 {
    let d = 2.0 * radius as f64 + 1.0;
    d * 36.0 + DETECTED_FRACTION * 33.0 * d * d * 6.0
}

/// Records detection and replacement (`rows`, `keys` from `outlier_rows`):
/// `out` receives the replaced colour and
/// variance planes (6: R, G, B, var R, G, B), `excess` the removed `e`.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    color: [BufferSlice; 3],
    var: [BufferSlice; 3],
    spp: BufferSlice,
    rows: [BufferSlice; 6],
    keys: BufferSlice,
    out: [BufferSlice; 6],
    excess: [BufferSlice; 3],
) -> Result<()> {
    super::dispatch_outlier(
        batch,
        &DECL,
        precision,
        push,
        &[&color, &var, &[spp], &rows, &[keys], &out, &excess],
        flops_per_pixel(push.radius),
    )
}
