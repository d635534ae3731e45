#version 460
// The device's memory bandwidth (issue #13's roofline): dst = src over
// push.width x push.height f32 words, one vec4 (16 bytes) per invocation,
// so neighbouring invocations touch neighbouring words and a workgroup of
// 64 (8 x 8) moves 1 KiB each way. 8 bytes a word cross memory. Scalar twin:
// src/reference/peak_copy.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::PeakPush (width counts f32 words).
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint iterations;
} push;

layout(std430, set = 0, binding = 0) readonly buffer src_blk { vec4 src[]; };
layout(std430, set = 0, binding = 1) buffer dst_blk { vec4 dst[]; };

void main()
{
    uint w4 = push.width / 4u;
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= w4 || y >= push.height) {
        return;
    }
    uint i = y * w4 + x;
    dst[i] = src[i];
}
