//! `lp_reach`: the horizontal half of LP's coverage test (spec §3.5): per
//! pixel, the largest `r_opt` of the centres of earlier passes in its row
//! that reach it horizontally (−1 if none), at the columns of the pass's
//! candidate grid; see its twin `reference::lp_reach`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::LpPush;

/// Declaration of `spirv/lp_reach.comp`: its bindings in binding order and the
/// size of [`LpPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "lp_reach",
    bindings: &[read("state0").planes(4), write("reach").sized_by_record()],
    push_size: std::mem::size_of::<LpPush>() as u32,
};

/// Candidate columns of a row one invocation computes (`LR_PX` in the
/// shader).
pub const PIXELS_PER_INVOCATION: u32 = 8;

/// Per pixel: 19 centre-map reads and compares.
pub fn flops_per_pixel() -> f64 {
    19.0 * 4.0
}

/// The columns of a `width`-pixel row that `push`'s candidate grid holds
/// (`x ≡ phase_x mod g`): what the kernel writes.
pub fn columns(push: &LpPush, width: u32) -> impl Iterator<Item = usize> {
    let g = push.granularity.max(1) as usize;
    ((push.phase & 0xffff) as usize..width as usize).step_by(g)
}

/// Per invocation: its joint window of `(LR_PX − 1)·g + 19` centre-map
/// entries, each compared for its `LR_PX` columns (≈ 4 flops).
pub fn flops_per_invocation(granularity: u32) -> f64 {
    let px = PIXELS_PER_INVOCATION as f64;
    ((px - 1.0) * granularity.max(1) as f64 + 19.0) * px * 4.0
}

/// Records `reach` of the centres made before `push.pass` (PASS-SNAPSHOT;
/// `push.pass` = 5 for all of them) from state plane 0, over the rows
/// `[first, end)` (any range: one row per workgroup row), into `reach`, a
/// ring of [`LpPush::ring_rows`] rows, at the [`columns`] of the candidate
/// grid of `push.granularity` and `push.phase` (every column for `g = 1`);
/// the other columns are not written.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &LpPush,
    state0: BufferSlice,
    reach: BufferSlice,
    rows: (u32, u32),
) -> Result<()> {
    DECL.require(1, &reach, 4 * push.width as u64 * push.ring_len() as u64)?;
    let cols = columns(push, push.width).count() as u32;
    batch.dispatch_rows(
        &DECL,
        precision,
        &[state0, reach],
        bytemuck::bytes_of(push),
        // One invocation per PIXELS_PER_INVOCATION candidate columns of a
        // row (register blocking: the shader's LR_PX).
        cols.div_ceil(PIXELS_PER_INVOCATION),
        (rows, push.height),
        flops_per_invocation(push.granularity),
    )
}
