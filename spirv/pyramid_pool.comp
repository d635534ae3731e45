#version 460
// The pyramid's coarse level (PYRAMID-LOWBAND, ours): one plane of the
// sanitised statistics pooled over 2x2 blocks of the fine image. Per coarse
// pixel, over the fine pixels of its block inside the image with n >= 1
// (N = sum of their n): a mean as sum(n x) / N, the variance of a mean as
// sum(n^2 v) / N^2, the count as N; 0 where N = 0 (an invalid pixel).
// Scalar twin: src/reference/pyramid_pool.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::PyramidPush.
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

PLANE_IN(0, src)
PLANE_IN(1, spp)
PLANE_OUT(2, dst)

const uint KIND_MEAN = 0u;
const uint KIND_VARIANCE = 1u;
const uint KIND_COUNT = 2u;

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    real total = real(0);
    real acc = real(0);
    for (uint dy = 0u; dy < 2u; ++dy) {
        for (uint dx = 0u; dx < 2u; ++dx) {
            uint fx = 2u * x + dx;
            uint fy = 2u * y + dy;
            if (fx < push.other_width && fy < push.other_height) {
                uint j = fy * push.other_width + fx;
                real n = real(spp_of(spp[j]));
                if (n > real(0)) {
                    real w = push.kind == KIND_VARIANCE ? n * n : n;
                    total += n;
                    acc += w * real(src[j]);
                }
            }
        }
    }
    real v;
    if (push.kind == KIND_COUNT) {
        v = total;
    } else if (total <= real(0)) {
        v = real(0);
    } else if (push.kind == KIND_VARIANCE) {
        v = acc / (total * total);
    } else {
        v = acc / total;
    }
    dst[y * push.width + x] = float(v);
}
