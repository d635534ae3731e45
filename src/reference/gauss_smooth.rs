//! Scalar twin of `spirv/gauss_smooth.comp`: the Gaussian map smoothing `G_σ`
//! of spec §0.5 (used for `hbar = G_1(h_opt)`, §2.3 step 8, `G_1.5`, §6.2
//! step 8, and for the sampling map, §9.1), as the column pass over
//! [`gauss_rows`]' row sums; [`smooth`] runs both passes.

use super::gauss_rows::{column_sums, gauss_rows};
use crate::shared::SmoothPush;

/// For every pixel (`row0` ignored): `Σ gy·num / Σ gy·den` over the rows
/// `|q.y − y| <= push.radius` (clipped) of its column, 0 where the weights
/// sum to 0.
pub fn gauss_smooth(push: &SmoothPush, num: &[f32], den: &[f32], out: &mut [f32]) {
    let (w, h) = (push.width as usize, push.height as usize);
    let (r, sigma) = (push.radius as usize, push.sigma as f64);
    for y in 0..h {
        for x in 0..w {
            let [n, d] = column_sums((w, h), r, sigma, [num, den], (x, y));
            out[y * w + x] = if d > 0.0 { (n / d) as f32 } else { 0.0 };
        }
    }
}

/// `G_σ(map)` through both passes, with the row sums stored in f32 as on
/// the GPU: for every pixel `p`, the mean of `map(q)` over the valid pixels
/// `q` (`spp_of >= 1`) with `|q − p|_inf <= push.radius` (clipped to the
/// image), weighted by `exp(−|q−p|²/(2σ²))`; 0 if there is none. Invalid
/// pixels receive the smoothed value of their valid neighbours.
/// `push.radius` is the caller's `ceil(3σ)`. `σ <= 0` degenerates to the
/// identity on valid pixels (0 elsewhere).
pub fn smooth(push: &SmoothPush, map: &[f32], spp: &[f32], out: &mut [f32]) {
    let n = (push.width * push.height) as usize;
    let mut sums = vec![vec![0.0f32; n]];
    let mut den = vec![0.0f32; n];
    gauss_rows(push, &[map], spp, &mut sums, &mut den);
    gauss_smooth(push, &sums[0], &den, out);
}
