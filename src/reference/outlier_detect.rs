//! Scalar twin of `spirv/outlier_detect.comp`: outlier detection (spec §4.4
//! step 1). The kernel merges `outlier_rows`' row summaries; the twin
//! computes the same statistics of `Ω_o(14) \ {o}` from their definition
//! ([`super::outliers::is_outlier`]) over the pixels `kept` by OUTLIER-CLIP
//! (the nonzero keys the kernel's summaries were made from), so it reads no
//! summaries.

use super::outliers::{is_outlier, DETECT_RADIUS, K_SIGMA, MIN_NEIGHBOURS};
use crate::shared::{OutlierPush, DETECT_RIM};

/// Zeroes the excess `e` and returns the detected pixels in raster order
/// (the kernel's queue holds the same set in any order); `push.mode`
/// [`DETECT_RIM`] is OUTLIER-RIM.
pub fn outlier_detect(
    push: &OutlierPush,
    color: [&[f32]; 3],
    var: [&[f32]; 3],
    spp: &[f32],
    kept: &[bool],
    e: [&mut [f32]; 3],
) -> Vec<usize> {
    assert_eq!(
        push.radius as usize, DETECT_RADIUS,
        "the twin implements R = 14"
    );
    assert_eq!(push.min_n, MIN_NEIGHBOURS);
    assert_eq!(push.k_sigma as f64, K_SIGMA);
    let (w, h) = (push.width as usize, push.height as usize);
    let rim = push.mode == DETECT_RIM;
    for plane in e {
        plane.fill(0.0);
    }
    (0..w * h)
        .filter(|&o| is_outlier(w, h, color, var, spp, kept, rim, o))
        .collect()
}
