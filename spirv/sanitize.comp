#version 460
// Input sanitation of one scalar channel plane, spec §0.4 steps 1-2
// (stage 0). The host then runs `sanitize_low_spp` (step 3) when the channel
// has a variance layer, or `estimate_variance` (step 4) when it has none.
// The stages are separate kernels: on lavapipe the 49-entry arrays of the
// later stages slow every invocation of a kernel that merely contains them.
// Scalar twin: src/reference/sanitize.rs.
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

PLANE_IN(0, value_in)
PLANE_IN(1, var_in)
PLANE_IN(2, spp)
PLANE_OUT(3, value_out)
PLANE_OUT(4, var_out)
// 0: values repaired, 1: input variances negative/non-finite, 2: pixels
// handled by step 3, 3: variances from the step-4 estimator.
layout(std430, set = 0, binding = 5) buffer Counters { uint counters[]; };

float san_value_in(uint i) { return value_in[i]; }
float san_var_in(uint i) { return var_in[i]; }
float san_spp(uint i) { return spp[i]; }
void san_store(uint i, float value, float var)
{
    value_out[i] = value;
    var_out[i] = var;
}

#include "lib/sanitize_repair.glsl"

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    ivec2 p = ivec2(x, y);
    ivec2 size = ivec2(push.width, push.height);
    stage_repair(p, size, pix(p));
}
