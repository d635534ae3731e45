#version 460
// The built-in path tracer: one invocation per work item, i.e. per sample
// of the pass. render_scan gives the items (an exclusive prefix sum of the
// pass's per-pixel counts); this kernel traces a window of them and leaves
// each sample's values in the items buffer, and render_resolve adds them to
// the accumulation planes (src/accum.rs, layout with position and
// visibility). Host side: src/render/mod.rs. The images use no atomics;
// the traversal counters (binding 8) add each invocation's rays and BVH
// node visits with integer atomics and a carry, so their totals are exact
// (RENDER-COUNT).
//
// Per sample: box-filtered position in the pixel, thin-lens camera, shutter
// time in [0, 1); diffuse BSDF with cosine sampling, next-event estimation
// to the emitters of the light table (spheres, quads, triangles; picked by
// power) combined with BSDF sampling by MIS (power heuristic), Russian
// roulette after 3 vertices, environment on a miss.
#include "render/render_scene.glsl"

layout(local_size_x = 64) in;

// Mirrors mcdenoise::render::TracePush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;          // first grid row of the band (Batch::dispatch)
    uint item0;         // the window's first item (of the pass)
    uint items;         // items in the window
    uint seed_lo;
    uint seed_hi;
    uint uniform_spp;   // > 0: every pixel has this many samples (no search)
} push;

// Per pixel: (exclusive prefix of the pass's counts, count plane at the
// start of the pass); entry width * height holds (total, 0) (render_scan).
layout(std430, set = 0, binding = 5) readonly buffer Scan { uvec2 scan[]; };
// Four uvec4 per item of the window: the float bits of the 14 values in
// AccumLayout channel order (colour, albedo, normal, depth, position,
// visibility), then the pixel (NO_PIXEL past the pass's samples) and the
// sample index. Read by render_resolve (and Renderer::run_pass_debug).
layout(std430, set = 0, binding = 6) buffer Items { uvec4 items[]; };
// Per-vertex shading normals: three vec4 per entry; a triangle's entry
// index is in the bits of its p3.w (0xffffffff: flat).
layout(std430, set = 0, binding = 7) readonly buffer Normals { vec4 vnormals[]; };
// Traversal counters since the renderer's last reset: rays (low, high
// word), BVH node visits (low, high word).
layout(std430, set = 0, binding = 8) buffer Work { uint work[]; };
// Placements of keyframed objects back to the scene file's: three vec4
// (the rows of a 3x4 affine map) per entry, entry 0 the identity; a
// primitive's entry is in bits 16-22 of its p0.w (GpuScene::rest).
layout(std430, set = 0, binding = 9) readonly buffer Rest { vec4 rest[]; };

#include "render/render_path.glsl"

// Traces item j of the window (if it is one of the pass's samples).
void trace_item(uint j)
{
    // Item i is sample i - prefix[p] of the last pixel p with prefix[p] <= i
    // (it has a non-zero count): a binary search, ~log2(pixels) steps, or
    // i / spp in a uniform pass.
    uint i = push.item0 + j;
    uint lo = push.uniform_spp > 0u ? i / push.uniform_spp : 0u;
    uint hi = push.uniform_spp > 0u ? lo + 1u : push.width * push.height;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) >> 1u;
        if (scan[mid].x <= i) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    uint b = 4u * j;
    if (i >= scan[lo + 1u].x) {
        // Past the counts' total (a map that sums to less than the host's).
        items[b + 3u] = uvec4(0u, 0u, NO_PIXEL, 0u);
        return;
    }
    uint pixel = lo;
    // The sample index counts the pixel's samples over all passes: the
    // random numbers of a sample do not depend on how passes split them.
    uint sample_index = scan[pixel].y + (i - scan[pixel].x);
    uvec4 key = uvec4(pixel, sample_index, push.seed_hi, push.seed_lo);
    vec3 col, alb, nrm, pos;
    float dep, vis;
    trace_sample(key, uvec2(pixel % push.width, pixel / push.width), col, alb, nrm, dep, pos, vis);
    items[b] = floatBitsToUint(vec4(col, alb.r));
    items[b + 1u] = floatBitsToUint(vec4(alb.gb, nrm.xy));
    items[b + 2u] = floatBitsToUint(vec4(nrm.z, dep, pos.xy));
    items[b + 3u] = uvec4(floatBitsToUint(pos.z), floatBitsToUint(vis), pixel, sample_index);
}

void main()
{
    uint row_items = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    uint j = (push.row0 + gl_GlobalInvocationID.y) * row_items + gl_GlobalInvocationID.x;
    if (j < push.items) {
        trace_item(j);
    }
    // One atomic pair per counter and invocation that traced.
    if (g_rays > 0u) {
        add_wide(0u, g_rays);
        add_wide(2u, g_nodes);
    }
}
