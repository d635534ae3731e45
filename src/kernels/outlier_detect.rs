//! `outlier_detect`: outlier detection (spec §4.4 step 1) from
//! `outlier_rows`' summaries and `outlier_grey`'s keys. It queues the
//! detected pixels for [`super::outlier_median`], which finds their
//! replacements and then writes them ([`super::outlier_median::Step::Apply`]). Twin:
//! `reference::outlier_detect`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision, QUEUE_HEADER_WORDS};
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
        read("keys"),
        read("wn"),
        read("wm"),
        read("wq"),
        read("xn"),
        read("xm"),
        read("xq"),
        write("queue").sized_by_record(),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Per pixel: `2R+1` merges of row summaries (≈ 12 flops each) and the
/// 8-neighbour test (≈ 3 each).
pub fn flops_per_pixel(radius: u32) -> f64 {
    let d = 2.0 * radius as f64 + 1.0;
    d * 12.0 + 24.0
}

/// Words of the queue of a `width × height` image: the indirect dispatch
/// arguments (3), the entry count, then the entries: at most one pixel per
/// 2×2 block (OUTLIER-ISOLATED and OUTLIER-RIM never detect two
/// 8-neighbours; the kernels drop any excess, `queue_capacity` in
/// `spirv/lib/outliers.glsl`).
pub fn queue_words(width: usize, height: usize) -> usize {
    QUEUE_HEADER_WORDS + width.div_ceil(2) * height.div_ceil(2)
}

/// Records detection (`keys` from `outlier_grey`, `rows` from
/// `outlier_rows`): `excess` is zeroed (by fills) and `queue` (of
/// [`queue_words`]) receives the detected pixels. Its header is reset here
/// (x and count 0, y and z 1).
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    color: [BufferSlice; 3],
    var: [BufferSlice; 3],
    spp: BufferSlice,
    keys: BufferSlice,
    rows: [BufferSlice; 6],
    excess: [BufferSlice; 3],
    queue: BufferSlice,
) -> Result<()> {
    let words = queue_words(push.width as usize, push.height as usize);
    DECL.require(14, &queue, 4 * words as u64)?;
    batch.reset_queue(queue)?;
    for plane in excess {
        batch.fill(plane, 0);
    }
    super::dispatch_image(
        batch,
        &DECL,
        precision,
        push,
        &[&color, &var, &[spp, keys], &rows, &[queue]],
        flops_per_pixel(push.radius),
    )
}
