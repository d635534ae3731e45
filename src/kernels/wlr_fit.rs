//! `wlr_fit`: WLR steps 1–7 (spec §2.3) per pixel — TSVD (§0.6), curvature
//! bandwidths `b_j`, the five trial fits, the parametric fits and `h_opt`.
//! The per-pixel routines live in `spirv/lib/wlr.glsl`, shared with
//! `wlr_final`. Twin: `reference::wlr_fit`.
//!
//! Outputs (bindings 19..26): `h_opt`; `λ1`, `κ0`, `κ1` of the model
//! `MSE(h) = (λ1 h²)² + (κ0 + κ1 h^{-k})/n_c` that `wlr_final` evaluates at
//! `hbar` (for `κ1 <= 0`, `k = 0` and SOLVE-FAIL of the curvature fit:
//! `λ1 = κ1 = 0`, `κ0 = n_c·MSE_fixed`); `kflags = k + 16·flags` (§2.5 bits
//! 0, 2, 3, 4); `b_1..b_3` (debug, 0 for `j >= k`). Invalid centre: all 0.
//! Binding 17, `state`: per centre with `k >= 1`, the local space and the
//! `b_j` that `wlr_final` reads back instead of recomputing them
//! ([`STATE_WORDS`] per pixel, in a ring of [`WlrPush::ring_rows`] rows).
//!
//! [`DECL_VIS`], `wlr_fit_vis` (the same source with `WLR_VIS`): WLR-VIS,
//! the prefiltered visibility and its variance as a tenth feature
//! (bindings 18, 19), at most 9 local coordinates; its state holds
//! [`STATE_WORDS_VIS`] per pixel.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::WlrPush;

/// Declaration of `spirv/wlr_fit.comp`: its bindings in binding order and the
/// size of [`WlrPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "wlr_fit",
    bindings: bindings!(),
    push_size: std::mem::size_of::<WlrPush>() as u32,
};

/// Declaration of `wlr_fit_vis` (WLR-VIS): [`DECL`]'s bindings, then the
/// prefiltered visibility and its variance.
pub const DECL_VIS: KernelDecl = KernelDecl {
    name: "wlr_fit_vis",
    bindings: bindings!(read("visibility"), read("visibility_variance")),
    push_size: std::mem::size_of::<WlrPush>() as u32,
};

/// The declaration of the variant that reads `features` (9, or 10 with the
/// visibility).
pub fn decl(features: usize) -> &'static KernelDecl {
    if features > 9 {
        &DECL_VIS
    } else {
        &DECL
    }
}

macro_rules! bindings {
    ($($extra:expr),*) => { &[
        read("features_a").planes(4),
        read("features_b").planes(4),
        read("variances_a").planes(4),
        read("variances_b").planes(4),
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("vbar"),
        read("spp"),
        write("h_opt"),
        write("lambda1"),
        write("kappa0"),
        write("kappa1"),
        write("kflags"),
        write("b1"),
        write("b2"),
        write("b3"),
        write("state").sized_by_record(),
        $($extra),*
    ] };
}
use bindings;

/// Names of the 8 output maps, in binding order.
pub const OUTPUTS: [&str; 8] = [
    "h_opt", "lambda1", "kappa0", "kappa1", "kflags", "b1", "b2", "b3",
];

/// Words (of the kernel's precision, f32 or f64) of the centre state per
/// pixel: 23 `vec4` (`WLR_STATE_VEC4` in `spirv/lib/wlr.glsl`).
pub const STATE_WORDS: usize = 23 * 4;
/// The same for `wlr_fit_vis`: 25 `vec4` (the visibility's column of the
/// projection).
pub const STATE_WORDS_VIS: usize = 25 * 4;

/// [`STATE_WORDS`] or [`STATE_WORDS_VIS`] for `features` features.
pub fn state_words(features: usize) -> usize {
    if features > 9 {
        STATE_WORDS_VIS
    } else {
        STATE_WORDS
    }
}

