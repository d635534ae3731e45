#version 460
// Traces a list of rays through the built-in renderer's BVH and writes the
// nearest hit (t, primitive). Test aid: tests/render.rs compares it with a
// brute-force f64 intersection (Primitive::intersect in src/render/scene.rs).
#include "render/render_scene.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::render::RaysPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint count;
} push;

// Two vec4 per ray: (origin, tmin), (direction, time).
layout(std430, set = 0, binding = 5) readonly buffer Rays { vec4 rays[]; };
// One vec2 per ray: (t, primitive index), or (-1, -1) on a miss. Indices
// are exact as floats below 2^24 primitives.
layout(std430, set = 0, binding = 6) buffer Hits { vec2 hits[]; };

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    uint i = y * push.width + x;
    if (x >= push.width || y >= push.height || i >= push.count) {
        return;
    }
    vec4 a = rays[2u * i];
    vec4 b = rays[2u * i + 1u];
    Hit h = trace(a.xyz, b.xyz, b.w, a.w, T_INF, false);
    hits[i] = h.prim < 0 ? vec2(-1.0) : vec2(h.t, float(h.prim));
}
