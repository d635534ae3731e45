//! Scalar twin of `spirv/outlier_rows.comp`: per pixel, the (count, mean, M2)
//! of grey over the valid pixels of the left `[x − R, x − 1]` and right
//! `[x + 1, x + R]` row segments (spec §4.4 step 1, the row part).

use super::outliers::grey;
use super::spp_of;
use crate::shared::OutlierPush;

/// `(count, mean, M2)` of `grey` over the valid pixels of row `y`, `[a, b)`.
fn segment(
    push: &OutlierPush,
    color: [&[f32]; 3],
    spp: &[f32],
    y: usize,
    a: usize,
    b: usize,
) -> [f64; 3] {
    let w = push.width as usize;
    let vals: Vec<f64> = (a..b)
        .map(|x| y * w + x)
        .filter(|&q| spp_of(spp[q]) >= 1.0)
        .map(|q| grey(color, q))
        .collect();
    if vals.is_empty() {
        return [0.0; 3];
    }
    let n = vals.len() as f64;
    let m = vals.iter().sum::<f64>() / n;
    [n, m, vals.iter().map(|v| (v - m) * (v - m)).sum()]
}

/// The order-preserving u32 key of a grey value rounded to f32 (unsigned
/// order of keys = numeric order of greys).
pub fn key(g: f64) -> u32 {
    let b = (g as f32).to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// `out` = left count, mean, M2, right count, mean, M2; `keys` = [`key`] of
/// each pixel's grey.
pub fn outlier_rows(
    push: &OutlierPush,
    color: [&[f32]; 3],
    spp: &[f32],
    out: [&mut [f32]; 6],
    keys: &mut [u32],
) {
    let (w, h, r) = (
        push.width as usize,
        push.height as usize,
        push.radius as usize,
    );
    for y in 0..h {
        for x in 0..w {
            let l = segment(push, color, spp, y, x.saturating_sub(r), x);
            let rt = segment(push, color, spp, y, x + 1, (x + r + 1).min(w));
            for (k, v) in l.iter().chain(rt.iter()).enumerate() {
                out[k][y * w + x] = *v as f32;
            }
            keys[y * w + x] = key(grey(color, y * w + x));
        }
    }
}
