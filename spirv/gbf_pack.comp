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
//
// PACK-QUADS: an invocation packs four consecutive pixels of the rows
// [push.base, push.height) taken as one run of pixels (quad k: pixels
// 4k .. 4k + 3 of the run, which starts at a multiple of 4), reading each
// input plane as one vec4: 15 loads and 16 stores per 4 pixels instead of
// 15 loads and 4 stores per pixel. The inputs are bound as whole vec4s
// (PlaneSet::plane_quads); the values of a last, partial quad past the run
// are read but not stored. The grid's rows are rows of ceil(width / 4)
// quads, from row push.base.
// Scalar twin: src/reference/gbf_pack.rs.
#include "lib/common.glsl"
#extension GL_EXT_control_flow_attributes : require

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::GbfPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;    // gbf_pack: the end of its rows
    uint row0;
    uint base;      // gbf_pack, gbf_filter: first row of the packed bindings
    float second_below;  // gbf_filter: GBF-SECOND's pass when > 0
} push;

layout(std430, set = 0, binding = 0) readonly buffer f0_blk { vec4 f0[]; };
layout(std430, set = 0, binding = 1) readonly buffer f1_blk { vec4 f1[]; };
layout(std430, set = 0, binding = 2) readonly buffer f2_blk { vec4 f2[]; };
layout(std430, set = 0, binding = 3) readonly buffer f3_blk { vec4 f3[]; };
layout(std430, set = 0, binding = 4) readonly buffer f4_blk { vec4 f4[]; };
layout(std430, set = 0, binding = 5) readonly buffer f5_blk { vec4 f5[]; };
layout(std430, set = 0, binding = 6) readonly buffer f6_blk { vec4 f6[]; };
layout(std430, set = 0, binding = 7) readonly buffer v0_blk { vec4 v0[]; };
layout(std430, set = 0, binding = 8) readonly buffer v1_blk { vec4 v1[]; };
layout(std430, set = 0, binding = 9) readonly buffer v2_blk { vec4 v2[]; };
layout(std430, set = 0, binding = 10) readonly buffer v3_blk { vec4 v3[]; };
layout(std430, set = 0, binding = 11) readonly buffer v4_blk { vec4 v4[]; };
layout(std430, set = 0, binding = 12) readonly buffer v5_blk { vec4 v5[]; };
layout(std430, set = 0, binding = 13) readonly buffer v6_blk { vec4 v6[]; };
layout(std430, set = 0, binding = 14) readonly buffer spp_blk { vec4 spp[]; };
layout(std430, set = 0, binding = 15) buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 16) buffer fb_blk { vec4 fb[]; };
layout(std430, set = 0, binding = 17) buffer va_blk { vec4 va[]; };
layout(std430, set = 0, binding = 18) buffer vb_blk { vec4 vb[]; };

void main()
{
    uint w4 = (push.width + 3u) / 4u;
    uint gx = gl_GlobalInvocationID.x;
    uint gy = push.row0 + gl_GlobalInvocationID.y - push.base;
    uint run = (push.height - push.base) * push.width;
    uint k0 = 4u * (gy * w4 + gx);
    if (gx >= w4 || k0 >= run) {
        return;
    }
    // The run starts at pixel base * width, a multiple of 4 (methods::gbf).
    uint q = (push.base * push.width) / 4u + k0 / 4u;
    vec4 a0 = f0[q], a1 = f1[q], a2 = f2[q], a3 = f3[q];
    vec4 b0 = f4[q], b1 = f5[q], b2 = f6[q], b3 = spp[q];
    vec4 c0 = v0[q], c1 = v1[q], c2 = v2[q], c3 = v3[q];
    vec4 d0 = v4[q], d1 = v5[q], d2 = v6[q];
    // Pixel k0 + j of the run is index k0 + j of the packed planes (which
    // start at row push.base). Constant lane indices after unrolling.
    [[unroll]] for (uint j = 0u; j < 4u; ++j) {
        if (k0 + j < run) {
            fa[k0 + j] = vec4(a0[j], a1[j], a2[j], a3[j]);
            fb[k0 + j] = vec4(b0[j], b1[j], b2[j], b3[j]);
            va[k0 + j] = vec4(c0[j], c1[j], c2[j], c3[j]);
            vb[k0 + j] = vec4(d0[j], d1[j], d2[j], 0.0);
        }
    }
}
