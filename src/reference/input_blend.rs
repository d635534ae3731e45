//! Scalar twin of `spirv/input_blend.comp`: one channel of a
//! reconstruction blended with its input by inverse error (INPUT-BLEND).

use super::finalize_stats::spp_of;
use crate::shared::{BlendPush, BLEND_TRIM_MAX};

/// Per valid pixel `i` (`n ≥ 1`), with `V = max(v_i, trimmed_mean)`
/// (negative variances read as 0; [`trimmed_mean`] over the valid pixels
/// within radius r),
/// `E = max(E_i, 0)` and, where `s = push.residual_radius > 0`, the
/// residual's bound over the valid pixels `q` within radius `s`
/// (BLEND-RESIDUAL): `B = mean (f_q − y_q)² − mean v_q − z √(2 mean v_q² /
/// n)`, not read (0) where a term `(f_q − y_q)²` or `v_q²` is not finite
/// or exceeds f32's largest; with `M = max(E, B)` and `W = max(k E, B)`:
/// `f'_i = max((V f_i + W y_i) / (V + W), 0)` and
/// `E'_i = w_f² M + w_y² V` with `w_y = W / (V + W)`, computed as
/// `f + w_y (y − f)` from `V`, `M` and `W` divided by the largest, as the
/// kernel does in f32. An invalid pixel, one with `V + W` zero or not
/// finite, or one whose blend is not finite (or whose `E'` exceeds f32),
/// keeps `f_i` and `E_i`.
/// Writes `f'` and `E'`.
pub fn input_blend(
    push: &BlendPush,
    f: &[f32],
    e: &[f32],
    y: &[f32],
    v: &[f32],
    spp: &[f32],
    f_out: &mut [f32],
    e_out: &mut [f32],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    let r = push.radius as usize;
    let k = push.k as f64;
    let rs = push.residual_radius;
    let var = |q: usize| (v[q] as f64).max(0.0);
    for py in 0..h {
        for px in 0..w {
            let i = py * w + px;
            f_out[i] = f[i];
            e_out[i] = e[i];
            if spp_of(spp[i]) <= 0.0 {
                continue;
            }
            let mut window = Vec::with_capacity((2 * r + 1) * (2 * r + 1));
            for qy in py.saturating_sub(r)..(py + r + 1).min(h) {
                for qx in px.saturating_sub(r)..(px + r + 1).min(w) {
                    let q = qy * w + qx;
                    if spp_of(spp[q]) > 0.0 {
                        window.push(var(q));
                    }
                }
            }
            let big_v = var(i).max(trimmed_mean(&mut window));
            let ei = if e[i] > 0.0 { e[i] as f64 } else { 0.0 };
            let bias = if rs > 0 {
                residual_bound(push, (f, y, v, spp), (px, py))
            } else {
                0.0
            };
            let mi = ei.max(bias);
            let s = big_v.max(mi);
            if s.is_nan() || s <= 0.0 || s.is_infinite() {
                continue;
            }
            let (a, b) = (big_v / s, (k * (ei / s)).max(bias / s));
            let (wy, wf) = (b / (a + b), a / (a + b));
            let fi = f[i] as f64;
            let o = fi + wy * (y[i] as f64 - fi);
            let eo = wf * wf * mi + wy * wy * big_v;
            if !o.is_finite() || o > f32::MAX as f64 || !eo.is_finite() || eo > f32::MAX as f64 {
                continue;
            }
            f_out[i] = o.max(0.0) as f32;
            e_out[i] = eo as f32;
        }
    }
}

/// The mean of `values` without its `⌈n/10⌉` largest, at most
/// [`BLEND_TRIM_MAX`] and never all of them (BLEND-TRIM): the variance
/// window's floor, which a lamp's few pixels beside a dark one do not
/// lift. Reorders `values`; NaN for none.
pub fn trimmed_mean(values: &mut [f64]) -> f64 {
    let n = values.len();
    let drop = n.div_ceil(10).min(n.saturating_sub(1)).min(BLEND_TRIM_MAX);
    values.sort_by(|a, b| b.total_cmp(a));
    let rest = &values[drop..];
    rest.iter().sum::<f64>() / rest.len() as f64
}

/// The residual's bound `B` at pixel `(px, py)` (BLEND-RESIDUAL): the mean
/// of `(f − y)² − v` over the valid pixels within `push.residual_radius`,
/// less `z` standard deviations of that mean were `f` exact
/// (`√(2 Σ v²) / n`); 0 where a term is not finite or exceeds f32's
/// largest, as in the kernel.
pub fn residual_bound(
    push: &BlendPush,
    (f, y, v, spp): (&[f32], &[f32], &[f32], &[f32]),
    (px, py): (usize, usize),
) -> f64 {
    let (w, h) = (push.width as usize, push.height as usize);
    let r = push.residual_radius as usize;
    let big = f32::MAX as f64;
    let (mut n, mut d2, mut mv, mut mv2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for qy in py.saturating_sub(r)..(py + r + 1).min(h) {
        for qx in px.saturating_sub(r)..(px + r + 1).min(w) {
            let q = qy * w + qx;
            if spp_of(spp[q]) > 0.0 {
                let d = f[q] as f64 - y[q] as f64;
                let vq = (v[q] as f64).max(0.0);
                if !(d * d <= big && vq * vq <= big) {
                    return 0.0;
                }
                n += 1.0;
                d2 += d * d;
                mv += vq;
                mv2 += vq * vq;
            }
        }
    }
    d2 / n - mv / n - push.z as f64 * ((mv2 / n).sqrt() * (2.0 / n).sqrt())
}
