//! Scalar twin of `spirv/box_rows.comp`, one plane at a time: the row part of
//! a box sum over valid pixels, `Σ_{|qx − x| <= R, valid} value`, or the count
//! of valid pixels when `push.mode` has [`BOX_COUNT_LAST`].

use super::spp_of;
use crate::shared::{OutlierPush, BOX_COUNT_LAST};

/// Row sums (or counts) of `value` over `|qx − x| <= push.radius`, clipped.
pub fn box_rows(push: &OutlierPush, value: &[f32], spp: &[f32], out: &mut [f32]) {
    let (w, h, r) = (
        push.width as usize,
        push.height as usize,
        push.radius as usize,
    );
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0f64;
            for qx in x.saturating_sub(r)..(x + r + 1).min(w) {
                let q = y * w + qx;
                if spp_of(spp[q]) >= 1.0 {
                    s += if push.mode & BOX_COUNT_LAST != 0 {
                        1.0
                    } else {
                        value[q] as f64
                    };
                }
            }
            out[y * w + x] = s as f32;
        }
    }
}

/// Column sums over `|qy − y| <= r`, clipped, of a row-sum plane: with
/// [`box_rows`], the sum over the square window. For the twins of the column
/// kernels.
pub fn box_cols(w: usize, h: usize, r: usize, rows: &[f32], x: usize, y: usize) -> f64 {
    (y.saturating_sub(r)..(y + r + 1).min(h))
        .map(|qy| rows[qy * w + x] as f64)
        .sum()
}
