#version 460
// The device's arithmetic peak (issue #13's roofline): every invocation runs
// push.iterations rounds of eight independent real4 fused multiply-adds,
// acc <- acc * m + c (64 flops a round), and writes the sum of its
// accumulators, so nothing is optimised away. Eight chains hide the FMA
// latency; no memory traffic but one store. Scalar twin:
// src/reference/peak_fma.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::PeakPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint iterations;
} push;

PLANE_OUT(0, out_p)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    real s = real(i % 1024u) * real(1.0 / 1024.0);
    real4 m = real4(0.9990234375);
    real4 c = real4(0.0009765625);
    real4 a0 = real4(s, s + 0.125, s + 0.25, s + 0.375);
    real4 a1 = a0 + real4(0.5);
    real4 a2 = a0 * real4(0.5);
    real4 a3 = a1 * real4(0.5);
    real4 a4 = a0 + real4(0.0625);
    real4 a5 = a1 + real4(0.0625);
    real4 a6 = a2 + real4(0.0625);
    real4 a7 = a3 + real4(0.0625);
    for (uint k = 0u; k < push.iterations; ++k) {
        a0 = fma(a0, m, c);
        a1 = fma(a1, m, c);
        a2 = fma(a2, m, c);
        a3 = fma(a3, m, c);
        a4 = fma(a4, m, c);
        a5 = fma(a5, m, c);
        a6 = fma(a6, m, c);
        a7 = fma(a7, m, c);
    }
    real4 t = ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7));
    out_p[i] = float((t.x + t.y) + (t.z + t.w));
}
