// Shared integer helpers of the sampling allocation (spec §9.1 sanitise,
// §9.2 ROUNDING). Everything here is exact integer arithmetic on the bit
// patterns of the f32 priority map, so a GPU and its scalar twin
// (src/reference/sampling.rs) agree bit for bit whatever the device's float
// modes (denormal flushing, division precision). 64-bit integers are
// uvec2 words (lib/u64.glsl), so no kernel needs shaderInt64. Needs
// common.glsl first.

#include "lib/u64.glsl"

// Workgroup = one block of the reduction / scan tree: 8x8 = 64 elements.
#define SAMPLE_BLOCK 64u
// f32 bit pattern of 1.0.
#define ONE_BITS 0x3F800000u
// "no parent level" marker of sample_scan.
#define NO_LEVEL 0xFFFFFFFFu

// §9.1 sanitise on bits: non-finite, negative, zero or denormal r -> 0.
uint sane_bits(uint u)
{
    uint e = (u >> 23) & 0xFFu;
    return ((u >> 31) != 0u || e == 0u || e == 0xFFu) ? 0u : u;
}

// The reference maximum M' of the quantisation: the largest sanitised r of
// a valid pixel, or 1.0 when that is 0 (§9.1 "or 1 if that is 0").
uint ref_bits(uint max_bits)
{
    return max_bits != 0u ? max_bits : ONE_BITS;
}

// r'_i after §9.1 sanitise, as f32 bits: invalid pixels take M'; if every
// r is 0 and no pixel is invalid (sum r = 0), every pixel takes 1.
uint eff_bits(uint r_bits, bool valid, uint max_bits, bool any_invalid)
{
    if (!valid) {
        return ref_bits(max_bits);
    }
    if (max_bits == 0u && !any_invalid) {
        return ONE_BITS;
    }
    return sane_bits(r_bits);
}

// q_i = floor(r'_i * 2^(31 - e(M'))) with e(M') the binary exponent of M'
// rounded up: r' as a 31-bit fixed-point fraction of M' (q(M') in [2^30, 2^31)).
u64 quantise(uint b, uint ref)
{
    if (b == 0u) {
        return u64(0u);
    }
    uint sh = (ref >> 23) - (b >> 23);
    if (sh >= 32u) {
        return u64(0u);
    }
    uint m = (b & 0x7FFFFFu) | 0x800000u;
    return u64_from((m << 7) >> sh);
}

// u_i = floor(2^32 q_i / S), exact u64 division (q < 2^31, so 2^32 q < 2^63).
u64 share_of(u64 q, u64 s)
{
    return u64_is_zero(s) ? u64(0u) : u64_div(u64(0u, q.x), s);
}

// Linear workgroup index of an 8x8 grid laid out `groups_x` workgroups wide
// (row0 is the first pixel row of the band; bands are multiples of 8 rows).
uint block_index(uint row0, uint groups_x)
{
    return (row0 / 8u + gl_WorkGroupID.y) * groups_x + gl_WorkGroupID.x;
}
