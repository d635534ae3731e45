//! Scalar twin of `spirv/finalize_covariance.comp` (f64 arithmetic).

use super::finalize_stats::spp_of;
use crate::shared::FinalizePush;

/// `v` if it is finite and within f32 range, else 0: how a variance or
/// covariance that the sums cannot give (non-finite or huge sums, e.g. from
/// positions far beyond a scene's range) is stored. Mirrors `kept` in
/// `spirv/finalize_covariance.comp`.
pub fn kept(v: f64) -> f64 {
    if v.is_finite() && v.abs() <= f32::MAX as f64 {
        v
    } else {
        0.0
    }
}

/// Position covariance of the samples divided by n, with the diagonal clamped
/// to ≥ 0 and each off-diagonal to `|S_ab| ≤ sqrt(S_aa S_bb)`.
/// `cov` receives XX XY XZ YY YZ ZZ. Always finite: an entry that is not
/// finite in f32 (NaN, ±∞ or beyond f32 range, from non-finite or
/// overflowing sums) is 0 ([`kept`]), the diagonal before the clamp (so a
/// zeroed variance zeroes its covariances too).
pub fn finalize_covariance(
    push: &FinalizePush,
    sums: [&[f32]; 3],
    sumsqs: [&[f32]; 3],
    cross: [&[f32]; 3],
    count: &[f32],
    cov: &mut [Vec<f32>; 6],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let n = spp_of(count[i]);
            let mut out = [0.0f64; 6];
            if n >= 1.0 {
                let m: [f64; 3] = std::array::from_fn(|a| sums[a][i] as f64 / n);
                let d: [f64; 3] = std::array::from_fn(|a| {
                    kept(((sumsqs[a][i] as f64 - n * m[a] * m[a]) / n).max(0.0))
                });
                let off = |s: f32, a: usize, b: usize| {
                    let c = (s as f64 - n * m[a] * m[b]) / n;
                    // Finite (both factors are within f32 range) and ≥ 0.
                    let bound = (d[a] * d[b]).sqrt();
                    kept(c).clamp(-bound, bound)
                };
                out = [
                    d[0],
                    off(cross[0][i], 0, 1),
                    off(cross[1][i], 0, 2),
                    d[1],
                    off(cross[2][i], 1, 2),
                    d[2],
                ];
            }
            for k in 0..6 {
                cov[k][i] = out[k] as f32;
            }
        }
    }
}
