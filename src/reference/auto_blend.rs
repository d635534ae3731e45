//! Scalar twin of `spirv/auto_blend.comp`: `--method auto`'s blend of its
//! three members (AUTO-BLEND).

use super::auto_score::Rgb;
use crate::shared::{AutoPush, AUTO_MAPS, AUTO_MEMBERS, AUTO_SCORE_FLOOR};

/// Per pixel (`row0` ignored), from the smoothed `maps` (`auto_score`'s):
/// member `m`'s hat estimate `t_m = (dis_ma + dis_mb − dis_ab) / 2`, its
/// score `s_m = max(score_m, t_m)`, weight `w_m = 1 / max(s_m,
/// AUTO_SCORE_FLOOR)` (0 where its colour, error or score is not finite)
/// and factor `k_m = s_m / score_m` (1 where `score_m = 0`); `color =
/// Σ w_m f_m / Σ w_m` and `error = (Σ w_m √(k_m E_m) / Σ w_m)²` per
/// channel (0 where `Σ w = 0`).
pub fn auto_blend(
    push: &AutoPush,
    colors: [Rgb; AUTO_MEMBERS],
    errors: [Rgb; AUTO_MEMBERS],
    maps: [&[f32]; AUTO_MAPS],
    color: [&mut [f32]; 3],
    error: [&mut [f32]; 3],
) {
    let n = (push.width * push.height) as usize;
    let [cr, cg, cb] = color;
    let [er, eg, eb] = error;
    for i in 0..n {
        let d = |k: usize| maps[AUTO_MEMBERS + k][i] as f64;
        let (d01, d02, d12) = (d(0), d(1), d(2));
        let hat = [
            0.5 * (d01 + d02 - d12),
            0.5 * (d01 + d12 - d02),
            0.5 * (d02 + d12 - d01),
        ];
        let (mut root, mut ws) = ([0.0f64; 3], 0.0f64);
        let mut weights = [0.0f64; AUTO_MEMBERS];
        let mut base = None;
        for m in 0..AUTO_MEMBERS {
            let ok = colors[m].iter().chain(&errors[m]).all(|p| p[i].is_finite())
                && maps[m][i].is_finite();
            if !ok {
                continue;
            }
            let s = maps[m][i] as f64;
            let best = s.max(hat[m]);
            let w = 1.0 / best.max(AUTO_SCORE_FLOOR);
            let k = if s > 0.0 { best / s } else { 1.0 };
            for c in 0..3 {
                root[c] += w * (k * (errors[m][c][i] as f64).max(0.0)).sqrt();
            }
            weights[m] = w;
            ws += w;
            base.get_or_insert(m);
        }
        let f = |m: usize, c: usize| colors[m][c][i] as f64;
        let mut num = [0.0f64; 3];
        let inv = if ws > 0.0 { 1.0 / ws } else { 0.0 };
        // The first usable member plus the weighted differences, as the
        // kernel: members that agree give their colour back exactly.
        if let Some(b) = base {
            for (c, n) in num.iter_mut().enumerate() {
                let d: f64 = (0..AUTO_MEMBERS)
                    .filter(|&m| weights[m] > 0.0)
                    .map(|m| weights[m] * (f(m, c) - f(b, c)))
                    .sum();
                *n = f(b, c) + d * inv;
            }
        }
        for (c, (o, e)) in [
            (&mut *cr, &mut *er),
            (&mut *cg, &mut *eg),
            (&mut *cb, &mut *eb),
        ]
        .into_iter()
        .enumerate()
        {
            o[i] = num[c] as f32;
            let r = root[c] * inv;
            e[i] = (r * r) as f32;
        }
    }
}