/// Typical share of a centre's valid window pixels that WLR-CI accepts
/// (steps 3, 5, 9) and that lie in the support of the curvature fit's
/// kernel (step 4, `h = 1`), measured with the CPU twins (R = 9, one centre
/// in 64) on glossy_cornell, indirect_room and dof_checker at 16 spp:
/// accepted 0.955, 0.994, 0.971; curvature support 0.883, 0.828, 0.877.
pub const ACCEPTED: f64 = 0.97;
/// See [`ACCEPTED`].
pub const CURVATURE_SUPPORT: f64 = 0.86;
/// Typical share of the valid window pixels in the support of the trial
/// fits' kernels (`w_i > 0`), for `h_s` = 0.2 … 1.0, measured as
/// [`ACCEPTED`] (per scene: 0.158/0.553/0.809/0.856/0.872,
/// 0.142/0.511/0.764/0.819/0.840, 0.139/0.492/0.742/0.847/0.903).
pub const TRIAL_SUPPORT: [f64; 5] = [0.15, 0.52, 0.77, 0.84, 0.87];
/// Typical cyclic Jacobi sweeps of the 9×9 Gram matrix `G` to the f32
/// tolerance (`JACOBI_TOL` 1e-6): 2.9, 3.5 and 3.3 on average on the three
/// scenes of [`ACCEPTED`] (f64 twin at the f32 rule), rounded up to 4 for
/// the f32 arithmetic. The bounds on `‖E‖₂` spare the second
/// eigenproblem for most centres (TSVD-ONE-JACOBI); it is not counted.
pub const JACOBI_SWEEPS: f64 = 4.0;

/// One Jacobi rotation of a 9×9 matrix (`jacobi_sweeps`): the angle (17),
/// the 7 other rows (42), the two diagonal entries (4) and the rows of `V`
/// (54). The mirrored writes of the symmetric update are not arithmetic.
const JACOBI_ROTATION: f64 = 117.0;

/// Per valid window pixel, the TSVD pass (TSVD-ONE-PASS, as LP's
/// `lp_centres` counts it): the 9 components'
/// minimum and maximum (18), their difference from the centre and its sum
/// (18), the square roots of the 7 noisy variances and their sum (14), the
/// 45 products of the Gram sum (90) and the 28 of the noise sum (56).
pub const TSVD_PASS: f64 = tsvd_pass(9.0);

/// [`TSVD_PASS`] for `d` features (two of them the noiseless pixel
/// coordinates).
pub const fn tsvd_pass(d: f64) -> f64 {
    4.0 * d + 2.0 * (d - 2.0) + d * (d + 1.0) + (d - 2.0) * (d - 1.0)
}

/// Once per centre, the rest of the TSVD (§0.6): [`JACOBI_SWEEPS`] sweeps
/// of 36 rotations and the off-diagonal norms (75 each, one check more
/// than sweeps, plus the initial norm); the scaled Gram entries
/// `((n S2 − S1 S1ᵀ)/n)/(ρ_j ρ_l)` (45 × 5) and noise entries (28 × 2);
/// the bounds on `λ_max(EᵀE)` (7 products by the 7×7 non-zero block, with
/// their maximum and scaling: ~830); ranges, square roots and the rank
/// (~60); the projection `P = V_kᵀ diag(1/ρ)` (`9k + 9`).
pub fn tsvd_once(k: f64) -> f64 {
    tsvd_once_of(9.0, k)
}

/// [`tsvd_once`] for `d` features: `d(d−1)/2` rotations of
/// `17 + 6(d−2) + 4 + 6d` (117 at 9), the norms and entries
/// by their counts, the bounds by the noisy block's size squared.
pub fn tsvd_once_of(d: f64, k: f64) -> f64 {
    let pairs = d * (d - 1.0) / 2.0;
    let rotation = JACOBI_ROTATION + 12.0 * (d - 9.0);
    let jacobi =
        JACOBI_SWEEPS * pairs * rotation + (JACOBI_SWEEPS + 1.0) * (2.0 * pairs + 3.0) + 90.0;
    let noisy = d - 2.0;
    jacobi
        + d * (d + 1.0) / 2.0 * 5.0
        + noisy * (noisy + 1.0)
        + 830.0 * (noisy / 7.0) * (noisy / 7.0)
        + 60.0
        + d * k
        + d
}

