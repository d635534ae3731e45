//! Scalar twin of `spirv/gbf_filter.comp`: G-buffer prefilter steps 9–10
//! (spec §6) — up to four feature planes filtered with the 7×7 weights at
//! `hbar`, with propagated variances.

use super::gbf::{filter_features, Planes};
use crate::shared::GbfPush;

/// Output planes: the `push.count` filtered features, then 0-planes up to
/// 4, then their variances likewise (8 planes). An invalid pixel or one
/// with `hbar < 1e-3` (H0) keeps its input.
pub fn gbf_filter(
    push: &GbfPush,
    pos: [&[f32]; 3],
    inv: [&[f32]; 6],
    spp: &[f32],
    hbar: &[f32],
    feat: [&[f32]; 4],
    var: [&[f32]; 4],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), 8, "gbf_filter: output planes");
    let (w, h) = (push.width as usize, push.height as usize);
    let k = (push.count as usize).clamp(1, 4);
    let p = Planes {
        width: w,
        height: h,
        pos,
        pos_var: None,
        inv,
        spp,
    };
    super::wlr::par_pixels::<8>(w, h, out, |x, y| {
        let q = y * w + x;
        let mut o = [0.0f32; 8];
        if !p.valid(q) {
            for j in 0..k {
                o[j] = feat[j][q];
                o[4 + j] = var[j][q];
            }
            return o;
        }
        let r = filter_features(&p, x, y, hbar[q] as f64, &feat[..k], &var[..k]);
        for j in 0..k {
            o[j] = r[j].0 as f32;
            o[4 + j] = r[j].1 as f32;
        }
        o
    });
}
