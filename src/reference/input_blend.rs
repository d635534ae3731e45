//! Scalar twin of `spirv/input_blend.comp`: one channel of a
//! reconstruction blended with its input by inverse error (INPUT-BLEND).

use super::finalize_stats::spp_of;
use crate::shared::BlendPush;

/// Per valid pixel `i` (`n ≥ 1`), with `V = max(v_i, mean of v over the
/// valid pixels within radius r)` (negative variances read as 0) and
/// `E = max(E_i, 0)`:
/// `f'_i = max((V f_i + k E y_i) / (V + k E), 0)` and
/// `E'_i = V E (V + k² E) / (V + k E)²`, computed as `f + w_y (y − f)` and
/// `w_f² E + w_y² V` from `V` and `E` divided by the larger, as the kernel
/// does in f32. An invalid pixel, one with `V + k E` zero or not finite,
/// or one whose blend is not finite (or whose `E'` exceeds f32), keeps
/// `f_i` and `E_i`.
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
    let var = |q: usize| (v[q] as f64).max(0.0);
    for py in 0..h {
        for px in 0..w {
            let i = py * w + px;
            f_out[i] = f[i];
            e_out[i] = e[i];
            if spp_of(spp[i]) <= 0.0 {
                continue;
            }
            let (mut sum, mut count) = (0.0, 0.0);
            for qy in py.saturating_sub(r)..(py + r + 1).min(h) {
                for qx in px.saturating_sub(r)..(px + r + 1).min(w) {
                    let q = qy * w + qx;
                    if spp_of(spp[q]) > 0.0 {
                        sum += var(q);
                        count += 1.0;
                    }
                }
            }
            let big_v = var(i).max(sum / count);
            let ei = if e[i] > 0.0 { e[i] as f64 } else { 0.0 };
            let s = big_v.max(ei);
            if s.is_nan() || s <= 0.0 || s.is_infinite() {
                continue;
            }
            let (a, b) = (big_v / s, k * (ei / s));
            let (wy, wf) = (b / (a + b), a / (a + b));
            let fi = f[i] as f64;
            let o = fi + wy * (y[i] as f64 - fi);
            let eo = wf * wf * ei + wy * wy * big_v;
            if !o.is_finite() || o > f32::MAX as f64 || !eo.is_finite() || eo > f32::MAX as f64 {
                continue;
            }
            f_out[i] = o.max(0.0) as f32;
            e_out[i] = eo as f32;
        }
    }
}
