#version 460
// Accumulation sums of one scalar channel -> mean and variance of the mean.
// input-format.md: variance of the mean = unbiased sample variance / n.
// Cancellation guard: sum(x^2) - n*mean^2 < 0 (float rounding) -> 0.
// n < 1: mean 0, variance 0 (invalid pixel, spec §0.2).
// n < 2: variance 0; sanitation fills it from the neighbours (spec §0.4 step 3).
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
// origin: the channel was accumulated relative to it (AccumLayout's
// position_origin, 0 elsewhere); the mean adds it back, the variance is
// shift-invariant and keeps the precision the shifted sums have.
layout(push_constant) uniform Push { uint width; uint height; uint row0; float origin; } push;

PLANE_IN(0, sum_in)
PLANE_IN(1, sumsq_in)
PLANE_IN(2, count_in)
PLANE_OUT(3, mean_out)
PLANE_OUT(4, var_out)

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) return;
    uint i = y * push.width + x;
    real n = real(spp_of(count_in[i]));
    real mean = real(0.0);
    real var = real(0.0);
    if (n >= real(1.0)) {
        real s = real(sum_in[i]);
        mean = s / n;
        if (n >= real(2.0)) {
            real ss = max(real(sumsq_in[i]) - s * mean, real(0.0));
            var = ss / (n - real(1.0)) / n;
        }
    }
    mean_out[i] = n >= real(1.0) ? float(real(push.origin) + mean) : 0.0;
    var_out[i] = float(var);
}
