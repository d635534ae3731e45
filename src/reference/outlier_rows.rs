//! Scalar twin of `spirv/outlier_rows.comp`: per pixel, the (count, mean, M2)
//! of grey over the valid pixels of the row segment `[x − R, x + R]` with
//! the pixel itself and without it (spec §4.4 step 1, the row part), from
//! the keys of [`super::outlier_grey`] (0: invalid).

use super::outlier_grey::unkey;
use crate::shared::OutlierPush;

/// `(count, mean, M2)` of the greys of the valid keys of `keys` (two passes).
fn summary(keys: impl Iterator<Item = u32> + Clone) -> [f64; 3] {
    let vals = keys.filter_map(unkey).map(f64::from);
    let n = vals.clone().count() as f64;
    if n == 0.0 {
        return [0.0; 3];
    }
    let m = vals.clone().sum::<f64>() / n;
    [n, m, vals.map(|v| (v - m) * (v - m)).sum()]
}

/// `out` = count, mean, M2 of row `y` over `[x − R, x + R]` (clipped) with
/// pixel `x`, then the same without it.
pub fn outlier_rows(push: &OutlierPush, keys: &[u32], out: [&mut [f32]; 6]) {
    let (w, h, r) = (
        push.width as usize,
        push.height as usize,
        push.radius as usize,
    );
    for y in 0..h {
        let row = &keys[y * w..(y + 1) * w];
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r + 1).min(w));
            let with = summary(row[a..b].iter().copied());
            let without = summary(
                row[a..b]
                    .iter()
                    .enumerate()
                    .filter(|&(k, _)| a + k != x)
                    .map(|(_, &v)| v),
            );
            for (k, v) in with.iter().chain(without.iter()).enumerate() {
                out[k][y * w + x] = *v as f32;
            }
        }
    }
}
