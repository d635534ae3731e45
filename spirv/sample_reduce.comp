#version 460
// One level of the fixed-order reduction tree of the sampling allocation
// (spec §9.1 sanitise, §9.2 ROUNDING steps 1 and the up-sweep of step 2).
// Each 8x8 workgroup reduces one block of 64 consecutive elements of its
// level and writes one u64 (a uvec2, lib/u64.glsl) to tree[dst_off + block]. Modes (push.mode):
//   0 leaf max   element = pixel i: sanitised r bits if valid, else bit 32
//                (the "some pixel is invalid" flag); combine = max / or
//   1 inner max  element = tree[src_off + i]
//   2 leaf q     element = q_i (needs the max at tree[max_off])
//   3 leaf u     element = u_i = floor(2^32 q_i / S) (S at tree[s_off])
//   4 inner sum  element = tree[src_off + i]; combine = u64 add
// Integer only: the result is independent of the device's float modes.
// Scalar twin: src/reference/sample_reduce.rs.
#include "lib/common.glsl"
#include "lib/sampling.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::SampleTreePush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint mode;
    uint n;
    uint groups_x;
    uint src_off;
    uint dst_off;
    uint par_off;
    uint max_off;
    uint s_off;
    uint u_off;
    uint budget;
    uint spread;    // samples spread evenly over the pixels besides `budget` (sample_scan leaf)
    uint pad1;
    uint pad2;
} push;

layout(std430, set = 0, binding = 0) readonly buffer r_blk { uint r_bits[]; };
PLANE_IN(1, spp)
layout(std430, set = 0, binding = 2) buffer tree_blk { u64 tree[]; };

shared u64 acc[SAMPLE_BLOCK];

// Max of the low words, or of the high words (the "invalid" flag); or sum.
u64 combine(u64 a, u64 b)
{
    if (push.mode <= 1u) {
        return u64(max(a.x, b.x), a.y | b.y);
    }
    return u64_add(a, b);
}

void main()
{
    uint lid = gl_LocalInvocationIndex;
    uint block = block_index(push.row0, push.groups_x);
    uint i = block * SAMPLE_BLOCK + lid;
    u64 v = u64(0u);
    if (i < push.n) {
        if (push.mode == 1u || push.mode == 4u) {
            v = tree[push.src_off + i];
        } else {
            bool valid = spp_of(spp[i]) >= 1.0;
            if (push.mode == 0u) {
                v = valid ? u64_from(sane_bits(r_bits[i])) : u64(0u, 1u);
            } else {
                u64 m = tree[push.max_off];
                uint mb = m.x;
                uint ref = ref_bits(mb);
                u64 q = quantise(eff_bits(r_bits[i], valid, mb, m.y != 0u), ref);
                v = push.mode == 2u ? q : share_of(q, tree[push.s_off]);
            }
        }
    }
    acc[lid] = v;
    barrier();
    for (uint stride = SAMPLE_BLOCK / 2u; stride > 0u; stride >>= 1) {
        if (lid < stride) {
            acc[lid] = combine(acc[lid], acc[lid + stride]);
        }
        barrier();
    }
    if (lid == 0u && block * SAMPLE_BLOCK < push.n) {
        tree[push.dst_off + block] = acc[0];
    }
}
