#version 460
// The horizontal half of LP's coverage test (spec §3.5): reach(x, y) = the
// largest r_opt of the centres c in row y made in a pass before push.pass
// (PASS-SNAPSHOT) with |x - c_x| <= r_opt(c), or -1. Pixel i is covered iff
// some row y' has reach(x_i, y') >= |y_i - y'|. Only the columns of the
// candidate grid of push.granularity (x = phase_x mod g) are written: the
// only ones lp_select reads (1/19 of the row before the second pass; all
// of it for the last, g = 1). One row per workgroup row, so a dispatch
// covers any range of rows (the wavefront of methods::lp); the plane is a
// ring of push.ring_rows rows (LpPush::ring_rows).
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
    uint phase;
    uint ring_rows;
} push;

layout(std430, set = 0, binding = 0) readonly buffer st0_blk { vec4 st0[]; };
PLANE_OUT(1, reach)

#define LP_RADIUS 9

// Register blocking: an invocation computes LR_PX consecutive candidate
// columns of a row (g apart). Each centre-map entry of their joint window
// ((LR_PX - 1) g + 19 wide) is loaded once and compared for every column
// (lavapipe pays per lane and float loaded: for g = 1, (LR_PX + 18) / LR_PX
// loads per pixel instead of 19). A maximum does not depend on the order,
// so the result is the same.
#extension GL_EXT_control_flow_attributes : require
#define LR_PX 8

void main()
{
    int g = int(max(push.granularity, 1u));
    uint x0 = (push.phase & 0xffffu) + gl_GlobalInvocationID.x * uint(LR_PX * g);
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x0 >= push.width || y >= push.height) {
        return;
    }
    int w = int(push.width);
    real best[LR_PX];
    [[unroll]] for (int p = 0; p < LR_PX; ++p) {
        best[p] = real(-1);
    }
    // A centre's map value is pass + 1: made before push.pass iff <= push.pass.
    float before = float(push.pass);
    int u1 = min(int(x0) + (LR_PX - 1) * g + LP_RADIUS, w - 1);
    for (int qx = max(int(x0) - LP_RADIUS, 0); qx <= u1; ++qx) {
        vec2 c = st0[int(y) * w + qx].xy;
        real r = real(c.y);
        bool made = c.x > 0.0 && c.x <= before;
        [[unroll]] for (int p = 0; p < LR_PX; ++p) {
            if (made && real(abs(qx - int(x0) - p * g)) <= r && r > best[p]) {
                best[p] = r;
            }
        }
    }
    uint ring = push.ring_rows == 0u ? push.height : push.ring_rows;
    [[unroll]] for (int p = 0; p < LR_PX; ++p) {
        uint x = x0 + uint(p * g);
        if (x < push.width) {
            reach[(y % ring) * push.width + x] = float(best[p]);
        }
    }
}
