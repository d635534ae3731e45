#version 460
// The horizontal half of LP's coverage test (spec §3.5): reach(x, y) = the
// largest r_opt of the centres c in row y with |x - c_x| <= r_opt(c), or -1.
// Pixel i is covered iff some row y' has reach(x_i, y') >= |y_i - y'|.
// Scalar twin: src/reference/lp_reach.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::LpPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint granularity;
    uint pass;
    uint options;
    uint out_stride;
    uint pad1;
} push;

layout(std430, set = 0, binding = 0) readonly buffer st0_blk { vec4 st0[]; };
PLANE_OUT(1, reach)

#define LP_RADIUS 9

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    int w = int(push.width);
    real best = real(-1);
    for (int qx = max(int(x) - LP_RADIUS, 0); qx <= min(int(x) + LP_RADIUS, w - 1); ++qx) {
        vec4 c = st0[int(y) * w + qx];
        real r = real(c.y);
        if (c.x > 0.0 && real(abs(qx - int(x))) <= r && r > best) {
            best = r;
        }
    }
    reach[y * push.width + x] = float(best);
}
