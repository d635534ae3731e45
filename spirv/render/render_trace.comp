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
