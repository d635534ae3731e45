//! Scalar twin of `spirv/outlier_median.comp`: outlier replacement (spec
//! §4.4 steps 2–3) at the detected pixels, from the definition's median
//! ([`super::outliers::median_at`]), and (its `OUTLIER_APPLY` mode) the
//! replacements written into the statistics.

use super::outliers::{median_at, DETECT_RADIUS};
use crate::shared::OutlierPush;

/// At every pixel `o` of `detected`: the colour and variance of the median
/// pixel `q*` of its window, and `e = y_o − y_q*`. Other pixels are left as
/// they are.
#[allow(clippy::too_many_arguments)]
pub fn outlier_median(
    push: &OutlierPush,
    color: [&[f32]; 3],
    var: [&[f32]; 3],
    spp: &[f32],
    detected: &[usize],
    out_color: [&mut [f32]; 3],
    out_var: [&mut [f32]; 3],
    e: [&mut [f32]; 3],
) {
    assert_eq!(
        push.radius as usize, DETECT_RADIUS,
        "the twin implements R = 14"
    );
    let w = push.width as usize;
    let h = push.height as usize;
    for &o in detected {
        let q = median_at(w, h, color, spp, o);
        for ch in 0..3 {
            out_color[ch][o] = color[ch][q];
            out_var[ch][o] = var[ch][q];
            e[ch][o] = (color[ch][o] as f64 - color[ch][q] as f64) as f32;
        }
    }
}

/// `color[ch][o] = rep[ch][o]` and `var[ch][o] = rep[3 + ch][o]` for every
/// `o` of `detected`.
pub fn outlier_apply(
    detected: &[usize],
    rep: [&[f32]; 6],
    color: [&mut [f32]; 3],
    var: [&mut [f32]; 3],
) {
    for (ch, (c, v)) in color.into_iter().zip(var).enumerate() {
        for &o in detected {
            c[o] = rep[ch][o];
            v[o] = rep[3 + ch][o];
        }
    }
}
