// The built-in path tracer's scene on the GPU: bindings 0-4, random
// numbers, ray/primitive intersection and BVH traversal. Host side:
// src/render/gpu_scene.rs (layouts) and src/render/scene.rs (the f64 twin
// of the intersection, Primitive::intersect).
//
// All arithmetic is f32: the render kernels have no f64 variant of their own
// (their `_f64` build is the same code; tests/reflect.rs exempts them).

// Mirrors mcdenoise::render::gpu_scene::GpuParams.
layout(std430, set = 0, binding = 0) readonly buffer Params {
    vec4 cam_pos;    // xyz lens centre, w lens radius
    vec4 lens_u;     // unit right vector
    vec4 lens_v;     // unit up vector
    vec4 focus_w;    // forward * focus distance
    vec4 half_u;     // right * half image width at the focus distance
    vec4 half_v;     // up * half image height at the focus distance
    vec4 env;        // rgb environment radiance
    uvec4 counts;    // nodes, primitives, max depth, lights
} P;

// Binary BVH, two vec4 per node: (min, first), (max, count). count == 0:
// inner node with children first and first + 1; else a leaf of primitives
// [first, first + count).
layout(std430, set = 0, binding = 1) readonly buffer Nodes { vec4 nodes[]; };

// Four vec4 per primitive (see gpu_scene.rs): p0 = (a, kind | material << 2
// | placement << 16),
// p1 = (b, radius), p2 = (c, light pdf per unit area), p3 = (motion, bits of
// the shading-normal entry).
// Sphere: a = centre. Quad: corner a, edges b, c. Triangle: vertex a, edges b, c.
layout(std430, set = 0, binding = 2) readonly buffer Prims { vec4 prims[]; };

// Three vec4 per material: (class | texture << 8, texture scale, GGX alpha,
// index of refraction), colour a, colour b. The colours are the albedo's
// (diffuse, plastic), the reflectance's (conductor), the tint (dielectric)
// or the radiance (emissive); a constant has a == b.
layout(std430, set = 0, binding = 3) readonly buffer Materials { vec4 mats[]; };

// One vec4 per light: (primitive index bits, cumulative selection
// probability, 0, 0), in ascending order of the cumulative probability;
// the last entry's is 1.
layout(std430, set = 0, binding = 4) readonly buffer Lights { vec4 lights[]; };

#define KIND_SPHERE 0u
#define KIND_QUAD 1u
#define KIND_TRIANGLE 2u

// Material classes (low byte of a material's first word).
#define MAT_DIFFUSE 0u
#define MAT_EMISSIVE 3u
#define MAT_CONDUCTOR 4u
#define MAT_PLASTIC 5u
#define MAT_DIELECTRIC 6u
// Albedo textures (second byte).
#define TEX_CONSTANT 0u
#define TEX_CHECKER 1u
#define TEX_NOISE 2u

// Must cover the deepest BVH path (the host checks: gpu_scene::STACK_SIZE).
#define STACK_SIZE 32
#define T_INF 3.0e38
#define PI 3.14159265358979

// ---------------------------------------------------------------- random numbers
// Counter-based: a pure function of (pixel, sample, dimension, seed), so the
// same sample gets the same numbers however passes and bands split the work.
// pcg4d (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering").
uvec4 pcg4d(uvec4 v)
{
    v = v * 1664525u + 1013904223u;
    v.x += v.y * v.w; v.y += v.z * v.x; v.z += v.x * v.y; v.w += v.y * v.z;
    v ^= v >> 16u;
    v.x += v.y * v.w; v.y += v.z * v.x; v.z += v.x * v.y; v.w += v.y * v.z;
    return v;
}

// Two uniform numbers in [0, 1) for dimension pair `dim`.
vec2 rand2(uvec4 key, uint dim)
{
    uvec4 h = pcg4d(uvec4(key.x, key.y, key.z ^ (dim * 0x9E3779B9u), key.w));
    return vec2(h.xy >> 8u) * (1.0 / 16777216.0);
}

// ---------------------------------------------------------------- light selection
// The light whose selection interval [cdf[l-1], cdf[l]) holds u: the first l
// with u < cdf[l], or the last light (u ≥ every entry only by rounding).
// Binary search over the cumulative probabilities, O(log lights); the same
// index as a linear scan (tests/render.rs compares them through render_lights).
uint select_light(float u)
{
    uint lo = 0u;
    uint hi = P.counts.w - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) >> 1u;
        if (u >= lights[mid].y) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// ---------------------------------------------------------------- intersection
struct Hit {
    float t;
    int prim;   // -1: miss
};

uint prim_kind(uint i) { return floatBitsToUint(prims[4u * i].w) & 3u; }
uint prim_material(uint i) { return (floatBitsToUint(prims[4u * i].w) >> 2u) & 0x3fffu; }

