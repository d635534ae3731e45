#version 460
// Gaussian map smoothing G_sigma (spec §0.5): the g-weighted mean of the map
// over the valid pixels (spp_of >= 1) of the clipped window |q - p|_inf <=
// push.radius (= ceil(3 sigma)); 0 if there is none. Used for hbar =
// G_1(h_opt) (§2.3 step 8) and the sampling map (§9.1). sigma <= 0: identity
// on valid pixels. Scalar twin: src/reference/gauss_smooth.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::SmoothPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
    float sigma;
    uint pad0;
    uint pad1;
    uint pad2;
} push;

PLANE_IN(0, map)
PLANE_IN(1, spp)
PLANE_OUT(2, out_p)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    ivec2 p = ivec2(x, y);
    int r = int(push.radius);
    real sigma = real(push.sigma);
    real num = real(0);
    real den = real(0);
    for (int qy = max(p.y - r, 0); qy <= min(p.y + r, int(push.height) - 1); ++qy) {
        for (int qx = max(p.x - r, 0); qx <= min(p.x + r, int(push.width) - 1); ++qx) {
            uint q = uint(qy) * push.width + uint(qx);
            if (spp_of(spp[q]) < 1.0) {
                continue;
            }
            ivec2 o = ivec2(qx, qy) - p;
            real g;
            if (sigma > real(0)) {
                // exp in float (GLSL has no double exp): far below tolerance.
                real r2 = real(o.x * o.x + o.y * o.y);
                g = real(exp(float(-r2 / (real(2) * sigma * sigma))));
            } else {
                g = (o.x == 0 && o.y == 0) ? real(1) : real(0);
            }
            num += g * real(map[q]);
            den += g;
        }
    }
    out_p[y * push.width + x] = den > real(0) ? float(num / den) : 0.0;
}
