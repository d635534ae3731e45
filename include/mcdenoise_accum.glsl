// mcdenoise_accum.glsl: the accumulation layout mcdenoise reads, as shader
// code. A renderer includes it in the compute shader that adds its samples,
// hands the buffer to mcdenoise (mcd_denoiser_record in mcdenoise.h, or
// Denoiser::record_into in Rust), and mcdenoise finalises it on the GPU.
// The same file is compiled into mcdenoise's own path tracer
// (spirv/render/render_resolve.comp: with position and visibility) and into
// the examples' shader (examples/c/accumulate.comp: without), so there is
// one definition; both are denoised through Rust's AccumLayout
// (src/accum.rs) in the test suite.
//
// The layout: one buffer of planes, each plane width * height f32 values in
// row-major order; plane i starts at float i * mcd_plane_stride(width *
// height) (planes are 256-byte aligned, so each can be bound on its own).
// Planes, in order:
//   for each scalar channel c: Σx_c, then Σx_c²          (2 planes each)
//   if MCDENOISE_ACCUM_POSITION: Σxy, Σxz, Σyz of the position (3 planes)
//   the sample count n (f32)                             (1 plane)
// Scalar channels: colour R G B, albedo R G B, normal X Y Z, depth, then
// position X Y Z (optional) and visibility (optional). A miss adds 0 to
// every feature (position: 0, i.e. -origin relative to the origin) but
// counts as a sample. Positions are accumulated relative to an origin near
// the visible geometry (the camera, say) and the same origin is given to
// mcdenoise (AccumLayout::position_origin): f32 sums of world positions far
// from 0 lose the variance the G-buffer prefilter reads.
//
// Before including, define:
//   MCDENOISE_ACCUM_POSITION    1 if positions are accumulated (default 0)
//   MCDENOISE_ACCUM_VISIBILITY  1 if visibility is accumulated (default 0)
//   MCDENOISE_ACCUM_LOAD(plane, pixel)         an expression: the float at
//                                              plane `plane`, pixel `pixel`
//   MCDENOISE_ACCUM_STORE(plane, pixel, value) a statement storing it
// For one buffer bound whole, for example:
//   layout(std430, binding = 0) buffer Accum { float accum[]; };
//   #define MCDENOISE_ACCUM_LOAD(p, i) accum[(p) * stride + (i)]
//   #define MCDENOISE_ACCUM_STORE(p, i, v) accum[(p) * stride + (i)] = (v)
// Plane indices are compile-time constants after unrolling, so a host that
// splits the planes over several bindings (to stay within
// maxStorageBufferRange) selects the binding in its macros at no cost.
//
// One invocation should own a pixel while it adds (no atomics here): add a
// pixel's samples in one invocation, or in passes that do not overlap.

#ifndef MCDENOISE_ACCUM_GLSL
#define MCDENOISE_ACCUM_GLSL

#ifndef MCDENOISE_ACCUM_POSITION
#define MCDENOISE_ACCUM_POSITION 0
#endif
#ifndef MCDENOISE_ACCUM_VISIBILITY
#define MCDENOISE_ACCUM_VISIBILITY 0
#endif

// Scalar channels.
const uint MCD_CHANNELS = 10u + 3u * uint(MCDENOISE_ACCUM_POSITION) + uint(MCDENOISE_ACCUM_VISIBILITY);
// Channel numbers: colour 0-2, albedo 3-5, normal 6-8, depth 9, position
// 10-12 (if accumulated), visibility after them (if accumulated).
const uint MCD_CHANNEL_COLOR = 0u;
const uint MCD_CHANNEL_ALBEDO = 3u;
const uint MCD_CHANNEL_NORMAL = 6u;
const uint MCD_CHANNEL_DEPTH = 9u;
const uint MCD_CHANNEL_POSITION = 10u;
const uint MCD_CHANNEL_VISIBILITY = 10u + 3u * uint(MCDENOISE_ACCUM_POSITION);
// First of the three position cross-product planes (if positions).
const uint MCD_PLANE_CROSS = 2u * MCD_CHANNELS;
// The sample-count plane.
const uint MCD_PLANE_COUNT = 2u * MCD_CHANNELS + 3u * uint(MCDENOISE_ACCUM_POSITION);
// Number of planes.
const uint MCD_PLANES = MCD_PLANE_COUNT + 1u;

