#version 460
// Spec §10.1 for the sample map (TEMPORAL-MAP, ours): what the LP temporal
// filter will make of this frame at each pixel, from the previous frame's
// state (lib/temporal.glsl, read only), as a factor on the error estimate
// the adaptive pass's sample map reads: g = P00 after the update, the
// weight of this frame's observation in the filtered intercept, clamped
// to <= 1; g = 1 where the pixel is reset or passed through.
// (sr, sg, sb: the error the map reads) -> (gr, gg, gb) = g * it.
// Scalar twin: src/reference/lp_temporal_gain.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::TemporalPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint flags;
    float lambda;
    float p00;
    float p11;
    float error_scale;
    float inflate_scale;
} push;

PLANE_IN(0, yr)
PLANE_IN(1, yg)
PLANE_IN(2, yb)
PLANE_IN(3, px)
PLANE_IN(4, py)
PLANE_IN(5, pz)
PLANE_IN(6, vx)
PLANE_IN(7, vy)
PLANE_IN(8, vz)
PLANE_IN(9, depth)
PLANE_IN(10, spp)
PLANE_IN(11, er)
PLANE_IN(12, eg)
PLANE_IN(13, eb)
PLANE_IN(14, prev)
PLANE_IN(15, mx)
PLANE_IN(16, my)
PLANE_IN(17, sr)
PLANE_IN(18, sg)
PLANE_IN(19, sb)
PLANE_OUT(20, gr)
PLANE_OUT(21, gg)
PLANE_OUT(22, gb)

#include "lib/temporal.glsl"

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    real2 b[3];
    real3 p;
    int off;
    int step = temporal_step(x, y, b, p, off);
    real g = step == STEP_CONTINUE ? min(p.x, real(1)) : real(1);
    gr[i] = float(g * real(sr[i]));
    gg[i] = float(g * real(sg[i]));
    gb[i] = float(g * real(sb[i]));
}
