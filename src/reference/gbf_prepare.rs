//! Scalar twin of `spirv/gbf_prepare.comp`: G-buffer prefilter step 1
//! (spec §6) — the covariance smoothed with `G_1.5`, regularised (S-PSD)
//! and inverted, per pixel ([`super::gbf::prepare_pixel`]).

use super::gbf::prepare_pixel;
use crate::shared::GbfPush;

/// `S̃⁻¹` (six planes, `XX XY XZ YY YZ ZZ`) for every pixel (`row0`
/// ignored), from the covariance `cov` and the position.
pub fn gbf_prepare(
    push: &GbfPush,
    cov: [&[f32]; 6],
    pos: [&[f32]; 3],
    spp: &[f32],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), 6, "gbf_prepare: output planes");
    let (w, h) = (push.width as usize, push.height as usize);
    super::wlr::par_pixels::<6>(w, h, out, |x, y| {
        prepare_pixel(cov, pos, spp, w, h, x, y).map(|v| v as f32)
    });
}
