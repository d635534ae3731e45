#version 460
// Spec §0.4 step 4 (stage 2) on the output of `sanitize`: the variance
// layer is missing, estimate it from the image (MAD of local residuals).
// Scalar twin: src/reference/estimate_variance.rs.
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
    uint _pad;
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

// Spec §0.4 step 4: the variance layer is missing; MAD estimate for valid
// pixels, 0 for invalid ones.
void stage_estimate(ivec2 p, ivec2 size, uint i)
{
    value_out[i] = value_in[i];
    float v = 0.0;
    if (san_valid(p)) {
        v = float(san_mad_variance(p, size));
        atomicAdd(counters[3], san_counts(p) ? 1u : 0u);
    }
    var_out[i] = v;
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
    stage_estimate(p, size, pix(p));
}
