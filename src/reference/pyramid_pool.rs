//! Scalar twin of `spirv/pyramid_pool.comp`: one statistics plane pooled
//! over 2×2 blocks into the pyramid's coarse level (PYRAMID-LOWBAND).

use super::finalize_stats::spp_of;
use crate::shared::{PyramidPush, PYRAMID_COUNT, PYRAMID_VARIANCE};

/// The coarse size of a `width × height` image: each side halved, rounded
/// up (a last odd row or column pools alone).
pub fn coarse_size(width: usize, height: usize) -> (usize, usize) {
    (width.div_ceil(2), height.div_ceil(2))
}

/// Per coarse pixel of the push's image (`width × height`; the fine image
/// is `other_width × other_height`), over the fine pixels of its block
/// with `n ≥ 1` (`N = Σ n`): a mean `Σ n x / N`, the variance of a mean
/// `Σ n² v / N²`, or the count `N`, by [`PyramidPush::kind`]; 0 where
/// `N = 0`.
pub fn pyramid_pool(push: &PyramidPush, src: &[f32], spp: &[f32], dst: &mut [f32]) {
    let (w, h) = (push.width as usize, push.height as usize);
    let (fw, fh) = (push.other_width as usize, push.other_height as usize);
    for y in 0..h {
        for x in 0..w {
            let (mut total, mut acc) = (0.0f64, 0.0f64);
            for dy in 0..2 {
                for dx in 0..2 {
                    let (fx, fy) = (2 * x + dx, 2 * y + dy);
                    if fx < fw && fy < fh {
                        let j = fy * fw + fx;
                        let n = spp_of(spp[j]);
                        if n > 0.0 {
                            let weight = if push.kind == PYRAMID_VARIANCE {
                                n * n
                            } else {
                                n
                            };
                            total += n;
                            acc += weight * src[j] as f64;
                        }
                    }
                }
            }
            dst[y * w + x] = if push.kind == PYRAMID_COUNT {
                total
            } else if total <= 0.0 {
                0.0
            } else if push.kind == PYRAMID_VARIANCE {
                acc / (total * total)
            } else {
                acc / total
            } as f32;
        }
    }
}
