#version 460
// Down-sweep of the sampling allocation's prefix sum and the final counts
// (spec §9.2 ROUNDING steps 2-3). Each 8x8 workgroup scans one block of 64
// consecutive elements of its level in a fixed order (Hillis-Steele in
// shared memory, exact u64 as uvec2, lib/u64.glsl) and adds the block's offset, read from the level
// above (tree[par_off + block], exclusive prefix; 0 at the top level).
//   mode 0 (inner level): element = block sum tree[src_off + i] of the level
//          below; writes its exclusive prefix tree[dst_off + i].
//   mode 1 (leaf): element = u_i of pixel i, P_i = inclusive prefix;
//          counts[i] = floor(T P_i / U) - floor(T P_{i-1} / U) in u64
//          (T = push.budget < 2^32, P_i <= U <= 2^32: no overflow). U = 0
//          takes u_i = 1 for every pixel, i.e. P_i = i + 1.
// Integer only. Scalar twin: src/reference/sample_scan.rs.
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
layout(std430, set = 0, binding = 3) buffer counts_blk { uint counts[]; };

shared u64 acc[SAMPLE_BLOCK];

void main()
{
    uint lid = gl_LocalInvocationIndex;
    uint block = block_index(push.row0, push.groups_x);
    uint i = block * SAMPLE_BLOCK + lid;
    u64 v = u64(0u);
    if (i < push.n) {
        if (push.mode == 0u) {
            v = tree[push.src_off + i];
        } else {
            u64 m = tree[push.max_off];
            uint mb = m.x;
            bool valid = spp_of(spp[i]) >= 1.0;
            u64 q = quantise(eff_bits(r_bits[i], valid, mb, m.y != 0u), ref_bits(mb));
            v = share_of(q, tree[push.s_off]);
        }
    }
    acc[lid] = v;
    barrier();
    for (uint off = 1u; off < SAMPLE_BLOCK; off <<= 1) {
        u64 t = lid >= off ? acc[lid - off] : u64(0u);
        barrier();
        acc[lid] = u64_add(acc[lid], t);
        barrier();
    }
    if (i >= push.n) {
        return;
    }
    u64 base = push.par_off == NO_LEVEL ? u64(0u) : tree[push.par_off + block];
    u64 incl = u64_add(base, acc[lid]);
    if (push.mode == 0u) {
        tree[push.dst_off + i] = u64_sub(incl, v);
        return;
    }
    uint t = push.budget;
    u64 u_total = tree[push.u_off];
    u64 p1;
    u64 p0;
    if (u64_is_zero(u_total)) {
        u_total = u64_from(push.n);
        p1 = u64_from(i + 1u);
        p0 = u64_from(i);
    } else {
        p1 = incl;
        p0 = u64_sub(incl, v);
    }
    // SAMPLE-FLOOR: `spread` samples by the same cumulative rounding over
    // the pixels in raster order, then the map's share of `budget`
    // (T < 2^32 and P <= 2^32: the products stay below 2^64).
    uint f = push.spread;
    u64 np = u64_from(push.n);
    uint even = u64_sub(u64_div(u64_mul32(f, i + 1u), np), u64_div(u64_mul32(f, i), np)).x;
    uint share = u64_sub(u64_div(u64_mul_u32(p1, t), u_total), u64_div(u64_mul_u32(p0, t), u_total)).x;
    counts[i] = even + share;
}
