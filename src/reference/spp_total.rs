//! Scalar twin of `spirv/spp_total.comp` and of `spp_total_mean`
//! (`spirv/lib/common.glsl`): the image's sample total for APR-COUNT-CAP.

use super::spp_of;

/// A pixel counts at most this many samples (`SPP_TOTAL_MAX`).
pub const MAX: f64 = 2_097_152.0;

/// `[low word, high word, count]` of `Σ ⌊16 n_i + ½⌋` over the valid pixels
/// of `spp` (`n_i ≥ 1`), `n_i` capped at [`MAX`].
pub fn spp_total(spp: &[f32]) -> [u32; 3] {
    let (mut sum, mut count) = (0u64, 0u32);
    for &s in spp {
        let n = spp_of(s);
        if n >= 1.0 {
            sum += (16.0 * n.min(MAX) as f32 + 0.5).floor() as u64;
            count += 1;
        }
    }
    [sum as u32, (sum >> 32) as u32, count]
}

/// The mean sample count of the valid pixels from [`spp_total`]'s words,
/// in the f32 operations of the GPU (0 without valid pixels).
pub fn spp_total_mean(t: [u32; 3]) -> f32 {
    if t[2] == 0 {
        return 0.0;
    }
    let sum = t[1] as f32 * 4_294_967_296.0 + t[0] as f32;
    sum / (16.0 * t[2] as f32)
}
