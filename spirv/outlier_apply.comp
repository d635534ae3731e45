#version 460
// Outlier replacement, applied (spec §4.4 step 3): for each pixel o that
// outlier_detect queued, the colour and variance outlier_median wrote to
// o's pixel of the replacement planes go into the statistics, in place.
// Dispatched indirectly over the queue, one invocation per entry (striding
// past 65535 workgroups); no other pixel is read or written, so the stage
// never copies the statistics. (outlier_median cannot write in place: the
// median pixel of one entry may be another entry.)
// Scalar twin: src/reference/outlier_apply.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 64) in;

PLANE_IN(0, rep_r)
PLANE_IN(1, rep_g)
PLANE_IN(2, rep_b)
PLANE_IN(3, rep_vr)
PLANE_IN(4, rep_vg)
PLANE_IN(5, rep_vb)
PLANE_OUT(6, cr)
PLANE_OUT(7, cg)
PLANE_OUT(8, cb)
PLANE_OUT(9, vr)
PLANE_OUT(10, vg)
PLANE_OUT(11, vb)
layout(std430, set = 0, binding = 12) readonly buffer queue_blk { uint queue[]; };

void main()
{
    uint entries = min(queue[3], queue_capacity());
    for (uint at = gl_GlobalInvocationID.x; at < entries; at += gl_NumWorkGroups.x * 64u) {
        uint o = queue[4u + at];
        cr[o] = rep_r[o];
        cg[o] = rep_g[o];
        cb[o] = rep_b[o];
        vr[o] = rep_vr[o];
        vg[o] = rep_vg[o];
        vb[o] = rep_vb[o];
    }
}
