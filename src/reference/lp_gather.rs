//! Scalar twin of `spirv/lp_gather.comp`: LP's output (spec §3.5). Every
//! pixel averages the predictions of the centres that cover it, gathered in
//! raster order over its 19×19 neighbourhood, and forms its error estimate
//! (LP-FEATNOISE) and local dimension from them. The twin skips the window
//! rows that the `lp_reach` plane says hold no covering centre; the kernel
//! walks a list of its 8×8 tile's centres instead (LP-GATHER-UNION): the
//! same centres in the same order, so the same sums.

use super::lp::{state_value, Planes, StateLayout as S, RADIUS};
use super::wlr::D;
use super::{pixel_test_limit, spp_of};
use crate::shared::{LpPush, LP_PIXEL_TEST};

/// Output planes: colour R G B (clamped ≥ 0); error R G B, the estimated
/// MSE `E_i[ch] = mean_c max(ξ̂_c,ch(r_opt), 0) + (Σ_j |ū[ch][j]| σ_ij)²`
/// (LP-FEATNOISE: the centres' model error plus the variance that the
/// averaged linear map `ū = mean_c u_c` passes on from pixel i's own noisy
/// features, `σ_ij² = var(x_ij)` in §2.1 order, positions exact; only the
/// variances are known, and `(Σ_j |ū_j| σ_j)²` is the largest value
/// `ūᵀ Cov(x_i) ū` can take with them: feature noise that is fully
/// correlated, as it is where a pixel straddles an edge); ΔMSE R G B
/// (`E_i·n_i^{-4/(d_i+4)}`, §9.1, for sampling); coverage count; the local
/// dimension `d_i = mean_c k_c`.
///
/// Decision LP-PIXEL-TEST (ours): with option `lp.pixel_test`
/// ([`LP_PIXEL_TEST`]), a centre's prediction `f_c(i)` enters pixel i's average only if
/// `Σ_ch (f_c(i)[ch] − y_i[ch])² <= t² · max(Σ_ch v_i[ch], v̄_i)`, with `t`
/// = [`t_threshold3`](super::t_threshold3)`(n_i)` and `v̄_i` the mean of `Σ_ch v` over i's valid
/// 3×3 neighbourhood without its largest value (i included; a pixel whose
/// few samples happen to agree has a variance estimate far below its true
/// one, and the local level of noise says so; one neighbour that straddles
/// the edge of a bright light does not). A centre's window is
/// chosen by its mean error over the window (§3.4), so a centre on a bright,
/// noisy highlight takes a 19×19 window whose linear model, dominated by the
/// highlight, predicts ~3 at dark pixels of 0.08 several pixels away: the
/// mean hides them. If every covering centre is left out, i keeps its input
/// colour with `E_i = v_i`, `ΔMSE = v_i/n_i` (`d = 0`) and coverage 0.
pub const OUTPUTS: usize = 11;

/// For every pixel (`row0` ignored). `state` = the vec4 state planes after
/// the last pass, `reach` their [`lp_reach`](super::lp_reach) plane. An invalid pixel gets the mean colour of its valid 3×3
/// neighbours (§0.2), error, ΔMSE, coverage and dimension 0. A valid pixel
/// no centre predicts (all left out by LP-PIXEL-TEST; without it,
/// impossible after the last pass, §3.5) keeps its input colour.
pub fn lp_gather(
    push: &LpPush,
    p: &Planes,
    reach: &[f32],
    state: &[Vec<f32>],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), OUTPUTS, "lp_gather: output planes");
    let (w, h) = (p.width, p.height);
    assert_eq!((push.width as usize, push.height as usize), (w, h));
    let test = push.options & LP_PIXEL_TEST != 0;
    super::wlr::par_pixels::<OUTPUTS>(w, h, out, |x, y| pixel(p, reach, state, test, x, y));
}

/// LP-PIXEL-TEST's limit on the squared miss `Σ_ch (f − y_i)²` at the valid
/// pixel `i` (see [`OUTPUTS`]): [`pixel_test_limit`] of the summed colour
/// variances.
fn lp_pixel_limit(p: &Planes, i: usize) -> f64 {
    let vsum = |q: usize| p.colour(q).1.iter().sum::<f64>();
    let yi = p.colour(i).0;
    let dist2 = |q: usize| {
        let yq = p.colour(q).0;
        (0..3).map(|c| (yq[c] - yi[c]).powi(2)).sum::<f64>()
    };
    pixel_test_limit(p.width, p.height, vsum, dist2, |q| p.valid(q), p.spp, i)
}

