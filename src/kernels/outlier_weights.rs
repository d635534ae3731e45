//! `outlier_weights`: the redistribution weights `ρ_o = e_o / Σ_{Ω_o(43)} ŷ`
//! (or the DARK-WINDOW share) at pixels with an excess (spec §4.4 step 4),
//! dispatched indirectly over the queue of detected pixels
//! ([`super::outlier_detect`]); its modes split the outliers between the
//! 87×87 window and OUTLIER-WIDE's, marking the wide ones in the queue.
//! Twin: `reference::outlier_weights`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_weights.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_weights",
    bindings: &[
        read("er"),
        read("eg"),
        read("eb"),
        read("sr"),
        read("sg"),
        read("sb"),
        read("cnt"),
        write("rho_r"),
        write("rho_g"),
        write("rho_b"),
        write("add_r"),
        write("add_g"),
        write("add_b"),
        write("queue").sized_by_record(),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Per queued pixel: the excess test, `2R+1` rows × 4 adds and the
/// divisions.
pub fn flops_per_entry(radius: u32) -> f64 {
    12.0 + (2.0 * radius as f64 + 1.0) * 4.0
}

/// Records the weights: `sums` are `box_rows` of ŷ per channel, `count` of
/// the valid count; `out` = ρ R, G, B, add R, G, B, zeroed here and then
/// written at the pixels of `queue` (from [`super::outlier_detect`], the
/// only ones whose `excess` can be non-zero) that `push.mode` selects
/// (OUTLIER-WIDE: [`crate::shared::WEIGHTS_NARROW`] also marks the others in
/// their queue entries, which [`crate::shared::WEIGHTS_WIDE`] then
/// weighs). Like
/// [`super::outlier_median`]'s, the indirect dispatch is one unit (its
/// bound: [`flops_per_entry`], ≈ 360 at R = 43 and 1736 at 215, a quarter
/// of the pixels at most); the cost
/// estimate assumes [`super::outlier_median::DETECTED_FRACTION`].
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    excess: [BufferSlice; 3],
    sums: [BufferSlice; 3],
    count: BufferSlice,
    queue: BufferSlice,
    out: [BufferSlice; 6],
) -> Result<()> {
    let words = super::outlier_detect::queue_words(push.width as usize, push.height as usize);
    DECL.require(13, &queue, 4 * words as u64)?;
    for plane in out {
        batch.fill(plane, 0);
    }
    let groups: [&[BufferSlice]; 5] = [&excess, &sums, &[count], &out, &[queue]];
    // Per entry: the window's column of 4 row sums, its excess and weights.
    let bytes = (2.0 * push.radius as f64 + 1.0) * 16.0 + 40.0;
    let flops = flops_per_entry(push.radius);
    super::dispatch_queued(batch, &DECL, precision, push, &groups, queue, flops, bytes)
}
