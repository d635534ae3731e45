#version 460
// G-buffer prefilter (spec §6) step 1 per pixel: S = G_1.5(position
// covariance) over the valid pixels of the clipped 11x11 window, as the
// column pass over gauss_rows' row sums of the six entries (and of their
// weights, den), S-PSD regularisation with the pixel's position, and the
// inverse S~^-1 (six planes XX XY XZ YY YZ ZZ) that gbf_sure and gbf_filter
// read for every neighbour.
// Scalar twin: src/reference/gbf_prepare.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::GbfPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint base;      // gbf_pack, gbf_filter: first row of the packed bindings
} push;

PLANE_IN(0, sxx)
PLANE_IN(1, sxy)
PLANE_IN(2, sxz)
PLANE_IN(3, syy)
PLANE_IN(4, syz)
PLANE_IN(5, szz)
PLANE_IN(6, den)
PLANE_IN(7, px)
PLANE_IN(8, py)
PLANE_IN(9, pz)
PLANE_OUT(10, ixx)
PLANE_OUT(11, ixy)
PLANE_OUT(12, ixz)
PLANE_OUT(13, iyy)
PLANE_OUT(14, iyz)
PLANE_OUT(15, izz)

#include "lib/gbf.glsl"
#include "lib/gauss.glsl"

#define GBF_SIGMA 1.5
#define GBF_SMOOTH_RADIUS 5

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    int y0 = max(int(y) - GBF_SMOOTH_RADIUS, 0);
    int y1 = min(int(y) + GBF_SMOOTH_RADIUS, int(push.height) - 1);
    GaussLine l = gauss_line(real(GBF_SIGMA), y0 - int(y));
    real3 na = real3(0);
    real3 nb = real3(0);
    real d = real(0);
    for (int qy = y0; qy <= y1; ++qy) {
        uint q = uint(qy) * push.width + x;
        na += l.g * real3(sxx[q], sxy[q], sxz[q]);
        nb += l.g * real3(syy[q], syz[q], szz[q]);
        d += l.g * real(den[q]);
        gauss_step(l);
    }
    real3 a = d > real(0) ? na / d : real3(0);
    real3 b = d > real(0) ? nb / d : real3(0);
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