fn pixel(
    p: &Planes,
    reach: &[f32],
    state: &[Vec<f32>],
    test: bool,
    x: usize,
    y: usize,
) -> [f32; OUTPUTS] {
    let (w, h) = (p.width, p.height);
    let i = y * w + x;
    let mut o = [0.0f32; OUTPUTS];
    if !p.valid(i) {
        // Mean shifted by the first valid neighbour: exact when they are equal.
        let mut first = [0.0; 3];
        let mut sum = [0.0; 3];
        let mut n = 0;
        for qy in y.saturating_sub(1)..(y + 2).min(h) {
            for qx in x.saturating_sub(1)..(x + 2).min(w) {
                let q = qy * w + qx;
                if p.valid(q) {
                    let (c, _) = p.colour(q);
                    if n == 0 {
                        first = c;
                    }
                    for ch in 0..3 {
                        sum[ch] += c[ch] - first[ch];
                    }
                    n += 1;
                }
            }
        }
        if n > 0 {
            for ch in 0..3 {
                o[ch] = (first[ch] + sum[ch] / n as f64).max(0.0) as f32;
            }
        }
        return o;
    }
    let xi_ = p.features(x, y);
    let n_i = spp_of(p.spp[i]);
    let (y_i, v_i) = p.colour(i);
    let limit = test.then(|| lp_pixel_limit(p, i));
    // Predictions are summed relative to the first one, so that equal
    // predictions average exactly (a constant image is returned exactly).
    let mut first = [0.0; 3];
    let mut pred = [0.0; 3];
    let mut err = [0.0; 3];
    let mut dim = 0.0;
    let mut usum = [[0.0; D]; 3];
    let mut count = 0usize;
    for qy in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(h) {
        // Rows whose reach (lp_reach) cannot cover i hold no covering centre.
        if reach[qy * w + x] < qy.abs_diff(y) as f32 {
            continue;
        }
        for qx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
            let q = qy * w + qx;
            let st = |s: usize| state_value(state, q, s) as f64;
            if st(S::PASS) <= 0.0 {
                continue;
            }
            let d = qx.abs_diff(x).max(qy.abs_diff(y)) as f64;
            if d > st(S::R_OPT) {
                continue;
            }
            let xc = p.features(qx, qy);
            let f: [f64; 3] = std::array::from_fn(|ch| {
                (0..D).fold(st(S::BETA0 + ch), |f, j| {
                    f + st(S::U + 9 * ch + j) * (xi_[j] - xc[j])
                })
            });
            let miss2: f64 = (0..3).map(|ch| (f[ch] - y_i[ch]).powi(2)).sum();
            if limit.is_some_and(|l| miss2 > l) {
                continue;
            }
            for ch in 0..3 {
                for j in 0..D {
                    usum[ch][j] += st(S::U + 9 * ch + j);
                }
                if count == 0 {
                    first[ch] = f[ch];
                }
                pred[ch] += f[ch] - first[ch];
                err[ch] += st(S::XI + ch).max(0.0);
            }
            dim += st(S::K);
            count += 1;
        }
    }
    if count == 0 {
        // No centre predicts i (only LP-PIXEL-TEST leaves a valid pixel
        // so): its input, whose error is its variance of the mean, falling
        // as 1/n (d = 0).
        for ch in 0..3 {
            o[ch] = y_i[ch].max(0.0) as f32;
            o[3 + ch] = v_i[ch] as f32;
            o[6 + ch] = (v_i[ch] / n_i) as f32;
        }
        return o;
    }
    let n = count as f64;
    // Standard deviations of pixel i's features (§2.1 order; the positions
    // are exact).
    let mut sd = [0.0; D];
    for (j, v) in sd.iter_mut().enumerate().skip(2) {
        *v = (p.var[j - 2][i] as f64).max(0.0).sqrt();
    }
    let d = dim / n;
    let rate = n_i.powf(-4.0 / (d + 4.0));
    for ch in 0..3 {
        o[ch] = (first[ch] + pred[ch] / n).max(0.0) as f32;
        let feat = (0..D)
            .map(|j| usum[ch][j].abs() * sd[j])
            .sum::<f64>()
            .powi(2)
            / (n * n);
        let e = err[ch] / n + feat;
        o[3 + ch] = e as f32;
        o[6 + ch] = (e * rate) as f32;
    }
    o[9] = count as f32;
    o[10] = d as f32;
    o
}
