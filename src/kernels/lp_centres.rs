//! `lp_centres`: one sparse-centre pass of LP (spec §3.5) on the candidate
//! grid of granularity `g`. Band by band, [`super::lp_select`] queues the
//! candidates `(g·gx, g·gy)` that are valid and not covered by a centre of
//! an earlier pass (PASS-SNAPSHOT), and this kernel, dispatched indirectly
//! with one invocation per queued centre, fits each: TSVD on the 19×19
//! window (§0.6), RLS ring by ring with the recursive error estimate
//! (§3.3–3.4), `r_opt`, and its 36-value state
//! ([`LpStateLayout`](crate::shared::LpStateLayout)) is written to its own
//! pixel of the state planes; nothing else is written. The centres of a
//! late pass are a few % of its candidates: fitted on the grid, most SIMD
//! lanes idled beside the one busy lane of a workgroup.
//! Twin: `reference::lp_centres`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::LpPush;

/// Declaration of `spirv/lp_centres.comp`: its bindings in binding order and
/// the size of [`LpPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "lp_centres",
    bindings: &[
        read("features_a").planes(4),
        read("features_b").planes(4),
        read("variances_a").planes(4),
        read("variances_b").planes(4),
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("var_color_r"),
        read("var_color_g"),
        read("var_color_b"),
        read("queue").sized_by_record(),
        write("state0").planes(4),
        write("state1").sized_by_record(),
        write("state2").sized_by_record(),
        write("state3").sized_by_record(),
        write("state4").sized_by_record(),
        write("state5").sized_by_record(),
        write("state6").sized_by_record(),
        write("state7").sized_by_record(),
        write("state8").sized_by_record(),
    ],
    push_size: std::mem::size_of::<LpPush>() as u32,
};

/// Invocations per workgroup (`local_size_x`, `LP_CENTRES_GROUP` in
/// `spirv/lib/common.glsl`): one per queued centre; `lp_select` counts the
/// indirect dispatch's workgroups in units of it. One SIMD vector of
/// lavapipe (LP-GROUP8): a late pass's band queues a few dozen to a few
/// hundred centres of unequal cost, and lavapipe gives each thread whole
/// workgroups, so larger groups leave a core idle at the end of a dispatch.
/// Above 65535 groups (524,280 centres in one band) the invocations stride
/// over the rest.
pub const GROUP: u32 = 8;

/// What `lp_centres` and `lp_gather` read: a packed copy of the sanitised
/// (and possibly prefiltered) features and their variances, and the
/// statistics' colour, colour variances and counts.
pub struct LpInputs {
    /// The features and their variances packed by [`super::gbf_pack`]
    /// (PACKED-LP): normal xyz and depth, albedo rgb and spp (PACKED-SPP:
    /// `lp_centres` learns a pixel's validity from it), the variances of
    /// those features and 0; vec4 planes of the whole image.
    pub packed: [BufferSlice; 4],
    /// Colour R, G, B.
    pub color: [BufferSlice; 3],
    /// Colour variances (of the mean) R, G, B.
    pub cvar: [BufferSlice; 3],
    /// Sample count `n` per pixel (f32); a pixel is valid when `n >= 1`.
    pub spp: BufferSlice,
}

/// An upper bound of the work of a centre, which sizes the bands (the
/// dispatch charges it to every candidate cell): 361 neighbours × (TSVD:
/// one pass with two full 9×9 Gram updates; RLS at the largest rank: three
/// projections, two 10×10 mat-vecs and one rank-1 update, 3 channels) plus
/// two 9×9 Jacobi decompositions of 10 sweeps. `bench` counts
/// [`flops_of_centre`] of each centre instead.
pub fn flops_per_centre() -> f64 {
    let n = 361.0;
    let tsvd = 2.0 * 81.0 * 2.0 + 40.0;
    let rls = 3.0 * 162.0 + 3.0 * 200.0 + 100.0;
    n * (tsvd + rls) + 2.0 * 10.0 * 81.0 * 9.0 * 4.0
}

