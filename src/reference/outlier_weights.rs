//! Scalar twin of `spirv/outlier_weights.comp`: the redistribution weights of
//! spec §4.4 step 4 at each pixel with an excess, from `box_rows`' row sums of
//! ŷ and of the valid count (DARK-WINDOW included), for the outliers its mode
//! selects (OUTLIER-WIDE).

use super::box_rows::box_cols;
use crate::shared::{OutlierPush, WEIGHTS_NARROW, WEIGHTS_WIDE};

/// `rho = e/S` per channel, or `add = e/|Ω|` where `S <= dark·|Ω|`; both 0
/// where `e = 0` in every channel and at the outliers the mode leaves out.
/// `wide` marks the outliers sent to the wide window: mode
/// [`WEIGHTS_NARROW`] writes it (`Σe > push.wide · ΣS` over the channels)
/// and weighs only the others, [`WEIGHTS_WIDE`] weighs only those it marks,
/// mode 0 weighs every one and leaves it as it is.
#[allow(clippy::too_many_arguments)]
pub fn outlier_weights(
    push: &OutlierPush,
    e: [&[f32]; 3],
    sums: [&[f32]; 3],
    count: &[f32],
    wide: &mut [bool],
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
        let s: [f64; 3] = std::array::from_fn(|ch| box_cols(w, h, r, sums[ch], x, y));
        match push.mode {
            WEIGHTS_NARROW => {
                let excess: f64 = (0..3).map(|ch| e[ch][o] as f64).sum();
                wide[o] = excess > push.wide as f64 * (s[0] + s[1] + s[2]);
                if wide[o] {
                    continue;
                }
            }
            WEIGHTS_WIDE if !wide[o] => continue,
            _ => {}
        }
        for ch in 0..3 {
            if s[ch] <= push.dark as f64 * n {
                add[ch][o] = (e[ch][o] as f64 / n) as f32;
            } else {
                rho[ch][o] = (e[ch][o] as f64 / s[ch]) as f32;
            }
        }
    }
}
