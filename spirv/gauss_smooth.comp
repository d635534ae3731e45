#version 460
// Gaussian map smoothing G_sigma (spec §0.5), column pass: from
// gauss_rows' row sums of one map (num) and of its weights (den), the sums
// over the rows |q.y - y| <= push.radius (clipped) weighted by gy(q.y - y);
// out = num / den, the g-weighted mean of the map over the valid pixels
// (spp_of >= 1) of the clipped window, g = gx gy; 0 if there is none.
// Used for hbar = G_1(h_opt) (§2.3 step 8), G_1.5 (§6.2 step 8) and the
// sampling map (§9.1). sigma <= 0: identity on valid pixels.
// Scalar twin: src/reference/gauss_smooth.rs.
#include "lib/common.glsl"
#include "lib/gauss.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::SmoothPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
    float sigma;
    uint count;
    uint pad1;
    uint pad2;
} push;

PLANE_IN(0, num)
PLANE_IN(1, den)
PLANE_OUT(2, out_p)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    int r = int(push.radius);
    int y0 = max(int(y) - r, 0), y1 = min(int(y) + r, int(push.height) - 1);
    GaussLine l = gauss_line(real(push.sigma), y0 - int(y));
    real n = real(0);
    real d = real(0);
    for (int qy = y0; qy <= y1; ++qy) {
        uint i = uint(qy) * push.width + x;
        n += l.g * real(num[i]);
        d += l.g * real(den[i]);
        gauss_step(l);
    }
    out_p[y * push.width + x] = d > real(0) ? float(n / d) : 0.0;
}
