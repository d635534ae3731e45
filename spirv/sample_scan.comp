#version 460
// Down-sweep of the sampling allocation's prefix sum and the final counts
// (spec §9.2 ROUNDING steps 2-3). Each 8x8 workgroup scans one block of 64
// consecutive elements of its level in a fixed order (Hillis-Steele in
// shared memory, exact u64) and adds the block's offset, read from the level
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
layout(std430, set = 0, binding = 2) buffer tree_blk { uint64_t tree[]; };
layout(std430, set = 0, binding = 3) buffer counts_blk { uint counts[]; };

shared uint64_t acc[SAMPLE_BLOCK];

const uint64_t LO = uint64_t(0xFFFFFFFFu);

void main()
{
    uint lid = gl_LocalInvocationIndex;
    uint block = block_index(push.row0, push.groups_x);
    uint i = block * SAMPLE_BLOCK + lid;
    uint64_t v = uint64_t(0);
    if (i < push.n) {
        if (push.mode == 0u) {
            v = tree[push.src_off + i];
        } else {
            uint64_t m = tree[push.max_off];
            uint mb = uint(m & LO);
            bool valid = spp_of(spp[i]) >= 1.0;
            uint64_t q = quantise(eff_bits(r_bits[i], valid, mb, (m >> 32) != uint64_t(0)),
                                  ref_bits(mb));
            v = share_of(q, tree[push.s_off]);
        }
    }
    acc[lid] = v;
    barrier();
    for (uint off = 1u; off < SAMPLE_BLOCK; off <<= 1) {
        uint64_t t = lid >= off ? acc[lid - off] : uint64_t(0);
        barrier();
        acc[lid] += t;
        barrier();
    }
    if (i >= push.n) {
        return;
    }
    uint64_t base = push.par_off == NO_LEVEL ? uint64_t(0) : tree[push.par_off + block];
    uint64_t incl = base + acc[lid];
    if (push.mode == 0u) {
        tree[push.dst_off + i] = incl - v;
        return;
    }
    uint64_t t = uint64_t(push.budget);
    uint64_t u_total = tree[push.u_off];
    uint64_t p1, p0;
    if (u_total == uint64_t(0)) {
        u_total = uint64_t(push.n);
        p1 = uint64_t(i) + uint64_t(1);
        p0 = uint64_t(i);
    } else {
        p1 = incl;
        p0 = incl - v;
    }
    // SAMPLE-FLOOR: `spread` samples by the same cumulative rounding over
    // the pixels in raster order, then the map's share of `budget`.
    uint64_t f = uint64_t(push.spread);
    uint64_t np = uint64_t(push.n);
    uint even = uint(f * uint64_t(i + 1u) / np - f * uint64_t(i) / np);
    counts[i] = even + uint(t * p1 / u_total - t * p0 / u_total);
}
