//! Scalar twin of `spirv/aos_nlm.comp`: AOS's variance-aware NL-means
//! feature prefilter (spec §5.2) of one buffer of 1 or 3 channels, by
//! [`super::aos::nlmeans`] (which is already a per-pixel gather in the
//! kernel's order). [`aos_nlm_boxed`]: the `aos_nlm_vis` build (WLR-VIS),
//! which first takes each valid pixel's 3×3 mean.

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

/// [`aos_nlm`] of the 3×3 means of one channel (`push.channels` = 1; the
/// kernel's `_vis` build reads only `g[0]`): each valid pixel's value first
/// becomes its mean over the valid pixels of its clipped 3×3 window, its
/// variance `Σ max(vg, 0) / n²` (summed in f64 in raster order, rounded to
/// f32 as the kernel stages them); invalid pixels keep theirs, and their
/// output is their input. The `aos_nlm_vis` kernel.
pub fn aos_nlm_boxed(push: &AosPush, g: &[&[f32]], vg: &[&[f32]], spp: &[f32]) -> Vec<Vec<f32>> {
    assert_eq!(push.channels, 1, "aos_nlm_boxed: one channel");
    let (w, h) = (push.width as usize, push.height as usize);
    let (g, vg) = (g[0], vg[0]);
    let valid = |i: usize| spp_of(spp[i]) >= 1.0;
    let (mut bg, mut bv) = (g.to_vec(), vg.to_vec());
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !valid(i) {
                continue;
            }
            let (mut s, mut sv, mut n) = (0.0f64, 0.0f64, 0.0f64);
            for qy in y.saturating_sub(1)..(y + 2).min(h) {
                for j in (qy * w + x.saturating_sub(1))..(qy * w + (x + 2).min(w)) {
                    if valid(j) {
                        s += g[j] as f64;
                        sv += (vg[j] as f64).max(0.0);
                        n += 1.0;
                    }
                }
            }
            bg[i] = (s / n) as f32;
            bv[i] = (sv / (n * n)) as f32;
        }
    }
    // An invalid pixel was left as it was: its output is its own input.
    aos_nlm(push, &[&bg], &[&bv], spp)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 3×3 mean first: a constant buffer stays constant with its
    /// variance divided by the window's valid count (9 inside, 4 in a
    /// corner), and one bright pixel spreads into its 3×3 window before
    /// the NL-means sees it.
    #[test]
    fn boxed_means_first() {
        let (w, h) = (12usize, 10usize);
        let n = w * h;
        let push = AosPush {
            width: w as u32,
            height: h as u32,
            channels: 1,
            stride: n as u32,
            ..Default::default()
        };
        let spp = vec![16.0f32; n];
        let g = vec![0.5f32; n];
        let v = vec![0.09f32; n];
        let out = aos_nlm_boxed(&push, &[&g], &[&v], &spp);
        assert!(out[0].iter().all(|&x| (x - 0.5).abs() < 1e-6));
        let inner = 5 * w + 5;
        // The NL-means of constant means keeps them; its propagated
        // variance is below the boxed one (0.01 inside, 0.0225 at a corner).
        assert!(out[1][inner] < 0.01 && out[1][inner] > 0.0);
        let plain = aos_nlm(&push, &[&g], &[&v], &spp);
        assert!(out[1][inner] < plain[1][inner] / 4.0);
        let mut spike = vec![0.0f32; n];
        spike[inner] = 9.0;
        let v = vec![1e-6f32; n];
        let out = aos_nlm_boxed(&push, &[&spike], &[&v], &spp);
        // The spike's 3×3 window holds its mass spread; far away nothing.
        assert!(out[0][inner] < 2.0, "{}", out[0][inner]);
        assert!(out[0][inner + 1] > 0.5);
        assert!(out[0][0].abs() < 1e-3);
    }
}
