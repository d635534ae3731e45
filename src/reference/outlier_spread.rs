//! Scalar twin of `spirv/outlier_spread.comp`: the redistribution applied
//! (spec §4.4 step 4), `ŷ ← max(0, ŷ(1 + Σρ) + Σadd)` over the window, from
//! `box_rows`' row sums of the weights; in place.

use super::box_rows::box_cols;
use super::spp_of;
use crate::shared::OutlierPush;

/// Applies the row-summed weights `rho`, `add` to `y` at valid pixels where
/// some weight reaches them (OUTLIER-CLAMP there).
pub fn outlier_spread(
    push: &OutlierPush,
    rho: [&[f32]; 3],
    add: [&[f32]; 3],
    spp: &[f32],
    y: [&mut [f32]; 3],
) {
    let (w, h, r) = (
        push.width as usize,
        push.height as usize,
        push.radius as usize,
    );
    for i in 0..w * h {
        if spp_of(spp[i]) < 1.0 {
            continue;
        }
        let (px, py) = (i % w, i / w);
        let rs: [f64; 3] = std::array::from_fn(|ch| box_cols(w, h, r, rho[ch], px, py));
        let a: [f64; 3] = std::array::from_fn(|ch| box_cols(w, h, r, add[ch], px, py));
        if rs == [0.0; 3] && a == [0.0; 3] {
            continue;
        }
        for ch in 0..3 {
            y[ch][i] = (y[ch][i] as f64 * (1.0 + rs[ch]) + a[ch]).max(0.0) as f32;
        }
    }
}
