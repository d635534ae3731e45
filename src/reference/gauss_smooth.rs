//! Scalar twin of `spirv/gauss_smooth.comp`: the Gaussian map smoothing `G_σ`
//! of spec §0.5 (used for `hbar = G_1(h_opt)`, §2.3 step 8, and for the
//! sampling map, §9.1).

use super::spp_of;
use crate::shared::SmoothPush;

/// For every pixel `p` of the image (`row0` ignored): the mean of `map(q)`
/// over the valid pixels `q` (`spp_of >= 1`) with `|q − p|_inf <= push.radius`
/// (clipped to the image), weighted by `exp(−|q−p|²/(2σ²))`; 0 if there is
/// none. Invalid pixels receive the smoothed value of their valid neighbours.
/// `push.radius` is the caller's `ceil(3σ)`. `σ <= 0` degenerates to the
/// identity on valid pixels (0 elsewhere).
pub fn gauss_smooth(push: &SmoothPush, map: &[f32], spp: &[f32], out: &mut [f32]) {
    let (w, h) = (push.width as usize, push.height as usize);
    let r = push.radius as usize;
    let sigma = push.sigma as f64;
    for y in 0..h {
        for x in 0..w {
            let (mut num, mut den) = (0.0, 0.0);
            for qy in y.saturating_sub(r)..(y + r + 1).min(h) {
                for qx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    let q = qy * w + qx;
                    if spp_of(spp[q]) < 1.0 {
                        continue;
                    }
                    let (dx, dy) = (qx as f64 - x as f64, qy as f64 - y as f64);
                    let r2 = dx * dx + dy * dy;
                    let g = if sigma > 0.0 {
                        (-r2 / (2.0 * sigma * sigma)).exp()
                    } else if r2 == 0.0 {
                        1.0
                    } else {
                        0.0
                    };
                    num += g * map[q] as f64;
                    den += g;
                }
            }
            out[y * w + x] = if den > 0.0 { (num / den) as f32 } else { 0.0 };
        }
    }
}
