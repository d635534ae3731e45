//! Scalar twin of `spirv/outlier_grey.comp`: per pixel, the order-preserving
//! key of grey rounded to f32 (0 where the pixel is invalid), spec §4.4
//! step 1.

use super::outliers::grey;
use super::spp_of;
use crate::shared::OutlierPush;

/// The order-preserving u32 key of a grey value rounded to f32 (unsigned
/// order of keys = numeric order of greys). Never 0 for a non-NaN grey.
pub fn key(g: f64) -> u32 {
    let b = (g as f32).to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// The grey of a key from [`key`] (its inverse on f32 values); `None` for
/// 0, an invalid pixel's key.
pub fn unkey(k: u32) -> Option<f32> {
    (k != 0).then(|| {
        f32::from_bits(if k & 0x8000_0000 != 0 {
            k & 0x7fff_ffff
        } else {
            !k
        })
    })
}

/// `keys` = [`key`] of each valid pixel's grey, 0 where invalid.
pub fn outlier_grey(push: &OutlierPush, color: [&[f32]; 3], spp: &[f32], keys: &mut [u32]) {
    let n = push.width as usize * push.height as usize;
    for i in 0..n {
        keys[i] = if spp_of(spp[i]) >= 1.0 {
            key(grey(color, i))
        } else {
            0
        };
    }
}
