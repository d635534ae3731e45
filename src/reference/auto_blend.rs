//! Scalar twin of `spirv/auto_blend.comp`: `--method auto`'s blend of its
//! members (AUTO-BLEND), all of its per-member dispatches at once, the sums
//! kept in f64.

use super::auto_score::Rgb;
use crate::shared::{auto_pairs, AutoPush, AUTO_SCORE_FLOOR};

/// One member's inputs to the blend.
#[derive(Copy, Clone)]
pub struct Member<'a> {
    /// Its colour.
    pub color: Rgb<'a>,
    /// Its error estimate.
    pub error: Rgb<'a>,
    /// Its smoothed score (`auto_score`, then smoothed).
    pub score: &'a [f32],
}

/// Member `m`'s hat estimate of the `members.len()`-cornered hat from the
/// smoothed disagreements `d` (in [`auto_pairs`]' order): `(Σ_{b≠m} d_mb −
/// D / (n − 1)) / (n − 2)`, `D` the sum of all.
pub fn hat(d: &[f64], n: usize, m: usize) -> f64 {
    let (mut total, mut mine) = (0.0, 0.0);
    for (k, &(a, b)) in auto_pairs(n).iter().enumerate() {
        total += d[k];
        if a == m || b == m {
            mine += d[k];
        }
    }
    (mine - total / (n - 1) as f64) / (n - 2) as f64
}

/// Per pixel (`row0` ignored), from the smoothed disagreements `dis`
/// (`auto_dis`'s, smoothed): member `m`'s hat estimate `t_m` ([`hat`]), its
/// score `s_m = max(score_m, t_m)`, weight `w_m = 1 / max(s_m,
/// AUTO_SCORE_FLOOR)` (0 where its colour, error or score is not finite)
/// and factor `k_m = s_m / score_m` (1 where `score_m = 0`); `color =
/// Σ w_m f_m / Σ w_m` and `error = (Σ w_m √(k_m E_m) / Σ w_m)²` per
/// channel (0 where `Σ w = 0`).
pub fn auto_blend(
    push: &AutoPush,
    members: &[Member],
    dis: &[&[f32]],
    color: [&mut [f32]; 3],
    error: [&mut [f32]; 3],
) {
    let n = (push.width * push.height) as usize;
    let count = members.len();
    let [cr, cg, cb] = color;
    let [er, eg, eb] = error;
    for i in 0..n {
        let d: Vec<f64> = dis.iter().map(|p| p[i] as f64).collect();
        let (mut root, mut num, mut ws) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
        let mut base: Option<[f64; 3]> = None;
        for (m, mem) in members.iter().enumerate() {
            let ok = mem.color.iter().chain(&mem.error).all(|p| p[i].is_finite())
                && mem.score[i].is_finite();
            if !ok {
                continue;
            }
            let s = mem.score[i] as f64;
            let best = s.max(hat(&d, count, m));
            let w = 1.0 / best.max(AUTO_SCORE_FLOOR);
            let k = if s > 0.0 { best / s } else { 1.0 };
            let f: [f64; 3] = std::array::from_fn(|c| mem.color[c][i] as f64);
            // The first usable member plus the weighted differences, as the
            // kernel: members that agree give their colour back exactly.
            let b = *base.get_or_insert(f);
            for c in 0..3 {
                num[c] += w * (f[c] - b[c]);
                root[c] += w * (k * (mem.error[c][i] as f64).max(0.0)).sqrt();
            }
            ws += w;
        }
        let inv = if ws > 0.0 { 1.0 / ws } else { 0.0 };
        let b = base.unwrap_or([0.0; 3]);
        for (c, (o, e)) in [
            (&mut *cr, &mut *er),
            (&mut *cg, &mut *eg),
            (&mut *cb, &mut *eb),
        ]
        .into_iter()
        .enumerate()
        {
            o[i] = (b[c] + num[c] * inv) as f32;
            let r = root[c] * inv;
            e[i] = (r * r) as f32;
        }
    }
}
