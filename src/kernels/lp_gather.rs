//! `lp_gather`: LP's output (spec §3.5). Every pixel visits the centres of
//! its 19×19 neighbourhood in raster order (from its workgroup's list of the
//! centres that reach the 8×8 tile, LP-GATHER-UNION) and averages the
//! predictions `β_c + u_c·(x_i − x_c)` of the centres that cover it
//! (`|i − c|_inf <= r_opt(c)`; less those LP-PIXEL-TEST leaves out), their `max(ξ̂_c, 0)`, maps `u_c` and ranks
//! `k_c`. Error estimate (LP-FEATNOISE): `E_i = mean max(ξ̂_c, 0) +
//! (Σ_j |ū_j| σ_ij)²` (`σ_ij² = var(x_ij)`); local dimension `d_i = mean k_c`;
//! `ΔMSE = E_i·n_i^{-4/(d_i+4)}` (§9.1). With LP-PIXEL-TEST
//! (`LP_PIXEL_TEST`, `reference::lp_gather::OUTPUTS`) a centre whose
//! prediction misses the pixel's own mean by more than `t_threshold3(n_i)`
//! standard errors is left out. The outputs ([`OUTPUTS`]) go to one
//! binding, plane `k` at `k·out_stride` f32 values. Twin:
//! `reference::lp_gather`.

use super::lp_centres::LpInputs;
use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::LpPush;

/// Declaration of `spirv/lp_gather.comp`: its bindings in binding order and the
/// size of [`LpPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "lp_gather",
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
        read("spp"),
        read("state0").planes(4),
        read("state1").sized_by_record(),
        read("state2").sized_by_record(),
        read("state3").sized_by_record(),
        read("state4").sized_by_record(),
        read("state5").sized_by_record(),
        read("state6").sized_by_record(),
        read("state7").sized_by_record(),
        read("state8").sized_by_record(),
        write("out").sized_by_record(),
    ],
    push_size: std::mem::size_of::<LpPush>() as u32,
};

/// Names of the output planes, in the order of the packed output binding.
pub const OUTPUTS: [&str; 11] = [
    "out_r", "out_g", "out_b", "error_r", "error_g", "error_b", "dmse_r", "dmse_g", "dmse_b",
    "coverage", "dim",
];

/// Per pixel: for each centre of its tile's list a coverage test (4), and
/// for each covering centre (a few to a few dozen) 36 state reads, 9
/// feature differences, 3 × 9 FMAs and LP-PIXEL-TEST's squared miss (6);
/// once, the test's 3×3 variance mean (27 adds) and threshold (~30).
///
/// An upper bound (30 covering centres), which sizes the bands; `bench`
/// counts [`flops_of_pixel`] with the run's mean number of covering
/// centres instead.
pub fn flops_per_pixel() -> f64 {
    60.0 * 4.0 + 30.0 * 106.0 + 60.0 + 57.0
}

/// The work of a pixel covered by `centres` centres on average, as the
/// method needs it: per covering centre the 9 feature differences, three
/// predictions of 9 multiply-adds and β0 (57), LP-PIXEL-TEST's squared miss
/// (8), and the sums of `u` (27), of the prediction, error and rank (10):
/// 102; once, the test's 3×3 variance mean and threshold (~50), the
/// feature noise (7 square roots, three 9-term sums of `|ū|·σ` and their
/// squares: ~100), the means, the error and the ΔMSE rate (a power: ~40).
/// Finding the covering centres in the tile's list is integer work, not
/// counted.
pub fn flops_of_pixel(centres: f64) -> f64 {
    190.0 + 102.0 * centres
}

/// Records the gather over the rows `[first, end)` (`first` a multiple of
/// 8); `state` = the 9 vec4 planes once every pass is done within 9 rows of
/// them (planes 1..8 rings of [`LpPush::ring_rows`] rows), `out` = one buffer
/// holding the planes of [`OUTPUTS`], plane `k` at `k·push.out_stride` f32
/// values.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &LpPush,
    inp: &LpInputs,
    state: [BufferSlice; 9],
    out: BufferSlice,
    rows: (u32, u32),
) -> Result<()> {
    require_ring(&DECL, 12, push, &state)?;
    // Eleven planes `out_stride` words apart (the last always written).
    let pixels = push.width as u64 * push.height as u64;
    DECL.require(20, &out, 4 * (10 * push.out_stride as u64 + pixels))?;
    let mut b = Vec::with_capacity(DECL.bindings.len());
    b.extend_from_slice(&inp.packed);
    b.extend_from_slice(&inp.color);
    b.extend_from_slice(&inp.cvar);
    b.push(inp.spp);
    b.extend_from_slice(&state);
    b.push(out);
    batch.dispatch_rows(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(push),
        push.width,
        (rows, push.height),
        flops_per_pixel(),
    )
}

/// Checks LP's state planes 1..8 (bound from binding `first`): a ring of
/// [`LpPush::ring_len`] rows of one vec4 per pixel each.
pub(super) fn require_ring(
    decl: &KernelDecl,
    first: usize,
    push: &LpPush,
    state: &[BufferSlice; 9],
) -> Result<()> {
    let bytes = 16 * push.width as u64 * push.ring_len() as u64;
    for (k, s) in state[1..].iter().enumerate() {
        decl.require(first + k, s, bytes)?;
    }
    Ok(())
}
