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

// Plane indices of the accumulation layout with position and visibility
// (AccumLayout: channels colour 0-2, albedo 3-5, normal 6-8, depth 9,
// position 10-12, visibility 13; Σx at 2c, Σx² at 2c+1; cross products
// 28-30; count 31). src/render/mod.rs tests these against AccumLayout.

// render_trace's pixel of an item past the pass's samples.
#define NO_PIXEL 0xffffffffu

// Adds the items [a, b) of the window (all of one pixel) to its planes.
void resolve(uint pixel, uint a, uint b)
{
    uint stride = push.plane_stride;
    uint i0 = pixel;
    uint i1 = stride + pixel;
    uint i2 = 2u * stride + pixel;
    uint i3 = 3u * stride + pixel;
    uint i4 = 4u * stride + pixel;
    uint i5 = 5u * stride + pixel;
    uint i6 = 6u * stride + pixel;
    uint i7 = 7u * stride + pixel;
    float count = acc3[i7];

    // The running sums start from the planes and add the samples one by one
    // in sample order.
    vec3 s_col = vec3(acc0[i0], acc0[i2], acc0[i4]);
    vec3 q_col = vec3(acc0[i1], acc0[i3], acc0[i5]);
    vec3 s_alb = vec3(acc0[i6], acc1[i0], acc1[i2]);
    vec3 q_alb = vec3(acc0[i7], acc1[i1], acc1[i3]);
    vec3 s_nrm = vec3(acc1[i4], acc1[i6], acc2[i0]);
    vec3 q_nrm = vec3(acc1[i5], acc1[i7], acc2[i1]);
    vec3 s_pos = vec3(acc2[i4], acc2[i6], acc3[i0]);
    vec3 q_pos = vec3(acc2[i5], acc2[i7], acc3[i1]);
    vec3 s_cross = vec3(acc3[i4], acc3[i5], acc3[i6]);
    vec4 s_dv = vec4(acc2[i2], acc2[i3], acc3[i2], acc3[i3]);   // Σdepth, Σdepth², Σvis, Σvis²
    for (uint k = a; k < b; k++) {
        vec4 v0 = uintBitsToFloat(items[4u * k]);
        vec4 v1 = uintBitsToFloat(items[4u * k + 1u]);
        vec4 v2 = uintBitsToFloat(items[4u * k + 2u]);
        vec4 v3 = uintBitsToFloat(items[4u * k + 3u]);
        vec3 col = v0.xyz;
        vec3 alb = vec3(v0.w, v1.xy);
        vec3 nrm = vec3(v1.zw, v2.x);
        float dep = v2.y;
        vec3 pos = vec3(v2.zw, v3.x);
        float vis = v3.y;
        // Positions are accumulated relative to the lens centre (the
        // layout's position_origin): f32 sums of raw world positions far
        // from 0 lose the footprint's variance. A miss's position is 0, as
        // before (input-format.md), i.e. -origin relative to it.
        vec3 rel = pos - push.origin.xyz;
        s_col += col;
        q_col += col * col;
        s_alb += alb;
        q_alb += alb * alb;
        s_nrm += nrm;
        q_nrm += nrm * nrm;
        s_pos += rel;
        q_pos += rel * rel;
        s_cross += vec3(rel.x * rel.y, rel.x * rel.z, rel.y * rel.z);
        s_dv += vec4(dep, dep * dep, vis, vis * vis);
    }

    // Planes 0-7: colour Σ, Σ² (R, G, B), albedo R.
    acc0[i0] = s_col.r; acc0[i1] = q_col.r; acc0[i2] = s_col.g; acc0[i3] = q_col.g;
    acc0[i4] = s_col.b; acc0[i5] = q_col.b; acc0[i6] = s_alb.r; acc0[i7] = q_alb.r;
    // Planes 8-15: albedo G, B, normal X, Y.
    acc1[i0] = s_alb.g; acc1[i1] = q_alb.g; acc1[i2] = s_alb.b; acc1[i3] = q_alb.b;
    acc1[i4] = s_nrm.x; acc1[i5] = q_nrm.x; acc1[i6] = s_nrm.y; acc1[i7] = q_nrm.y;
    // Planes 16-23: normal Z, depth, position X, Y.
    acc2[i0] = s_nrm.z; acc2[i1] = q_nrm.z; acc2[i2] = s_dv.x;  acc2[i3] = s_dv.y;
    acc2[i4] = s_pos.x; acc2[i5] = q_pos.x; acc2[i6] = s_pos.y; acc2[i7] = q_pos.y;
    // Planes 24-31: position Z, visibility, cross products xy xz yz, count.
    acc3[i0] = s_pos.z; acc3[i1] = q_pos.z; acc3[i2] = s_dv.z;  acc3[i3] = s_dv.w;
    acc3[i4] = s_cross.x; acc3[i5] = s_cross.y; acc3[i6] = s_cross.z;
    acc3[i7] = count + float(b - a);
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