/// The work of a centre of TSVD rank `rank` (`p = rank + 1` regressors) with
/// a full 19×19 window (spec §0.6, §3.3–3.4), as the algorithm needs it:
/// - per window pixel, the TSVD pass ([`super::wlr_fit::TSVD_PASS`], as
///   WLR counts it);
/// - per window pixel, the RLS: the projection (9 differences, `9·rank`
///   multiply-adds), `Pζ` and the rank-1 update of `P` (`4p²`), `ζᵀPζ` and
///   the gain (`3p`), per channel the prediction, residual and `β` update
///   (`3·(4p + 1)`) and the score (9);
/// - once, ring 1's leave-one-out pass over 9 pixels (projection, leverage
///   `2p² + 2p`, predictions `6p`);
/// - once, the rest of the TSVD: the Jacobi sweeps at their typical count,
///   the scaling, the bounds on `‖E‖₂`, the rank and the projection
///   ([`super::wlr_fit::tsvd_once`]).
///
/// A mat4 block holding a 3×3 problem, or the duplicate half of a symmetric
/// matrix, is not counted: it is the kernel's layout, not the method's work.
pub fn flops_of_centre(rank: u32) -> f64 {
    let (k, p) = (rank as f64, rank as f64 + 1.0);
    let project = 9.0 + 18.0 * k;
    let rls = project + 4.0 * p * p + 3.0 * p + 3.0 * (4.0 * p + 1.0) + 9.0;
    let loo = 9.0 * (project + 2.0 * p * p + 2.0 * p + 6.0 * p);
    361.0 * (super::wlr_fit::TSVD_PASS + rls) + loo + super::wlr_fit::tsvd_once(k)
}

/// Records one pass (`push.granularity`, `push.pass`; `push.width/height`
/// are the image's) over the grid rows `[first, end)` of its candidate grid
/// ([`LpPush::centre_grid`]; `None`: all of them), in bands of grid rows
/// whose bound (every candidate a centre) stays within the batch's work per
/// submit: per band, in one [`Batch::unit`], [`super::lp_select`] into
/// `queue` (of [`super::lp_select::queue_words`]), then the fits. `reach` is the
/// `lp_reach` plane of the centres of earlier passes; `state` the 9 vec4
/// planes (planes 1..8 and `reach` rings of [`LpPush::ring_rows`] rows).
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &LpPush,
    inp: &LpInputs,
    reach: BufferSlice,
    queue: BufferSlice,
    state: [BufferSlice; 9],
    rows: Option<(u32, u32)>,
) -> Result<()> {
    let mut b = Vec::with_capacity(DECL.bindings.len());
    b.extend_from_slice(&inp.packed);
    b.extend_from_slice(&inp.color);
    b.extend_from_slice(&inp.cvar);
    b.push(queue);
    b.extend_from_slice(&state);
    super::lp_gather::require_ring(&DECL, 12, push, &state)?;
    let (gw, gh) = push.centre_grid();
    let (first, end) = rows.unwrap_or((0, gh));
    let end = end.min(gh);
    if gw == 0 || first >= end {
        return Ok(());
    }
    let row_flops = gw as f64 * flops_per_centre();
    // At least 8 grid rows: a band's centres are a few % of its candidates,
    // and an indirect dispatch of a handful of centres leaves cores idle.
    let band = batch.band_rows(row_flops, 8);
    // Compulsory traffic of a band: its share of the bound ranges.
    let bytes: f64 = b.iter().map(|s| s.size() as f64).sum::<f64>() / gh as f64;
    let select_flops = gw as f64 * super::lp_select::flops_per_candidate();
    let mut row0 = first;
    while row0 < end {
        let rows = band.min(end - row0);
        // The selection and the fits of its queue in one submit (checked
        // dispatch by dispatch, the selection went alone into a submit
        // before each band's fits).
        batch.unit((select_flops + row_flops) * rows as f64, |batch| {
            super::lp_select::record(
                batch,
                precision,
                push,
                inp.spp,
                reach,
                queue,
                (row0, row0 + rows),
            )?;
            batch.dispatch_indirect(
                &DECL,
                precision,
                &b,
                bytemuck::bytes_of(push),
                queue.sub(0, 12)?,
                row_flops * rows as f64,
                bytes * rows as f64,
            )
        })?;
        row0 += rows;
    }
    Ok(())
}
