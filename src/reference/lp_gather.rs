//! Scalar twin of `spirv/lp_gather.comp`: LP's output (spec §3.5). Every
//! pixel averages the predictions of the centres that cover it, gathered in
//! raster order over its 19×19 neighbourhood, with their error estimates.

use super::lp::{state_value, Planes, StateLayout as S, RADIUS};
use super::spp_of;
use super::wlr::D;
use crate::shared::LpPush;

/// Output planes: colour R G B (clamped ≥ 0), error R G B (mean of
/// `max(ξ̂_c,ch(r_opt), 0)` over the covering centres: the estimated MSE),
/// ΔMSE R G B (§3.5: the same mean of `max(ξ̂, 0)·n_i^{-4/(k_c+4)}`, for
/// sampling), coverage count.
pub const OUTPUTS: usize = 10;

/// For every pixel (`row0` ignored). `state` = the vec4 state planes after
/// the last pass, `reach` their [`lp_reach`](super::lp_reach) plane. An invalid pixel gets the mean colour of its valid 3×3
/// neighbours (§0.2), error 0 and coverage 0. A valid pixel no centre covers
/// (impossible after the last pass, §3.5) keeps its input colour with error,
/// ΔMSE and coverage 0.
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
    super::wlr::par_pixels::<OUTPUTS>(w, h, out, |x, y| pixel(p, reach, state, x, y));
}

fn pixel(p: &Planes, reach: &[f32], state: &[Vec<f32>], x: usize, y: usize) -> [f32; OUTPUTS] {
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
    // Predictions are summed relative to the first one, so that equal
    // predictions average exactly (a constant image is returned exactly).
    let mut first = [0.0; 3];
    let mut pred = [0.0; 3];
    let mut err = [0.0; 3];
    let mut dmse = [0.0; 3];
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
            let rate = n_i.powf(-4.0 / (st(S::K) + 4.0));
            for ch in 0..3 {
                let mut f = st(S::BETA0 + ch);
                for j in 0..D {
                    f += st(S::U + 9 * ch + j) * (xi_[j] - xc[j]);
                }
                if count == 0 {
                    first[ch] = f;
                }
                pred[ch] += f - first[ch];
                let e = st(S::XI + ch).max(0.0);
                err[ch] += e;
                dmse[ch] += e * rate;
            }
            count += 1;
        }
    }
    if count == 0 {
        let (c, _) = p.colour(i);
        for ch in 0..3 {
            o[ch] = c[ch].max(0.0) as f32;
        }
        return o;
    }
    let n = count as f64;
    for ch in 0..3 {
        o[ch] = (first[ch] + pred[ch] / n).max(0.0) as f32;
        o[3 + ch] = (err[ch] / n) as f32;
        o[6 + ch] = (dmse[ch] / n) as f32;
    }
    o[9] = count as f32;
    o
}
