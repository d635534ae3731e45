//! Scalar twin of `spirv/gbf_sure.comp`: G-buffer prefilter steps 2–7
//! (spec §6) per pixel — SURE at the six trial bandwidths and `h_opt`.
//! The routines are in [`super::gbf`].

use super::gbf::{choose, sure, Planes};
use crate::shared::GbfPush;

/// `h_opt` for every pixel (`row0` ignored); 0 for an invalid pixel.
/// `inv` = `S̃⁻¹` from [`gbf_prepare`](super::gbf_prepare).
pub fn gbf_sure(
    push: &GbfPush,
    pos: [&[f32]; 3],
    pos_var: [&[f32]; 3],
    inv: [&[f32]; 6],
    spp: &[f32],
    out: &mut [f32],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    let p = Planes {
        width: w,
        height: h,
        pos,
        pos_var: Some(pos_var),
        inv,
        spp,
    };
    let mut planes = vec![vec![0.0f32; w * h]];
    super::wlr::par_pixels::<1>(w, h, &mut planes, |x, y| {
        if !p.valid(y * w + x) {
            return [0.0];
        }
        [choose(&sure(&p, x, y)) as f32]
    });
    out[..w * h].copy_from_slice(&planes[0]);
}
