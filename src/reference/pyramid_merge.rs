//! Scalar twin of `spirv/pyramid_merge.comp`: the fine reconstruction's low
//! band from the coarse one's, as a ratio weighed by the error estimates
//! (PYRAMID-LOWBAND).

use super::finalize_stats::spp_of;
use crate::shared::PyramidPush;

/// One level's planes: colour, error estimate, sample counts.
#[derive(Copy, Clone, Debug)]
pub struct Level<'a> {
    /// The colour R, G, B.
    pub color: [&'a [f32]; 3],
    /// The error estimate per channel.
    pub error: [&'a [f32]; 3],
    /// The sample counts.
    pub spp: &'a [f32],
}

/// Per fine pixel `i` and channel, with the bilinear weights `w_k` of the
/// (up to four) coarse pixels around it that have `n ≥ 1` (pixel centres
/// aligned, clamped at the border, renormalised):
/// `L = up(down(f))`, `Ef = up(down(E_f))` (`down`: the mean over a
/// block's valid fine pixels weighted by their counts, as the coarse level
/// pools its input), `C = up(c)`, `Ec = up(E_c)`,
/// `a = Ef / (Ef + Ec)`;
/// `out = max(f (1 − a + a (max(C, 0) + ε) / (max(L, 0) + ε)), 0)` and
/// `E_out = E_f − a min(E_f, Ef)`. An invalid fine pixel, or one with no
/// valid coarse pixel around it, keeps `f` and `E_f`.
pub fn pyramid_merge(
    push: &PyramidPush,
    fine: &Level,
    coarse: &Level,
    color: [&mut [f32]; 3],
    error: [&mut [f32]; 3],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    let (cw, ch) = (push.other_width as usize, push.other_height as usize);
    let [or, og, ob] = color;
    let [er, eg, eb] = error;
    let eps = push.eps as f64;
    let at = |p: [&[f32]; 3], j: usize| [0, 1, 2].map(|k| p[k][j] as f64);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let f = at(fine.color, i);
            let ef = at(fine.error, i);
            let (mut lf, mut df, mut cu, mut ec) =
                ([0.0f64; 3], [0.0f64; 3], [0.0f64; 3], [0.0f64; 3]);
            let mut wsum = 0.0;
            let gx = ((x as f64 + 0.5) * 0.5 - 0.5).clamp(0.0, (cw - 1) as f64);
            let gy = ((y as f64 + 0.5) * 0.5 - 0.5).clamp(0.0, (ch - 1) as f64);
            let (x0, y0) = (gx as usize, gy as usize);
            let (tx, ty) = (gx - x0 as f64, gy - y0 as f64);
            for k in 0..4 {
                let kx = (x0 + (k & 1)).min(cw - 1);
                let ky = (y0 + (k >> 1)).min(ch - 1);
                let wx = if k & 1 == 1 { tx } else { 1.0 - tx };
                let wy = if k >> 1 == 1 { ty } else { 1.0 - ty };
                let wk = wx * wy;
                let c = ky * cw + kx;
                if wk <= 0.0 || spp_of(coarse.spp[c]) <= 0.0 {
                    continue;
                }
                let (mut bf, mut be, mut nb) = ([0.0f64; 3], [0.0f64; 3], 0.0);
                for q in 0..4 {
                    let (bx, by) = (2 * kx + (q & 1), 2 * ky + (q >> 1));
                    if bx < w && by < h {
                        let j = by * w + bx;
                        let n = spp_of(fine.spp[j]);
                        if n > 0.0 {
                            let (fj, ej) = (at(fine.color, j), at(fine.error, j));
                            for m in 0..3 {
                                bf[m] += n * fj[m];
                                be[m] += n * ej[m];
                            }
                            nb += n;
                        }
                    }
                }
                wsum += wk;
                let (cc, ce) = (at(coarse.color, c), at(coarse.error, c));
                for m in 0..3 {
                    lf[m] += wk * bf[m] / nb;
                    df[m] += wk * be[m] / nb;
                    cu[m] += wk * cc[m];
                    ec[m] += wk * ce[m];
                }
            }
            let (mut o, mut e) = (f, ef);
            if spp_of(fine.spp[i]) > 0.0 && wsum > 0.0 {
                for m in 0..3 {
                    let lf = lf[m] / wsum;
                    let df = (df[m] / wsum).max(0.0);
                    let cu = cu[m] / wsum;
                    let ec = (ec[m] / wsum).max(0.0);
                    let den = df + ec;
                    let a = if den > 0.0 { df / den } else { 0.0 };
                    let ratio = (cu.max(0.0) + eps) / (lf.max(0.0) + eps);
                    o[m] = (f[m] * (1.0 - a + a * ratio)).max(0.0);
                    let efm = ef[m].max(0.0);
                    e[m] = efm - a * efm.min(df);
                }
            }
            or[i] = o[0] as f32;
            og[i] = o[1] as f32;
            ob[i] = o[2] as f32;
            er[i] = e[0] as f32;
            eg[i] = e[1] as f32;
            eb[i] = e[2] as f32;
        }
    }
}
