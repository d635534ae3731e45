#version 460
// APR's features packed for apr_block and apr_gather (APR-PACKED): fa =
// normal xyz, albedo r; fb = albedo g b, depth, visibility (0 without
// APR_VIS). llvmpipe pays per load and lane, not per float: the blocks'
// window passes read a pixel's features in two loads instead of eight.
// Scalar twin: src/reference/apr_pack.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::AprPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint channel;
    uint mode;
    uint last;
    uint flags;
    uint stride;
    uint window;
} push;

PLANE_IN(0, f0)
PLANE_IN(1, f1)
PLANE_IN(2, f2)
PLANE_IN(3, f3)
PLANE_IN(4, f4)
PLANE_IN(5, f5)
PLANE_IN(6, f6)
PLANE_IN(7, f7)
layout(std430, set = 0, binding = 8) buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 9) buffer fb_blk { vec4 fb[]; };

// AprPush.flags bit (mirror mcdenoise::shared::APR_VIS).
#define APR_VIS 1u

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    fa[i] = vec4(f0[i], f1[i], f2[i], f3[i]);
    fb[i] = vec4(f4[i], f5[i], f6[i], (push.flags & APR_VIS) != 0u ? f7[i] : 0.0);
}
