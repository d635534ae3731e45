//! Scalar twin of `spirv/auto_score.comp`: the six maps `--method auto`
//! smooths (AUTO-BLEND).

use crate::shared::{AutoPush, AUTO_MAPS, AUTO_MEMBERS, AUTO_SCORE_MAX};

/// One member's planes: colour R, G, B or error R, G, B.
pub type Rgb<'a> = [&'a [f32]; 3];

fn finite_or_max(v: f64) -> f32 {
    let s = v as f32;
    if s.is_finite() {
        s
    } else {
        AUTO_SCORE_MAX
    }
}

/// Per pixel (`row0` ignored): `maps[m] = Σ_c max(E_m,c, 0) / (f_m,c² +
/// 0.01)` for the members `m = 0, 1, 2`, then `maps[3..6] = Σ_c (f_a,c −
/// f_b,c)² / (f̄_c² + 0.01)` for the pairs 01, 02, 12 (`f̄` the members'
/// mean); [`AUTO_SCORE_MAX`] where a value is not finite.
pub fn auto_score(
    push: &AutoPush,
    colors: [Rgb; AUTO_MEMBERS],
    errors: [Rgb; AUTO_MEMBERS],
    maps: &mut [Vec<f32>; AUTO_MAPS],
) {
    let n = (push.width * push.height) as usize;
    for i in 0..n {
        let f = |m: usize, c: usize| colors[m][c][i] as f64;
        for m in 0..AUTO_MEMBERS {
            let s: f64 = (0..3)
                .map(|c| (errors[m][c][i] as f64).max(0.0) / (f(m, c) * f(m, c) + 0.01))
                .sum();
            maps[m][i] = finite_or_max(s);
        }
        for (k, (a, b)) in [(0, 1), (0, 2), (1, 2)].into_iter().enumerate() {
            let d: f64 = (0..3)
                .map(|c| {
                    let fbar = (f(0, c) + f(1, c) + f(2, c)) / 3.0;
                    let d = f(a, c) - f(b, c);
                    d * d / (fbar * fbar + 0.01)
                })
                .sum();
            maps[AUTO_MEMBERS + k][i] = finite_or_max(d);
        }
    }
}
