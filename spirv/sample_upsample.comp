#version 460
// A coarse sample map's priority at the full resolution (MAP-COARSE, ours):
// each fine pixel takes the priority r of the coarse pixel whose 2x2 block
// holds it, out[x, y] = coarse[x / 2, y / 2]. The fine pixels' validity is
// the allocation's (sample_reduce reads the fine counts). A copy: no
// arithmetic, so the f32 and f64 variants agree bit for bit.
// Scalar twin: src/reference/sample_upsample.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::PyramidPush (width, height: the fine image;
// other_width, other_height: the coarse one).
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint kind;
    uint other_width;
    uint other_height;
    float eps;
    uint pad0;
} push;

PLANE_IN(0, coarse)
PLANE_OUT(1, dst)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint cx = min(x / 2u, push.other_width - 1u);
    uint cy = min(y / 2u, push.other_height - 1u);
    dst[y * push.width + x] = coarse[cy * push.other_width + cx];
}
