//! Twin of `spirv/lib/sampling.glsl`: the integer helpers of the sampling
//! allocation (spec §9.1 sanitise, §9.2 ROUNDING). They work on the bit
//! patterns of the f32 priority map, so the GPU and the CPU agree bit for bit.

/// Elements per tree block (`SAMPLE_BLOCK`).
pub const BLOCK: usize = 64;
/// f32 bits of 1.0 (`ONE_BITS`).
pub const ONE_BITS: u32 = 0x3F80_0000;

/// §9.1 sanitise on bits: a non-finite, negative, zero or subnormal `r` is 0.
/// (Subnormals are dropped so that no float mode — e.g. flush-to-zero — can
/// change the result.)
pub fn sane_bits(u: u32) -> u32 {
    let e = (u >> 23) & 0xFF;
    if (u >> 31) != 0 || e == 0 || e == 0xFF {
        0
    } else {
        u
    }
}

/// The reference maximum `M'` of the quantisation: the largest sanitised `r`
/// of a valid pixel, or 1.0 if that is 0 (§9.1 "or 1 if that is 0").
pub fn ref_bits(max_bits: u32) -> u32 {
    if max_bits != 0 {
        max_bits
    } else {
        ONE_BITS
    }
}

/// `r'_i` after the §9.1 sanitise, as f32 bits: invalid pixels take `M'`;
/// if every `r` is 0 and no pixel is invalid (`sum r = 0`), every pixel takes 1.
pub fn eff_bits(r_bits: u32, valid: bool, max_bits: u32, any_invalid: bool) -> u32 {
    if !valid {
        return ref_bits(max_bits);
    }
    if max_bits == 0 && !any_invalid {
        return ONE_BITS;
    }
    sane_bits(r_bits)
}

/// `q_i = floor(r'_i · 2^(31 − e))` where `2^(e−1) <= M' < 2^e`: `r'` as a
/// 31-bit fixed-point fraction of `M'`'s binade, so `q(M') ∈ [2^30, 2^31)`.
/// Computed by shifting the 24-bit significand (no float operation).
pub fn quantise(b: u32, reference: u32) -> u64 {
    if b == 0 {
        return 0;
    }
    let sh = (reference >> 23).wrapping_sub(b >> 23);
    if sh >= 32 {
        return 0;
    }
    let m = (b & 0x7F_FFFF) | 0x80_0000;
    ((m << 7) >> sh) as u64
}

/// `u_i = floor(2^32 q_i / S)`, exact (`q < 2^31`, so `2^32 q < 2^63`); 0 if `S = 0`.
pub fn share_of(q: u64, s: u64) -> u64 {
    (q << 32).checked_div(s).unwrap_or(0)
}
