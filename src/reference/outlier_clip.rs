//! Scalar twin of `spirv/outlier_clip.comp`: one round of OUTLIER-CLIP
//! (ours, spec §4.4 step 1) on the kept keys, from the definition of the
//! window statistics (no row summaries): a kept pixel `o` is dropped (key 0)
//! when at least `min_n` kept pixels of `Ω_o(R) \ {o}` have mean `m` and
//! population standard deviation `sd` with `grey_o − m > k·sd` and either
//! `grey_o − m > k·se_o` (signal by OUTLIER-NOISE) or `grey_o − m >
//! CLIP_FAR·sd` ([`super::outliers::leaves_statistics`]). Every test reads
//! the keys as they were before the round.

use super::outlier_grey::unkey;
use super::outliers::{grey_sd, leaves_statistics, mean_sd};
use crate::shared::OutlierPush;

/// One round in place on `keys` (0: invalid or already dropped); `var` is
/// the colour's variance.
pub fn outlier_clip(push: &OutlierPush, var: [&[f32]; 3], keys: &mut [u32]) {
    let (w, h, r) = (
        push.width as usize,
        push.height as usize,
        push.radius as usize,
    );
    let before = keys.to_vec();
    let grey = |q: usize| unkey(before[q]).map(f64::from);
    for o in 0..w * h {
        let Some(g) = grey(o) else { continue };
        let (x, y) = (o % w, o / w);
        let vals: Vec<f64> = (y.saturating_sub(r)..(y + r + 1).min(h))
            .flat_map(|qy| (x.saturating_sub(r)..(x + r + 1).min(w)).map(move |qx| qy * w + qx))
            .filter(|&q| q != o)
            .filter_map(grey)
            .collect();
        let Some((m, sd)) = mean_sd(&vals, push.min_n) else {
            continue;
        };
        if leaves_statistics(g - m, sd, grey_sd(var, o), push.k_sigma as f64) {
            keys[o] = 0;
        }
    }
}
