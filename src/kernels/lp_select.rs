//! `lp_select`: the centres of one band of one sparse-centre pass of LP
//! (spec §3.5) — the candidates of granularity `g` that are valid and
//! covered by no centre of an earlier pass (read from the `lp_reach` plane
//! of the state before the pass, PASS-SNAPSHOT) — appended to the queue
//! [`super::lp_centres`] fits, dispatched indirectly. Twin:
//! `reference::lp_select`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision, QUEUE_HEADER_WORDS};
use crate::shared::LpPush;

/// Declaration of `spirv/lp_select.comp`: its bindings in binding order and
/// the size of [`LpPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "lp_select",
    bindings: &[
        read("spp"),
        read("reach").sized_by_record(),
        write("queue").sized_by_record(),
    ],
    push_size: std::mem::size_of::<LpPush>() as u32,
};

/// Words of a queue that holds any band of any pass of a `width × height`
/// image (at most one entry per pixel).
pub fn queue_words(width: usize, height: usize) -> usize {
    QUEUE_HEADER_WORDS + width * height
}

/// Per candidate: up to 19 reach reads and compares, one append.
pub fn flops_per_candidate() -> f64 {
    19.0 * 3.0 + 4.0
}

/// Records the selection of the grid rows `rows` (`[first, end)` of
/// [`LpPush::centre_grid`], any range: one grid row per workgroup row) into
/// `queue` (of [`queue_words`]; its header is reset here). `reach` is a
/// ring of [`LpPush::ring_rows`] rows.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &LpPush,
    spp: BufferSlice,
    reach: BufferSlice,
    queue: BufferSlice,
    rows: (u32, u32),
) -> Result<()> {
    let (gw, gh) = push.centre_grid();
    DECL.require(1, &reach, 4 * push.width as u64 * push.ring_len() as u64)?;
    // The header and every candidate of the band's grid rows.
    let candidates = gw as u64 * rows.1.min(gh).saturating_sub(rows.0) as u64;
    DECL.require(2, &queue, 4 * (QUEUE_HEADER_WORDS as u64 + candidates))?;
    batch.reset_queue(queue)?;
    batch.dispatch_rows(
        &DECL,
        precision,
        &[spp, reach, queue],
        bytemuck::bytes_of(push),
        gw,
        (rows, gh),
        flops_per_candidate(),
    )
}
