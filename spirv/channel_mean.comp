#version 460
// out = (a + b + c) / 3 per pixel: vbar from the three colour variances
// (spec §0.1 GREY). Scalar twin: src/reference/channel_mean.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::ChannelMeanPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint pad0;
} push;

PLANE_IN(0, a)
PLANE_IN(1, b)
PLANE_IN(2, c)
PLANE_OUT(3, out_p)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    out_p[i] = float((real(a[i]) + real(b[i]) + real(c[i])) / real(3));
}
