#version 460
// Picks a light for each of a list of random numbers with the path
// tracer's light selection (select_light in render_scene.glsl) and writes
// its index in the light table. Test aid: tests/render.rs compares it with
// a linear scan of the table on the host (GpuScene::select_light_linear).
#include "render/render_scene.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::render::RaysPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint count;
} push;

// The random numbers in [0, 1).
layout(std430, set = 0, binding = 5) readonly buffer Us { float us[]; };
// One light-table index per number.
layout(std430, set = 0, binding = 6) buffer Picks { uint picks[]; };

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    uint i = y * push.width + x;
    if (x >= push.width || y >= push.height || i >= push.count || P.counts.w == 0u) {
        return;
    }
    picks[i] = select_light(us[i]);
}