// Plane index of Σx of channel c, and of Σx².
uint mcd_sum_plane(uint c) { return 2u * c; }
uint mcd_sumsq_plane(uint c) { return 2u * c + 1u; }

// Floats from one plane's start to the next for an image of `pixels`
// pixels: pixels rounded up to 64 (256 bytes).
uint mcd_plane_stride(uint pixels) { return (max(pixels, 1u) + 63u) & ~63u; }

// One sample of a pixel: what the renderer's path produced.
struct McdSample {
    vec3 color;       // radiance (linear RGB)
    vec3 albedo;      // first non-specular hit's albedo
    vec3 normal;      // its shading normal
    float depth;      // its distance along the ray
    vec3 position;    // its world position (read if MCDENOISE_ACCUM_POSITION)
    float visibility; // direct-light visibility 0..1 (if MCDENOISE_ACCUM_VISIBILITY)
};

// A miss: every feature 0 (the colour is the environment's).
McdSample mcd_miss(vec3 color)
{
    return McdSample(color, vec3(0.0), vec3(0.0), 0.0, vec3(0.0), 0.0);
}

// A pixel's planes, in layout order.
struct McdSums {
    float p[MCD_PLANES];
};

// Loads pixel `pixel`'s planes.
McdSums mcd_load(uint pixel)
{
    McdSums s;
    for (uint k = 0u; k < MCD_PLANES; k++) {
        s.p[k] = MCDENOISE_ACCUM_LOAD(k, pixel);
    }
    return s;
}

// Stores pixel `pixel`'s planes.
void mcd_store(uint pixel, McdSums s)
{
    for (uint k = 0u; k < MCD_PLANES; k++) {
        MCDENOISE_ACCUM_STORE(k, pixel, s.p[k]);
    }
}

// Adds one scalar channel's value.
void mcd_add_channel(inout McdSums s, uint c, float v)
{
    s.p[2u * c] += v;
    s.p[2u * c + 1u] += v * v;
}

// Adds one sample to running sums; `origin` is the position origin given to
// mcdenoise (ignored without positions).
void mcd_add(inout McdSums s, McdSample x, vec3 origin)
{
    for (uint k = 0u; k < 3u; k++) {
        mcd_add_channel(s, MCD_CHANNEL_COLOR + k, x.color[k]);
        mcd_add_channel(s, MCD_CHANNEL_ALBEDO + k, x.albedo[k]);
        mcd_add_channel(s, MCD_CHANNEL_NORMAL + k, x.normal[k]);
    }
    mcd_add_channel(s, MCD_CHANNEL_DEPTH, x.depth);
#if MCDENOISE_ACCUM_POSITION
    vec3 rel = x.position - origin;
    for (uint k = 0u; k < 3u; k++) {
        mcd_add_channel(s, MCD_CHANNEL_POSITION + k, rel[k]);
    }
    s.p[MCD_PLANE_CROSS] += rel.x * rel.y;
    s.p[MCD_PLANE_CROSS + 1u] += rel.x * rel.z;
    s.p[MCD_PLANE_CROSS + 2u] += rel.y * rel.z;
#endif
#if MCDENOISE_ACCUM_VISIBILITY
    mcd_add_channel(s, MCD_CHANNEL_VISIBILITY, x.visibility);
#endif
    s.p[MCD_PLANE_COUNT] += 1.0;
}

// Adds one sample to pixel `pixel` of the buffer (load, add, store).
void mcdenoise_accumulate(uint pixel, McdSample x, vec3 origin)
{
    McdSums s = mcd_load(pixel);
    mcd_add(s, x, origin);
    mcd_store(pixel, s);
}

#endif
