#version 460
// Features from samples of their own (RENDER-FEATURE-SAMPLES): after
// render_trace has traced a window, each of its items gets its albedo,
// normal, depth, position and visibility again from a camera path with
// independent random numbers (another pixel position, lens point and
// shutter time, another light sample for the visibility), so that the
// features' noise is not the colour's. The colour stays the item's own.
// Traces the camera ray through smooth mirrors to the first other surface,
// and the visibility's shadow ray at the first surface the camera ray hits
// unless it is smooth (a mirror or glass takes no light sample; the
// visibility stays 1), as render_trace takes it (render_path.glsl with
// FEATURES_ONLY). Host side: Renderer::record in src/render/mod.rs.
#include "render/render_scene.glsl"

#define FEATURES_ONLY
#include "render/render_path.glsl"

// The feature paths' random numbers: the sample's key with this in the
// seed's high word, a stream apart from every colour path's.
#define FEATURE_STREAM 0x6a09e667u

void main()
{
    uint row_items = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    uint j = (push.row0 + gl_GlobalInvocationID.y) * row_items + gl_GlobalInvocationID.x;
    uint b = 4u * j;
    if (j < push.items && items[b + 3u].z != NO_PIXEL) {
        uint pixel = items[b + 3u].z;
        uvec4 key = uvec4(pixel, items[b + 3u].w, push.seed_hi ^ FEATURE_STREAM, push.seed_lo);
        vec3 col, alb, nrm, pos;
        float dep, vis;
        trace_sample(key, uvec2(pixel % push.width, pixel / push.width), col, alb, nrm, dep, pos, vis);
        items[b].w = floatBitsToUint(alb.r);
        items[b + 1u] = floatBitsToUint(vec4(alb.gb, nrm.xy));
        items[b + 2u] = floatBitsToUint(vec4(nrm.z, dep, pos.xy));
        items[b + 3u].xy = floatBitsToUint(vec2(pos.z, vis));
    }
    if (g_rays > 0u) {
        add_wide(0u, g_rays);
        add_wide(2u, g_nodes);
    }
}
