#version 460
// G-buffer prefilter (spec §6) step 1 per pixel: S = G_1.5(position
// covariance) over the valid pixels of the clipped 11x11 window (all six
// entries in one pass), S-PSD regularisation with the pixel's position, and
// the inverse S~^-1 (six planes XX XY XZ YY YZ ZZ) that gbf_sure and
// gbf_filter read for every neighbour.
// Scalar twin: src/reference/gbf_prepare.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::GbfPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint count;
} push;

PLANE_IN(0, cxx)
PLANE_IN(1, cxy)
PLANE_IN(2, cxz)
PLANE_IN(3, cyy)
PLANE_IN(4, cyz)
PLANE_IN(5, czz)
PLANE_IN(6, px)
PLANE_IN(7, py)
PLANE_IN(8, pz)
PLANE_IN(9, spp)
PLANE_OUT(10, ixx)
PLANE_OUT(11, ixy)
PLANE_OUT(12, ixz)
PLANE_OUT(13, iyy)
PLANE_OUT(14, iyz)
PLANE_OUT(15, izz)

#include "lib/gbf.glsl"

#define GBF_SIGMA 1.5
#define GBF_SMOOTH_RADIUS 5

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    ivec2 p = ivec2(x, y);
    int x0 = max(p.x - GBF_SMOOTH_RADIUS, 0), x1 = min(p.x + GBF_SMOOTH_RADIUS, int(push.width) - 1);
    // Weights as in gauss_smooth.comp: gy(dy) gx(dx), gx by the recurrence
    // gx(d+1) = gx(d) q(d), q(d+1) = q(d) c (exp in float).
    real k = real(1) / (real(2) * real(GBF_SIGMA) * real(GBF_SIGMA));
    real c = real(exp(float(-real(2) * k)));
    real d0 = real(x0 - p.x);
    real gx0 = real(exp(float(-d0 * d0 * k)));
    real q0 = real(exp(float(-(real(2) * d0 + real(1)) * k)));
    real3 na = real3(0);
    real3 nb = real3(0);
    real den = real(0);
    for (int qy = max(p.y - GBF_SMOOTH_RADIUS, 0); qy <= min(p.y + GBF_SMOOTH_RADIUS, int(push.height) - 1); ++qy) {
        real dy = real(qy - p.y);
        real gy = real(exp(float(-dy * dy * k)));
        real gx = gx0;
        real q = q0;
        for (int qx = x0; qx <= x1; ++qx) {
            uint i = uint(qy) * push.width + uint(qx);
            if (spp_of(spp[i]) >= 1.0) {
                real g = gx * gy;
                na += g * real3(cxx[i], cxy[i], cxz[i]);
                nb += g * real3(cyy[i], cyz[i], czz[i]);
                den += g;
            }
            gx *= q;
            q *= c;
        }
    }
    real3 a = den > real(0) ? na / den : real3(0);
    real3 b = den > real(0) ? nb / den : real3(0);
    uint i = y * push.width + x;
    real3 ia, ib;
    gbf_regularised_inverse(a, b, real3(px[i], py[i], pz[i]), ia, ib);
    ixx[i] = float(ia.x);
    ixy[i] = float(ia.y);
    ixz[i] = float(ia.z);
    iyy[i] = float(ib.x);
    iyz[i] = float(ib.y);
    izz[i] = float(ib.z);
}
