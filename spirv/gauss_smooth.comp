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
    int x0 = max(p.x - r, 0), x1 = min(p.x + r, int(push.width) - 1);
    if (sigma > real(0)) {
        // g(o) = gy(o.y) gx(o.x); along a row gx follows the recurrence
        // gx(d+1) = gx(d) q(d), q(d+1) = q(d) c with q(d) = exp(-(2d+1)k),
        // c = exp(-2k), k = 1/(2 sigma^2): three exps per row instead of one
        // per tap. exp in float (GLSL has no double exp): far below tolerance.
        real k = real(1) / (real(2) * sigma * sigma);
        real c = real(exp(float(-real(2) * k)));
        real d0 = real(x0 - p.x);
        real gx0 = real(exp(float(-d0 * d0 * k)));
        real q0 = real(exp(float(-(real(2) * d0 + real(1)) * k)));
        for (int qy = max(p.y - r, 0); qy <= min(p.y + r, int(push.height) - 1); ++qy) {
            real dy = real(qy - p.y);
            real gy = real(exp(float(-dy * dy * k)));
            real gx = gx0;
            real q = q0;
            for (int qx = x0; qx <= x1; ++qx) {
                uint i = uint(qy) * push.width + uint(qx);
                if (spp_of(spp[i]) >= 1.0) {
                    real g = gx * gy;
                    num += g * real(map[i]);
                    den += g;
                }
                gx *= q;
                q *= c;
            }
        }
    } else {
        uint i = y * push.width + x;
        if (spp_of(spp[i]) >= 1.0) {
            num = real(map[i]);
            den = real(1);
        }
    }
    out_p[y * push.width + x] = den > real(0) ? float(num / den) : 0.0;
}
