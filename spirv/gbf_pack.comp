#version 460
// G-buffer prefilter (spec §6): packs the seven feature planes it filters
// (normal x y z, depth, albedo r g b) and their variances into four vec4
// planes, (normal, depth), (albedo, spp), (their variances, 0), for
// gbf_filter: one binding per four planes lets it filter all seven in one
// dispatch (one distance and one exp per neighbour instead of two) and
// write its results over the feature planes it no longer reads. The sample
// count rides in the albedo's fourth lane (PACKED-SPP): a kernel that reads
// a neighbour's features learns whether it is valid without another load
// (lavapipe pays per lane and load, not per byte).
// Scalar twin: src/reference/gbf_pack.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::GbfPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint base;      // gbf_pack, gbf_filter: first row of the packed bindings
} push;

PLANE_IN(0, f0)
PLANE_IN(1, f1)
PLANE_IN(2, f2)
PLANE_IN(3, f3)
PLANE_IN(4, f4)
PLANE_IN(5, f5)
PLANE_IN(6, f6)
PLANE_IN(7, v0)
PLANE_IN(8, v1)
PLANE_IN(9, v2)
PLANE_IN(10, v3)
PLANE_IN(11, v4)
PLANE_IN(12, v5)
PLANE_IN(13, v6)
PLANE_IN(14, spp)
layout(std430, set = 0, binding = 15) buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 16) buffer fb_blk { vec4 fb[]; };
layout(std430, set = 0, binding = 17) buffer va_blk { vec4 va[]; };
layout(std430, set = 0, binding = 18) buffer vb_blk { vec4 vb[]; };

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    // The packed planes start at row push.base (row chunks, methods/gbf.rs).
    uint k = i - push.base * push.width;
    fa[k] = vec4(f0[i], f1[i], f2[i], f3[i]);
    fb[k] = vec4(f4[i], f5[i], f6[i], spp[i]);
    va[k] = vec4(v0[i], v1[i], v2[i], v3[i]);
    vb[k] = vec4(v4[i], v5[i], v6[i], 0.0);
}
