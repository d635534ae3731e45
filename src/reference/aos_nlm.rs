//! Scalar twin of `spirv/aos_nlm.comp`: AOS's variance-aware NL-means
//! feature prefilter (spec §5.2) of one buffer of 1 or 3 channels, by
//! [`super::aos::nlmeans`] (which is already a per-pixel gather in the
//! kernel's order).

use super::aos::nlmeans;
use super::spp_of;
use crate::shared::{AosPush, AOS_NLM_CLAMP, NLM_CLAMP_Z};

/// Filters the `push.channels` planes `g` with variances `vg` over the
/// whole `push.width × push.height` image (`row0`, `base_row` ignored).
/// Returns the filtered channels, then their propagated variances
/// (`2·channels` planes, the kernel's output planes in order). Invalid
/// pixels (`spp_of < 1`) keep their input. With [`AOS_NLM_CLAMP`] in
/// `push.flags` each filtered channel is clamped to [`NLM_CLAMP_Z`]
/// standard errors `sqrt(max(vg, 0))` around its input (GBF-NLM).
pub fn aos_nlm(push: &AosPush, g: &[&[f32]], vg: &[&[f32]], spp: &[f32]) -> Vec<Vec<f32>> {
    let c = push.channels as usize;
    assert!(c >= 1 && g.len() >= c && vg.len() >= c, "aos_nlm: channels");
    let (w, h) = (push.width as usize, push.height as usize);
    let f64s = |p: &[f32]| p.iter().map(|&x| x as f64).collect::<Vec<f64>>();
    let gd: Vec<Vec<f64>> = g[..c].iter().map(|p| f64s(p)).collect();
    let vd: Vec<Vec<f64>> = vg[..c].iter().map(|p| f64s(p)).collect();
    let valid: Vec<bool> = spp.iter().map(|&s| spp_of(s) >= 1.0).collect();
    let gr: Vec<&[f64]> = gd.iter().map(|p| p.as_slice()).collect();
    let vr: Vec<&[f64]> = vd.iter().map(|p| p.as_slice()).collect();
    let (mut out, var) = nlmeans(w, h, &gr, &vr, &valid);
    if push.flags & AOS_NLM_CLAMP != 0 {
        let z = NLM_CLAMP_Z as f64;
        for (o, (g, v)) in out.iter_mut().zip(gd.iter().zip(&vd)) {
            for (x, (&g, &v)) in o.iter_mut().zip(g.iter().zip(v)) {
                let se = z * v.max(0.0).sqrt();
                *x = x.clamp(g - se, g + se);
            }
        }
    }
    out.into_iter()
        .chain(var)
        .map(|p| p.into_iter().map(|x| x as f32).collect())
        .collect()
}
