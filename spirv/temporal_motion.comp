#version 460
// TEMPORAL-MOTION (ours, before §10.1's search): one level of the
// coarse-to-fine search for where each pixel's surface was in the previous
// frame. Both frames' world positions are pooled into pyramids
// (pyramid_pool: means weighted by the sample counts, and by the previous
// state's valid flags); at a level (from the coarsest to the full
// resolution, level 0, which reads the frames' own planes), a pixel's
// search is centred on twice its coarser block's offset (0 at the
// coarsest level) and takes, among the previous frame's pixels that hold
// a position, the pixel itself, the centre and those within `radius` of
// the centre, in that order, the one nearest its own position (squared
// distance; a later one only if strictly nearer). A pixel without
// samples, or without a candidate, keeps the centre. The LP temporal
// filter's 7x7 window is centred on level 0's offsets.
// Scalar twin: src/reference/temporal_motion.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::MotionPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint coarse;
    uint coarse_width;
    uint coarse_height;
    int radius;
    uint pad0;
} push;

PLANE_IN(0, cx)
PLANE_IN(1, cy)
PLANE_IN(2, cz)
PLANE_IN(3, cn)
PLANE_IN(4, qx)
PLANE_IN(5, qy)
PLANE_IN(6, qz)
PLANE_IN(7, qn)
PLANE_IN(8, ox_c)
PLANE_IN(9, oy_c)
PLANE_OUT(10, ox)
PLANE_OUT(11, oy)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    ivec2 centre = ivec2(0);
    if (push.coarse != 0u) {
        uint k = min(y / 2u, push.coarse_height - 1u) * push.coarse_width
            + min(x / 2u, push.coarse_width - 1u);
        centre = 2 * ivec2(int(ox_c[k]), int(oy_c[k]));
    }
    ivec2 best = centre;
    if (spp_of(cn[i]) >= 1.0) {
        real3 p = real3(cx[i], cy[i], cz[i]);
        bool found = false;
        real best_cost = real(0);
        int r = push.radius;
        // The pixel itself, the centre, then the window in raster order.
        for (int k = -2; k < (2 * r + 1) * (2 * r + 1); ++k) {
            ivec2 o;
            if (k == -2) {
                o = ivec2(0);
            } else if (k == -1) {
                if (centre == ivec2(0)) {
                    continue;
                }
                o = centre;
            } else {
                ivec2 d = ivec2(k % (2 * r + 1) - r, k / (2 * r + 1) - r);
                o = centre + d;
                if (d == ivec2(0) || o == ivec2(0)) {
                    continue;
                }
            }
            ivec2 j2 = ivec2(x, y) + o;
            if (j2.x < 0 || j2.y < 0 || j2.x >= int(push.width) || j2.y >= int(push.height)) {
                continue;
            }
            uint j = uint(j2.y) * push.width + uint(j2.x);
            if (spp_of(qn[j]) < 1.0) {
                continue;
            }
            real3 dq = real3(qx[j], qy[j], qz[j]) - p;
            real cost = dot(dq, dq);
            if (!found || cost < best_cost) {
                found = true;
                best_cost = cost;
                best = o;
            }
        }
    }
    ox[i] = float(best.x);
    oy[i] = float(best.y);
}
