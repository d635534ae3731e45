//! Scalar twin of `spirv/outlier_weights.comp`: the redistribution weights of
//! spec §4.4 step 4 at each pixel with an excess, from `box_rows`' row sums of
//! ŷ and of the valid count (DARK-WINDOW included).

use super::box_rows::box_cols;
use crate::shared::OutlierPush;

/// `rho = e/S` per channel, or `add = e/|Ω|` where `S <= dark·|Ω|`; both 0
/// where `e = 0` in every channel.
pub fn outlier_weights(
    push: &OutlierPush,
    e: [&[f32]; 3],
    sums: [&[f32]; 3],
    count: &[f32],
    rho: [&mut [f32]; 3],
    add: [&mut [f32]; 3],
) {
    let (w, h, r) = (
        push.width as usize,
        push.height as usize,
        push.radius as usize,
    );
    for o in 0..w * h {
        let (x, y) = (o % w, o / w);
        for ch in 0..3 {
            rho[ch][o] = 0.0;
            add[ch][o] = 0.0;
        }
        if (0..3).all(|ch| e[ch][o] == 0.0) {
            continue;
        }
        let n = box_cols(w, h, r, count, x, y);
        if n <= 0.0 {
            continue;
        }
        for ch in 0..3 {
            let s = box_cols(w, h, r, sums[ch], x, y);
            if s <= push.dark as f64 * n {
                add[ch][o] = (e[ch][o] as f64 / n) as f32;
            } else {
                rho[ch][o] = (e[ch][o] as f64 / s) as f32;
            }
        }
    }
}