// Nearest hit of primitive i in (tmin, tbest), or tbest.
float intersect_prim(uint i, vec3 o, vec3 d, float time, float tmin, float tbest)
{
    vec4 p0 = prims[4u * i];
    vec4 p1 = prims[4u * i + 1u];
    vec4 p2 = prims[4u * i + 2u];
    vec3 motion = prims[4u * i + 3u].xyz;
    uint kind = floatBitsToUint(p0.w) & 3u;
    vec3 oo = o - time * motion;
    if (kind == KIND_SPHERE) {
        vec3 oc = oo - p0.xyz;
        float a = dot(d, d);
        float b = dot(oc, d);
        float c = dot(oc, oc) - p1.w * p1.w;
        float disc = b * b - a * c;
        if (disc < 0.0) {
            return tbest;
        }
        float sq = sqrt(disc);
        float t = (-b - sq) / a;
        if (t <= tmin) {
            t = (-b + sq) / a;
        }
        return (t > tmin && t < tbest) ? t : tbest;
    }
    vec3 e1 = p1.xyz;
    vec3 e2 = p2.xyz;
    vec3 pv = cross(d, e2);
    float det = dot(e1, pv);
    if (det == 0.0) {
        return tbest;
    }
    float inv = 1.0 / det;
    vec3 s = oo - p0.xyz;
    float u = dot(s, pv) * inv;
    vec3 q = cross(s, e1);
    float v = dot(d, q) * inv;
    bool inside = u >= 0.0 && v >= 0.0 && (kind == KIND_TRIANGLE ? u + v <= 1.0 : (u <= 1.0 && v <= 1.0));
    float t = dot(e2, q) * inv;
    return (inside && t > tmin && t < tbest) ? t : tbest;
}

// Entry distance of the ray into node n's box if it is below tbest, else T_INF.
float box_entry(uint n, vec3 o, vec3 inv_d, float tmin, float tbest)
{
    vec4 lo = nodes[2u * n];
    vec4 hi = nodes[2u * n + 1u];
    vec3 t0 = (lo.xyz - o) * inv_d;
    vec3 t1 = (hi.xyz - o) * inv_d;
    vec3 tn = min(t0, t1);
    vec3 tf = max(t0, t1);
    float enter = max(max(tn.x, tn.y), max(tn.z, tmin));
    float leave = min(min(tf.x, tf.y), min(tf.z, tbest));
    return enter <= leave ? enter : T_INF;
}

// This invocation's traversal work so far: rays traced and BVH nodes
// visited (render_trace adds them up per pass; the other kernels ignore
// them).
uint g_rays = 0u;
uint g_nodes = 0u;

// Nearest hit in (tmin, tmax) at shutter time `time`. With any_hit, returns
// the first hit found (shadow rays).
Hit trace(vec3 o, vec3 d, float time, float tmin, float tmax, bool any_hit)
{
    g_rays++;
    Hit h;
    h.t = tmax;
    h.prim = -1;
    if (P.counts.x == 0u) {
        return h;
    }
    // No infinities from zero components: the slab test stays NaN-free.
    vec3 safe = mix(d, vec3(1e-30), lessThan(abs(d), vec3(1e-30)));
    vec3 inv_d = 1.0 / safe;
    if (box_entry(0u, o, inv_d, tmin, h.t) >= T_INF) {
        return h;
    }
    uint stack[STACK_SIZE];
    int sp = 0;
    uint node = 0u;
    while (true) {
        g_nodes++;
        vec4 hi = nodes[2u * node + 1u];
        uint first = floatBitsToUint(nodes[2u * node].w);
        uint count = floatBitsToUint(hi.w);
        if (count > 0u) {
            for (uint i = first; i < first + count; i++) {
                float t = intersect_prim(i, o, d, time, tmin, h.t);
                if (t < h.t) {
                    h.t = t;
                    h.prim = int(i);
                }
            }
            if (any_hit && h.prim >= 0) {
                return h;
            }
        } else {
            float ta = box_entry(first, o, inv_d, tmin, h.t);
            float tb = box_entry(first + 1u, o, inv_d, tmin, h.t);
            if (ta < T_INF && tb < T_INF) {
                bool a_first = ta <= tb;
                node = a_first ? first : first + 1u;
                stack[sp] = a_first ? first + 1u : first;
                sp++;
                continue;
            }
            if (ta < T_INF) {
                node = first;
                continue;
            }
            if (tb < T_INF) {
                node = first + 1u;
                continue;
            }
        }
        if (sp == 0) {
            break;
        }
        sp--;
        node = stack[sp];
    }
    return h;
}
