#version 460
// Per-pixel sampling priority r_i (spec §9.1, REL-CHANNELS):
//   ΔMSE[ch] = max(E[ch], 0) n^(-4/(d+4))   (skipped: ΔMSE = max(E, 0) when
//                                           push.flags has SAMPLE_E_IS_DMSE, LP)
//   r = (1/3) sum_ch ΔMSE[ch] / (f̂[ch]^2 + eps)
// d is the d plane clamped to >= 0, or floor(clamp(value, 0, 2^20)) mod 16
// with SAMPLE_D_KFLAGS (WLR's kflags = k + 16 flags). Any non-finite input of a
// valid pixel (d only when used) gives r = 0 (the sanitise rule of §9.1 for non-finite r), as
// does a non-finite result. Invalid pixels (n = 0) get 0 here; the reduction
// (sample_reduce) gives them the global max. n^(-4/(d+4)) is evaluated with
// float pow (GLSL has no double pow). Scalar twin: src/reference/sample_priority.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::SamplePriorityPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint flags;
    float eps;
    uint pad0;
    uint pad1;
    uint pad2;
} push;

// Bits of push.flags; mirror mcdenoise::shared::SAMPLE_E_IS_DMSE / SAMPLE_D_KFLAGS.
#define SAMPLE_E_IS_DMSE 1u
#define SAMPLE_D_KFLAGS 2u

PLANE_IN(0, e0)
PLANE_IN(1, e1)
PLANE_IN(2, e2)
PLANE_IN(3, d_p)
PLANE_IN(4, f0)
PLANE_IN(5, f1)
PLANE_IN(6, f2)
PLANE_IN(7, spp)
PLANE_OUT(8, out_p)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    float n = spp_of(spp[i]);
    float dv = d_p[i];
    float e[3] = float[3](e0[i], e1[i], e2[i]);
    float f[3] = float[3](f0[i], f1[i], f2[i]);
    // d is not read when E is already ΔMSE (LP may pass any plane).
    bool finite = (push.flags & SAMPLE_E_IS_DMSE) != 0u || is_finite(dv);
    for (int c = 0; c < 3; ++c) {
        finite = finite && is_finite(e[c]) && is_finite(f[c]);
    }
    if (n < 1.0 || !finite) {
        out_p[i] = 0.0;
        return;
    }
    real rate = real(1);
    if ((push.flags & SAMPLE_E_IS_DMSE) == 0u) {
        float d = (push.flags & SAMPLE_D_KFLAGS) != 0u ? float(uint(clamp(dv, 0.0, 1048576.0)) % 16u)
                                                      : max(dv, 0.0);
        rate = real(pow(n, -4.0 / (d + 4.0)));
    }
    real eps = real(push.eps);
    real sum = real(0);
    for (int c = 0; c < 3; ++c) {
        real fc = real(f[c]);
        sum += real(max(e[c], 0.0)) * rate / (fc * fc + eps);
    }
    float r = float(sum / real(3));
    out_p[i] = is_finite(r) ? r : 0.0;
}
