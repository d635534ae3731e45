#version 460
// The centres of one band of one sparse-centre pass of LP (spec §3.5):
// thread (gx, gy) <-> candidate pixel (phi + g gx, phi + g (row0 + gy)) of
// the grid of granularity g. A valid candidate that no centre of an earlier
// pass covers (read from the `reach` plane of the state before this pass:
// PASS-SNAPSHOT) is appended to the queue lp_centres reads, dispatched
// indirectly with one invocation per entry: the centres of a pass are a few
// % of its candidates, scattered, and a SIMD vector costs as much as its
// busiest lane, so the fits run on a dense list instead of on the grid.
//
// Queue: [workgroups x, 1, 1, count, entries (pixel index)...]; the caller
// zeroes the count and x and sets y = z = 1 before the band. The order of
// the entries is whatever the atomics give: each centre writes only its own
// pixel, so the result does not depend on it.
// Scalar twin: src/reference/lp_select.rs.
#include "lib/common.glsl"

// One grid row per workgroup row, so a dispatch covers any range of grid
// rows (the wavefront of methods::lp).
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

PLANE_IN(0, spp)
PLANE_IN(1, reach)
layout(std430, set = 0, binding = 2) buffer queue_blk { uint queue[]; };

// Half-width of LP's window (LP_RADIUS in lib/lp.glsl).
#define LP_RADIUS 9
// Covered by a centre of an earlier pass (|p - c|_inf <= r_opt(c), §3.5):
// some row y' within 9 has reach(p.x, y') >= |p.y - y'| (lp_reach.comp).
// The reach plane is a ring of push.ring_rows rows (LpPush::ring_rows).
bool covered(ivec2 p, ivec2 size)
{
    // The ring row advances with qy, wrapping at ring: an integer division
    // per row (llvmpipe divides one lane at a time) was most of this
    // kernel's time.
    int ring = int(push.ring_rows == 0u ? push.height : push.ring_rows);
    int qy0 = max(p.y - LP_RADIUS, 0);
    int ry = qy0 % ring;
    for (int qy = qy0; qy <= min(p.y + LP_RADIUS, size.y - 1); ++qy, ry = ry + 1 == ring ? 0 : ry + 1) {
        if (reach[ry * size.x + p.x] >= float(abs(qy - p.y))) {
            return true;
        }
    }
    return false;
}

void main()
{
    uint g = max(push.granularity, 1u);
    // The candidate grid's phase (LpPush::phase): image coordinates mod g.
    uint x = (push.phase & 0xffffu) + gl_GlobalInvocationID.x * g;
    uint y = (push.phase >> 16) + (push.row0 + gl_GlobalInvocationID.y) * g;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    if (spp_of(spp[i]) < 1.0 || covered(ivec2(x, y), ivec2(push.width, push.height))) {
        return;
    }
    QUEUE_APPEND(queue, i, LP_CENTRES_GROUP, QUEUE_ROOM(queue))
}
