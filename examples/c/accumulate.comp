#version 450
// The C example's "renderer": adds this pass's samples of a procedural scene
// (a noisy gradient with an edge) to the accumulation buffer, with the
// layout and the accumulate function of include/mcdenoise_accum.glsl.
// Pass 0 takes `uniform_spp` samples in every pixel; later passes take as
// many as mcdenoise's sample map says (its output buffer, bound as is).

layout(local_size_x = 64) in;

layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint pass_index;
    uint uniform_spp;
    uint stride;     // floats between plane starts: mcd_plane_stride(width * height)
    uint frame;      // a sequence's frame: noise of its own (0 outside one)
} pc;

layout(std430, binding = 0) buffer Accum { float accum[]; };
layout(std430, binding = 1) readonly buffer SampleMap { uint sample_map[]; };

// No visibility; the position sums only if MCDENOISE_ACCUM_POSITION is
// defined to 1 before the include (10 channels and 21 planes without them).
#define MCDENOISE_ACCUM_LOAD(p, i) accum[(p) * pc.stride + (i)]
#define MCDENOISE_ACCUM_STORE(p, i, v) accum[(p) * pc.stride + (i)] = (v)
#include "mcdenoise_accum.glsl"

// PCG hash (Jarzynski and Olano 2020).
uint pcg(uint v)
{
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

void main()
{
    uint pixel = gl_GlobalInvocationID.x;
    if (pixel >= pc.width * pc.height) {
        return;
    }
    uint x = pixel % pc.width;
    uint y = pixel / pc.width;
    bool left = x < pc.width / 2u;
    // The noise-free radiance (host.c's truth()).
    float truth = (left ? 0.2 : 1.0) * (0.5 + float(y) / float(pc.height));
    uint n = pc.pass_index == 0u ? pc.uniform_spp : sample_map[pixel];
    McdSums s = mcd_load(pixel);
    for (uint k = 0u; k < n; k++) {
        uint h = pcg(pixel * 7919u + pcg((pc.pass_index + 16u * pc.frame) * 1000003u + k));
        float u = float(h >> 8u) * (1.0 / 16777216.0);
        McdSample x;
        x.color = vec3(truth * 2.0 * u);   // mean truth, variance truth^2 / 3
        x.albedo = vec3(left ? 0.2 : 1.0);
        x.normal = vec3(0.0, 0.0, 1.0);
        x.depth = 1.0;
        x.position = vec3(float(pixel % pc.width), float(pixel / pc.width), 1.0);
        x.visibility = 0.0;
        mcd_add(s, x, vec3(0.0));
    }
    mcd_store(pixel, s);
}