/// The local linear fits of steps 5 / 9 (`p = k + 1` regressors) over a
/// window of `window` valid pixels, at as many bandwidths as `support` has
/// entries (each the share of the window inside that bandwidth's kernel
/// support), with `accepted` the share WLR-CI accepts. Both passes (A: the
/// normal matrices; B: the equivalent kernels and step 5's sums):
/// - per valid pixel and pass: grey (3), the WLR-CI test (8), the outlier
///   weight (2), the centred colour (3);
/// - per accepted pixel and pass: `Δz` (`d` differences, `dk`
///   multiply-adds; `d` features), and per bandwidth its kernel `Π_j K_E` (`6k + 1`);
/// - per pixel in a bandwidth's support: pass A the weighted row and the
///   `p(p+1)/2` multiply-adds of the normal matrix' lower triangle
///   (`p(p+2)`), pass B `l_i` (`2p`) and the sums of `l`, `l₊` (20);
/// - once per bandwidth: `1/(h b_j)` (`2k`), the ridge Cholesky (`p³/3`),
///   the first column of the inverse (`2p²`), NONNEG and the bias (30).
pub(crate) fn fits_flops(window: f64, k: f64, d: f64, accepted: f64, support: &[f64]) -> f64 {
    let p = k + 1.0;
    let nfit = support.len() as f64;
    let valid = 2.0 * 16.0;
    let acc = accepted * 2.0 * (d + 2.0 * d * k + nfit * (6.0 * k + 1.0));
    let pos = support.iter().sum::<f64>() * (p * (p + 2.0) + 2.0 * p + 20.0);
    window * (valid + acc + pos) + nfit * (2.0 * k + p * p * p / 3.0 + 2.0 * p * p + 30.0)
}

/// The curvature fit (step 4, `q = 1 + 2k` columns) over `window` valid
/// pixels, `support` of them in its kernel's support: per valid pixel the
/// centred colour and outlier weight (5), `Δz` (`d + 2dk`) and the kernel
/// (`5k + 1`); per pixel in the support the squares (`k`), the weighted row
/// (`q`), the lower triangle of the normal matrix (`q(q+1)`) and three
/// right-hand sides (`6q`); once, the ridge Cholesky (`q³/3 + q²/2`), three
/// solves (`6q²`) and `Hbar_j`, `b_j` (`15k`).
fn curvature_flops(window: f64, k: f64, d: f64, support: f64) -> f64 {
    let q = 1.0 + 2.0 * k;
    window * (5.0 + d + (2.0 * d + 5.0) * k + support * (k + q * q + 8.0 * q))
        + q * q * q / 3.0
        + 6.5 * q * q
        + 15.0 * k
}

/// `wlr_fit`'s work at a valid centre of TSVD rank `rank` (§2.3 steps 1–7)
/// whose window holds `window` valid pixels ((2R+1)² inside the image),
/// with the typical shares [`ACCEPTED`], [`CURVATURE_SUPPORT`] and
/// [`TRIAL_SUPPORT`]: the TSVD pass per pixel (196) and the rest
/// of the TSVD once (the Jacobi sweeps, [`JACOBI_SWEEPS`]), the curvature
/// fit, the five trial fits (two passes) and the parametric fits (~250, f64).
/// Rank 0 (a window without a non-constant component) does the TSVD only.
///
/// Counted as the method needs it, as implemented: the padded lanes of the
/// kernel's `mat4` blocks (a 4×4 block holding a 3×3 fit, the zero design
/// components beyond `k`), the duplicate half of a symmetric matrix and the
/// accumulations of neighbours outside a kernel's support (`w_i = 0`, done
/// under a SIMD mask) are not counted. `mcdenoise bench` charges each pixel
/// this at its rank (WLR's rank map); the dispatch charges the bound
/// [`flops_per_pixel`].
/// Flops as [`EXP_FLOPS`](super::EXP_FLOPS) counts them.
pub fn flops_of_pixel(window: f64, rank: u32) -> f64 {
    flops_with(
        window,
        rank,
        9.0,
        ACCEPTED,
        CURVATURE_SUPPORT,
        &TRIAL_SUPPORT,
    )
}

/// [`flops_of_pixel`] of `wlr_fit_vis` (ten features).
pub fn flops_of_pixel_vis(window: f64, rank: u32) -> f64 {
    flops_with(
        window,
        rank,
        10.0,
        ACCEPTED,
        CURVATURE_SUPPORT,
        &TRIAL_SUPPORT,
    )
}

