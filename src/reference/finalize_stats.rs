//! Scalar twin of `spirv/finalize_stats.comp` (f64 arithmetic, f32 storage).

use crate::shared::FinalizePush;

/// The sample count as every kernel reads it (spec §0.2): non-finite or
/// below 1 → 0 (invalid pixel). Mirrors `spp_of` in `spirv/lib/common.glsl`.
pub fn spp_of(s: f32) -> f64 {
    if s.is_finite() && s >= 1.0 {
        s as f64
    } else {
        0.0
    }
}

/// One channel: `mean = origin + Σx / n` (the sums are relative to
/// `push.origin`), `var = max(Σx² − Σx·mean, 0) / (n − 1) / n`
/// (unbiased sample variance of the mean; 0 for n < 2; both 0 for n < 1).
pub fn finalize_stats(
    push: &FinalizePush,
    sum: &[f32],
    sumsq: &[f32],
    count: &[f32],
    mean_out: &mut [f32],
    var_out: &mut [f32],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let n = spp_of(count[i]);
            let (mut mean, mut var) = (0.0, 0.0);
            if n >= 1.0 {
                let s = sum[i] as f64;
                mean = s / n;
                if n >= 2.0 {
                    var = (sumsq[i] as f64 - s * mean).max(0.0) / (n - 1.0) / n;
                }
            }
            mean_out[i] = if n >= 1.0 {
                (push.origin as f64 + mean) as f32
            } else {
                0.0
            };
            var_out[i] = var as f32;
        }
    }
}
