//! Scalar twin of `spirv/outlier_detect.comp`: outlier detection and
//! replacement (spec §4.4 steps 1–3). The kernel merges `outlier_rows`'
//! half-row summaries; the twin computes the same statistics of
//! `Ω_o(14) \ {o}` from their definition ([`super::outliers::detect_at`]), so
//! it reads no summaries.

use super::outliers::{detect_at, DETECT_RADIUS, K_SIGMA, MIN_NEIGHBOURS};
use crate::shared::OutlierPush;

/// Writes the replaced colour and variance (a copy where nothing is detected)
/// and the excess `e = y_o − y_q*` (0 elsewhere).
pub fn outlier_detect(
    push: &OutlierPush,
    color: [&[f32]; 3],
    var: [&[f32]; 3],
    spp: &[f32],
    out_color: [&mut [f32]; 3],
    out_var: [&mut [f32]; 3],
    e: [&mut [f32]; 3],
) {
    assert_eq!(
        push.radius as usize, DETECT_RADIUS,
        "the twin implements R = 14"
    );
    assert_eq!(push.min_n, MIN_NEIGHBOURS);
    assert_eq!(push.k_sigma as f64, K_SIGMA);
    let (w, h) = (push.width as usize, push.height as usize);
    for o in 0..w * h {
        let q = detect_at(w, h, color, var, spp, o).unwrap_or(o);
        for ch in 0..3 {
            out_color[ch][o] = color[ch][q];
            out_var[ch][o] = var[ch][q];
            e[ch][o] = (color[ch][o] as f64 - color[ch][q] as f64) as f32;
        }
    }
}
