//! Scalar twin of `spirv/gbf_prepare.comp`: G-buffer prefilter step 1
//! (spec §6) — the covariance smoothed with `G_1.5` (the column pass over
//! [`super::gauss_rows`]' row sums), regularised (S-PSD) and inverted
//! ([`super::gbf::regularised_inverse`]); [`prepare`] runs both passes.

use super::gauss_rows::{column_sums, gauss_rows};
use super::gbf::{regularised_inverse, SMOOTH_SIGMA};
use super::linalg::gaussian_radius;
use crate::shared::{GbfPush, SmoothPush};

/// `S̃⁻¹` (six planes, `XX XY XZ YY YZ ZZ`) for every pixel (`row0`
/// ignored), from the row sums of the six covariance entries (`rows`) and
/// of their weights (`den`), and the position.
pub fn gbf_prepare(
    push: &GbfPush,
    rows: [&[f32]; 6],
    den: &[f32],
    pos: [&[f32]; 3],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), 6, "gbf_prepare: output planes");
    let (w, h) = (push.width as usize, push.height as usize);
    let sigma = SMOOTH_SIGMA as f64;
    let r = gaussian_radius(sigma);
    let planes = [rows[0], rows[1], rows[2], rows[3], rows[4], rows[5], den];
    super::wlr::par_pixels::<6>(w, h, out, |x, y| {
        let s = column_sums((w, h), r, sigma, planes, (x, y));
        let d = s[6];
        let sbar: [f64; 6] = std::array::from_fn(|k| if d > 0.0 { s[k] / d } else { 0.0 });
        let c = y * w + x;
        regularised_inverse(sbar, std::array::from_fn(|k| pos[k][c] as f64)).map(|v| v as f32)
    });
}

/// Step 1 through both passes (row sums stored in f32 as on the GPU):
/// `S̃⁻¹` for a `w × h` image from the covariance, position and spp.
pub fn prepare(
    w: usize,
    h: usize,
    cov: [&[f32]; 6],
    pos: [&[f32]; 3],
    spp: &[f32],
) -> Vec<Vec<f32>> {
    let n = w * h;
    let push = SmoothPush {
        width: w as u32,
        height: h as u32,
        radius: gaussian_radius(SMOOTH_SIGMA as f64) as u32,
        sigma: SMOOTH_SIGMA,
        ..Default::default()
    };
    let mut rows = vec![vec![0.0f32; n]; 6];
    let mut den = vec![0.0f32; n];
    gauss_rows(&push, &cov, spp, &mut rows, &mut den);
    let mut out = vec![vec![0.0f32; n]; 6];
    let g = GbfPush {
        width: w as u32,
        height: h as u32,
        ..Default::default()
    };
    gbf_prepare(
        &g,
        std::array::from_fn(|k| rows[k].as_slice()),
        &den,
        pos,
        &mut out,
    );
    out
}