fn flops_with(
    window: f64,
    rank: u32,
    d: f64,
    accepted: f64,
    curvature: f64,
    trials: &[f64],
) -> f64 {
    let k = rank as f64;
    let tsvd = window * tsvd_pass(d) + tsvd_once_of(d, k);
    if rank == 0 {
        return tsvd;
    }
    tsvd + curvature_flops(window, k, d, curvature)
        + fits_flops(window, k, d, accepted, trials)
        + 250.0
}

/// An upper bound of [`flops_of_pixel`] (of [`flops_of_pixel_vis`] for 10
/// `features`), which sizes the bands: a full `(2R+1)²` window, rank 9,
/// every neighbour accepted and inside every kernel's support.
pub fn flops_per_pixel(radius: u32, features: usize) -> f64 {
    let n = ((2 * radius + 1) * (2 * radius + 1)) as f64;
    flops_with(n, 9, features as f64, 1.0, 1.0, &[1.0; 5])
}

/// Records `wlr_fit` over the rows `rows = [first, end)` (`first` a multiple
/// of 8) of a `width × height` image with window radius `radius` (5
/// intermediate, 9 final) and `options` ([`WlrPush::options`] bits).
/// `packed` = the features (normal xyz, depth, albedo rgb) and their
/// variances as `gbf_pack` packs them (4 vec4 planes); `color` = R, G, B;
/// `vbar` = mean colour variance; `out` = the 8 maps of
/// [`OUTPUTS`]; `state` = a ring of `ring_rows` rows of [`state_words`]
/// per pixel, which must hold the rows `wlr_final` will read; `vis` = the
/// prefiltered visibility and its variance for `wlr_fit_vis` (WLR-VIS), or
/// `None` for `wlr_fit`.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    rows: (u32, u32),
    (radius, options): (u32, u32),
    packed: [BufferSlice; 4],
    color: [BufferSlice; 3],
    vbar: BufferSlice,
    spp: BufferSlice,
    out: [BufferSlice; 8],
    (state, ring_rows): (BufferSlice, u32),
    vis: Option<[BufferSlice; 2]>,
) -> Result<()> {
    let features = if vis.is_some() { 10 } else { 9 };
    let decl = decl(features);
    require_state(
        decl,
        17,
        precision,
        width,
        height,
        (&state, ring_rows),
        features,
    )?;
    let push = WlrPush {
        width,
        height,
        radius,
        options,
        ring_rows,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(20);
    b.extend_from_slice(&packed);
    b.extend_from_slice(&color);
    b.push(vbar);
    b.push(spp);
    b.extend_from_slice(&out);
    b.push(state);
    b.extend(vis.iter().flatten());
    batch.dispatch_rows(
        decl,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        (rows, height),
        flops_per_pixel(radius, features),
    )
}

/// Checks the centre state ring bound at `index`: `ring_rows` (≥ 1) rows,
/// at most the image's height, of [`state_words`] values per pixel (f64 in
/// the `_f64` variant, f32 otherwise) for `features` features.
pub(super) fn require_state(
    decl: &KernelDecl,
    index: usize,
    precision: Precision,
    width: u32,
    height: u32,
    (state, ring_rows): (&BufferSlice, u32),
    features: usize,
) -> Result<()> {
    if ring_rows == 0 {
        return Err(crate::error::Error::InvalidArgument(format!(
            "{}: the state ring needs at least one row",
            decl.name
        )));
    }
    let word = if precision == Precision::F64 { 8 } else { 4 };
    let rows = ring_rows.min(height) as u64;
    decl.require(
        index,
        state,
        rows * width as u64 * state_words(features) as u64 * word,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_band_bound_covers_every_rank_and_window() {
        for radius in [5, 9] {
            let full = ((2 * radius + 1) * (2 * radius + 1)) as f64;
            for rank in 0..=9 {
                for window in [1.0, full / 2.0, full] {
                    assert!(flops_of_pixel(window, rank) < flops_per_pixel(radius, 9));
                    assert!(flops_of_pixel_vis(window, rank) < flops_per_pixel(radius, 10));
                    assert!(flops_of_pixel(window, rank) < flops_of_pixel_vis(window, rank));
                    assert!(
                        super::super::wlr_final::flops_of_pixel(window, rank)
                            < super::super::wlr_final::flops_per_pixel(radius, 9)
                    );
                }
            }
        }
        // The work grows with the rank.
        for rank in 1..=9 {
            assert!(flops_of_pixel(361.0, rank) > flops_of_pixel(361.0, rank - 1));
        }
    }
}
