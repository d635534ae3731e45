//! Scalar twin of `spirv/auto_dis.comp`: how far each pair of `--method
//! auto`'s members disagrees (AUTO-BLEND).

use super::auto_score::{finite_or_max, Rgb};
use crate::shared::{auto_pairs, AutoPush};

/// Per pixel (`row0` ignored), for the `colors.len()` (3 or 4) members:
/// `dis[k] = Σ_c (f_a,c − f_b,c)² / (f̄_c² + 0.01)` for the `k`-th pair
/// `(a, b)` of [`auto_pairs`] (`f̄` the members' mean);
/// [`crate::shared::AUTO_SCORE_MAX`] where a value is not finite.
pub fn auto_dis(push: &AutoPush, colors: &[Rgb], dis: &mut [Vec<f32>]) {
    let n = (push.width * push.height) as usize;
    let members = colors.len();
    let pairs = auto_pairs(members);
    for i in 0..n {
        let f = |m: usize, c: usize| colors[m][c][i] as f64;
        let fbar: [f64; 3] =
            std::array::from_fn(|c| (0..members).map(|m| f(m, c)).sum::<f64>() / members as f64);
        for (k, &(a, b)) in pairs.iter().enumerate() {
            let d: f64 = (0..3)
                .map(|c| {
                    let d = f(a, c) - f(b, c);
                    d * d / (fbar[c] * fbar[c] + 0.01)
                })
                .sum();
            dis[k][i] = finite_or_max(d);
        }
    }
}
