#version 460
// The horizontal half of LP's coverage test (spec §3.5): reach(x, y) = the
// largest r_opt of the centres c in row y made in a pass before push.pass
// (PASS-SNAPSHOT) with |x - c_x| <= r_opt(c), or -1. Pixel i is covered iff
// some row y' has reach(x_i, y') >= |y_i - y'|. One row per workgroup row,
// so a dispatch covers any range of rows (the wavefront of methods::lp);
// the plane is a ring of push.ring_rows rows (LpPush::ring_rows).
// Scalar twin: src/reference/lp_reach.rs.
#include "lib/common.glsl"

layout(local_size_x = 64, local_size_y = 1) in;

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
    uint ring_rows;
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
    // A centre's map value is pass + 1: made before push.pass iff <= push.pass.
    float before = float(push.pass);
    for (int qx = max(int(x) - LP_RADIUS, 0); qx <= min(int(x) + LP_RADIUS, w - 1); ++qx) {
        vec4 c = st0[int(y) * w + qx];
        real r = real(c.y);
        if (c.x > 0.0 && c.x <= before && real(abs(qx - int(x))) <= r && r > best) {
            best = r;
        }
    }
    uint ring = push.ring_rows == 0u ? push.height : push.ring_rows;
    reach[(y % ring) * push.width + x] = float(best);
}
