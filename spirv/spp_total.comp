#version 460
// The image's sample total for APR-COUNT-CAP: t[0], t[1] = the low and high
// words of sum_i floor(16 n_i + 1/2) over the valid pixels (n_i capped at 2^21),
// t[2] = their number. Integer atomics with a carry, so the total does not
// depend on the order the workgroups add in. The caller zeroes t first; a
// band adds to what earlier bands left.
// Scalar twin: src/reference/spp_total.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::SppTotalPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint pad0;
} push;

PLANE_IN(0, spp)
layout(std430, set = 0, binding = 1) buffer total_blk { uint t[]; };

shared uint s_sum[64];
shared uint s_count[64];

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    uint lid = gl_LocalInvocationIndex;
    uint v = 0u, c = 0u;
    if (x < push.width && y < push.height) {
        float n = spp_of(spp[y * push.width + x]);
        if (n >= 1.0) {
            v = uint(floor(16.0 * min(n, SPP_TOTAL_MAX) + 0.5));
            c = 1u;
        }
    }
    s_sum[lid] = v;
    s_count[lid] = c;
    barrier();
    for (uint stride = 32u; stride > 0u; stride >>= 1) {
        if (lid < stride) {
            s_sum[lid] += s_sum[lid + stride];
            s_count[lid] += s_count[lid + stride];
        }
        barrier();
    }
    if (lid == 0u && s_count[0] > 0u) {
        uint p = s_sum[0];
        uint old = atomicAdd(t[0], p);
        if (old > 0xffffffffu - p) {
            atomicAdd(t[1], 1u);
        }
        atomicAdd(t[2], s_count[0]);
    }
}
