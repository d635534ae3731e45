//! Scalar twin of `spirv/gbf_filter.comp`: G-buffer prefilter steps 9–10
//! (spec §6) — the seven packed features filtered with the 7×7 weights at
//! `hbar`, with propagated variances.

use super::gbf::{filter_features, Planes};
use super::gbf_pack::unpack;
use super::spp_of;
use crate::shared::GbfPush;

/// Output planes: the 7 filtered features, then their 7 variances, from the
/// packed planes of [`super::gbf_pack`]. An invalid pixel or one with
/// `hbar < 1e-3` (H0) keeps its input. With `push.second_below > 0`
/// (GBF-SECOND's second pass) only the pixels with fewer samples than that
/// are filtered, and every pixel keeps its input variances.
pub fn gbf_filter(
    push: &GbfPush,
    pos: [&[f32]; 3],
    inv: [&[f32]; 6],
    spp: &[f32],
    hbar: &[f32],
    packed: [&[f32]; 4],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), 14, "gbf_filter: output planes");
    let (w, h) = (push.width as usize, push.height as usize);
    let feat: Vec<Vec<f32>> = (0..7).map(|k| unpack(packed[0], packed[1], k)).collect();
    let var: Vec<Vec<f32>> = (0..7).map(|k| unpack(packed[2], packed[3], k)).collect();
    let feat_r: Vec<&[f32]> = feat.iter().map(|v| v.as_slice()).collect();
    let var_r: Vec<&[f32]> = var.iter().map(|v| v.as_slice()).collect();
    let p = Planes {
        width: w,
        height: h,
        pos,
        pos_var: None,
        inv,
        spp,
    };
    super::wlr::par_pixels::<14>(w, h, out, |x, y| {
        let q = y * w + x;
        let mut o = [0.0f32; 14];
        let second = push.second_below > 0.0;
        if !p.valid(q) || (second && spp_of(spp[q]) >= push.second_below as f64) {
            for j in 0..7 {
                o[j] = feat[j][q];
                o[7 + j] = var[j][q];
            }
            return o;
        }
        let r = filter_features(&p, x, y, hbar[q] as f64, &feat_r, &var_r);
        for j in 0..7 {
            o[j] = r[j].0 as f32;
            o[7 + j] = if second { var[j][q] } else { r[j].1 as f32 };
        }
        o
    });
}
