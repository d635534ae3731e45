#version 460
// Spec §0.4 step 3 (stage 1) on the output of `sanitize`: variances of
// pixels with 1 <= spp < 2. Scalar twin: src/reference/sanitize_low_spp.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::SanitizePush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint stage;    // 0: steps 1-2, 1: step 3, 2: step 4
    uint has_var;  // stage 0 reads var_in only when 1
    uint skip_lo;  // margins not counted: left | top << 16
    uint skip_hi;  // right | bottom << 16
    uint in_place; // sanitize_quads only
} push;

// Whether a repair at p is counted: outside the margins SanitizePush::skip_lo
// and skip_hi leave out (a tile's halo; 0 counts every pixel).
bool san_counts(ivec2 p)
{
    uvec2 lo = uvec2(push.skip_lo & 0xffffu, push.skip_lo >> 16);
    uvec2 hi = uvec2(push.skip_hi & 0xffffu, push.skip_hi >> 16);
    return all(greaterThanEqual(uvec2(p), lo)) && uint(p.x) + hi.x < push.width
        && uint(p.y) + hi.y < push.height;
}

PLANE_IN(0, value_in)
PLANE_IN(1, var_in)
PLANE_IN(2, spp)
PLANE_OUT(3, value_out)
PLANE_OUT(4, var_out)
// 0: values repaired, 1: input variances negative/non-finite, 2: pixels
// handled by step 3, 3: variances from the step-4 estimator.
layout(std430, set = 0, binding = 5) buffer Counters { uint counters[]; };

uint pix(ivec2 q)
{
    return uint(q.y) * push.width + uint(q.x);
}

bool san_valid(ivec2 q)
{
    return spp_of(spp[pix(q)]) >= 1.0;
}

real san_value(ivec2 q)
{
    return real(value_in[pix(q)]);
}

#include "lib/sanitize.glsl"

// Spec §0.4 step 3: a valid pixel with spp < 2 gets the median over the 5x5
// pixels with spp >= 2 of v_q n_q, divided by max(n_p, 1); without such a
// pixel, the step-4 estimate.
void stage_low_spp(ivec2 p, ivec2 size, uint i)
{
    value_out[i] = value_in[i];
    float np = spp_of(spp[i]);
    if (np >= 1.0 && np < 2.0) {
        real vals[SAN_MAX];
        int m = 0;
        for (int qy = max(p.y - 2, 0); qy <= min(p.y + 2, size.y - 1); ++qy) {
            for (int qx = max(p.x - 2, 0); qx <= min(p.x + 2, size.x - 1); ++qx) {
                uint iq = pix(ivec2(qx, qy));
                float nq = spp_of(spp[iq]);
                if (nq >= 2.0) {
                    vals[m] = real(var_in[iq]) * real(nq);
                    ++m;
                }
            }
        }
        real v;
        if (m == 0) {
            v = san_mad_variance(p, size);
            atomicAdd(counters[3], san_counts(p) ? 1u : 0u);
        } else {
            v = san_median(vals, m) / max(real(np), real(1));
        }
        var_out[i] = float(v);
        atomicAdd(counters[2], san_counts(p) ? 1u : 0u);
    } else {
        var_out[i] = var_in[i];
    }
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    ivec2 p = ivec2(x, y);
    ivec2 size = ivec2(push.width, push.height);
    stage_low_spp(p, size, pix(p));
}
