#version 460
// Adds traced samples to the accumulation planes (src/accum.rs, layout with
// position and visibility). Host side: Renderer::record in
// src/render/mod.rs.
//
// render_trace leaves one work item per sample (its 14 values, its pixel and
// its sample index) in pixel order, each pixel's samples in sample order.
// This kernel resolves the items [begin, end) of the window: the pixels they
// belong to are first..last (the pixels of items begin and end - 1), and
// invocation k of `lanes` takes pixels first + k, first + k + lanes, ...:
// for each it adds its run of items to the pixel's planes one sample after
// the other in sample order, with running sums that start from the planes.
// So one invocation owns its pixel (gather, no atomics), a SIMD vector works
// on neighbouring pixels, and the planes are bit-identical however the
// samples are split into passes, windows and resolves. llvmpipe ends all
// loops of an invocation after 65,535 iterations in total: an invocation
// runs at most pixels / lanes + 1 pixel iterations and end - begin item
// iterations, which the host keeps within that (RESOLVE_CHUNK, RESOLVE_LANES).

layout(local_size_x = 64) in;

// Mirrors mcdenoise::render::ResolvePush.
layout(push_constant) uniform Push {
    uint begin;          // first item (index into the window's items)
    uint end;            // one past the last
    uint row0;           // first grid row of the band (Batch::dispatch)
    uint plane_stride;   // floats between plane starts
    vec4 origin;         // xyz: the layout's position origin (the lens centre)
    uint item0;          // the window's first item (of the pass)
    uint pixels;         // pixels of the image
    uint lanes;          // invocations of the dispatch that take pixels
    uint pad;
} push;

// Four uvec4 per item: the float bits of colour, albedo, normal, depth,
// position, visibility (AccumLayout channel order), then pixel and sample
// index (render_trace.comp).
layout(std430, set = 0, binding = 0) readonly buffer Items { uvec4 items[]; };
// The accumulation planes in four bindings of eight planes each (plane
// 8g + k of group g at k * plane_stride), so that no binding exceeds
// maxStorageBufferRange below 4 Mpixels.
// Per pixel: (exclusive prefix of the pass's counts, first sample index);
// entry `pixels` holds (total, 0) (render_scan).
layout(std430, set = 0, binding = 1) readonly buffer Scan { uvec2 scan[]; };
layout(std430, set = 0, binding = 2) buffer Accum0 { float acc0[]; };
layout(std430, set = 0, binding = 3) buffer Accum1 { float acc1[]; };
layout(std430, set = 0, binding = 4) buffer Accum2 { float acc2[]; };
layout(std430, set = 0, binding = 5) buffer Accum3 { float acc3[]; };

// The accumulation layout with position and visibility, as any renderer
// writes it: include/mcdenoise_accum.glsl (32 planes; src/render/mod.rs
// tests the plane indices against AccumLayout). Plane k lives in binding
// k / 8 at (k % 8) * plane_stride; the plane indices are constants once the
// header's loops are unrolled, so the selects fold away.
#define MCDENOISE_ACCUM_POSITION 1
#define MCDENOISE_ACCUM_VISIBILITY 1
#define ACC_INDEX(k, i) (((k) & 7u) * push.plane_stride + (i))
#define MCDENOISE_ACCUM_LOAD(k, i) acc_load(k, i)
#define MCDENOISE_ACCUM_STORE(k, i, v) acc_store(k, i, v)

float acc_load(uint k, uint i)
{
    uint j = ACC_INDEX(k, i);
    switch (k >> 3u) {
    case 0u: return acc0[j];
    case 1u: return acc1[j];
    case 2u: return acc2[j];
    default: return acc3[j];
    }
}

void acc_store(uint k, uint i, float v)
{
    uint j = ACC_INDEX(k, i);
    switch (k >> 3u) {
    case 0u: acc0[j] = v; break;
    case 1u: acc1[j] = v; break;
    case 2u: acc2[j] = v; break;
    default: acc3[j] = v; break;
    }
}

#include "mcdenoise_accum.glsl"

// render_trace's pixel of an item past the pass's samples.
#define NO_PIXEL 0xffffffffu

// Adds the items [a, b) of the window (all of one pixel) to its planes:
// running sums that start from the planes and add the samples one by one in
// sample order. Positions are relative to the lens centre (the layout's
// position_origin).
void resolve(uint pixel, uint a, uint b)
{
    McdSums s = mcd_load(pixel);
    for (uint k = a; k < b; k++) {
        vec4 v0 = uintBitsToFloat(items[4u * k]);
        vec4 v1 = uintBitsToFloat(items[4u * k + 1u]);
        vec4 v2 = uintBitsToFloat(items[4u * k + 2u]);
        vec4 v3 = uintBitsToFloat(items[4u * k + 3u]);
        McdSample x;
        x.color = v0.xyz;
        x.albedo = vec3(v0.w, v1.xy);
        x.normal = vec3(v1.zw, v2.x);
        x.depth = v2.y;
        x.position = vec3(v2.zw, v3.x);
        x.visibility = v3.y;
        mcd_add(s, x, push.origin.xyz);
    }
    mcd_store(pixel, s);
}

void main()
{
    uint row_items = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    uint k = (push.row0 + gl_GlobalInvocationID.y) * row_items + gl_GlobalInvocationID.x;
    if (k >= push.lanes) {
        return;
    }
    uint first = items[4u * push.begin + 3u].z;
    if (first == NO_PIXEL) {
        return;   // items past the pass's samples come last
    }
    uint last = items[4u * (push.end - 1u) + 3u].z;
    last = last == NO_PIXEL ? push.pixels - 1u : last;
    // The resolve's items, as items of the pass.
    uint g0 = push.item0 + push.begin;
    uint g1 = push.item0 + push.end;
    for (uint p = first + k; p <= last; p += push.lanes) {
        uint a = max(scan[p].x, g0);
        uint b = min(scan[p + 1u].x, g1);
        if (a < b) {
            resolve(p, a - push.item0, b - push.item0);
        }
    }
}
