//! Scalar twin of `spirv/sample_priority.comp`: the per-pixel sampling
//! priority `r_i` of spec §9.1 (REL-CHANNELS), in f64.

use super::spp_of;
use crate::shared::{SamplePriorityPush, SAMPLE_D_KFLAGS, SAMPLE_E_IS_DMSE};

/// For every pixel of the `push.width × push.height` image (`row0` ignored):
/// `r = (1/3) Σ_ch max(E[ch], 0)·rate / (f̂[ch]² + ε)` with
/// `rate = n^(−4/(d+4))`, or 1 with [`SAMPLE_E_IS_DMSE`]; `d = max(d, 0)`, or
/// `floor(clamp(d, 0, 2^20)) mod 16` with [`SAMPLE_D_KFLAGS`]. Invalid pixels
/// (`spp_of(n) < 1`), pixels with any non-finite input (`d` only when used)
/// and non-finite results (as f32) get 0.
pub fn sample_priority(
    push: &SamplePriorityPush,
    e: [&[f32]; 3],
    d: &[f32],
    f: [&[f32]; 3],
    spp: &[f32],
    out: &mut [f32],
) {
    let npix = push.width as usize * push.height as usize;
    for i in 0..npix {
        let n = spp_of(spp[i]);
        let d_used = push.flags & SAMPLE_E_IS_DMSE == 0;
        let finite = (!d_used || d[i].is_finite())
            && (0..3).all(|c| e[c][i].is_finite() && f[c][i].is_finite());
        if n < 1.0 || !finite {
            out[i] = 0.0;
            continue;
        }
        let rate = if push.flags & SAMPLE_E_IS_DMSE != 0 {
            1.0
        } else {
            let dv = d[i] as f64;
            let dim = if push.flags & SAMPLE_D_KFLAGS != 0 {
                (dv.clamp(0.0, 1_048_576.0) as u32 % 16) as f64
            } else {
                dv.max(0.0)
            };
            n.powf(-4.0 / (dim + 4.0))
        };
        let eps = push.eps as f64;
        let sum: f64 = (0..3)
            .map(|c| {
                let fc = f[c][i] as f64;
                (e[c][i] as f64).max(0.0) * rate / (fc * fc + eps)
            })
            .sum();
        let r = (sum / 3.0) as f32;
        out[i] = if r.is_finite() { r } else { 0.0 };
    }
}
