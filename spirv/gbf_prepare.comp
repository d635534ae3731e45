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
    float second_below;  // gbf_filter: GBF-SECOND's pass when > 0
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

// Register blocking: an invocation prepares GP_ROWS consecutive pixels of a
// column. Each row of their joint column window (GP_ROWS + 10 tall) is
// loaded once and added to every pixel whose window holds it (lavapipe pays
// per lane and float loaded); each pixel's weights step only inside its own
// window, so its sums take the same rows, weights and order as one
// invocation per pixel.
#extension GL_EXT_control_flow_attributes : require
#define GP_ROWS 8

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y0 = (push.row0 + gl_GlobalInvocationID.y) * uint(GP_ROWS);
    if (x >= push.width || y0 >= push.height) {
        return;
    }
    int last = int(push.height) - 1;
    int v0 = max(int(y0) - GBF_SMOOTH_RADIUS, 0);
    int v1 = min(int(y0) + GP_ROWS - 1 + GBF_SMOOTH_RADIUS, last);
    GaussLine l[GP_ROWS];
    int lo[GP_ROWS], hi[GP_ROWS];  // each pixel's clipped window
    real3 na[GP_ROWS], nb[GP_ROWS];
    real d[GP_ROWS];
    [[unroll]] for (int p = 0; p < GP_ROWS; ++p) {
        int y = int(y0) + p;
        lo[p] = max(y - GBF_SMOOTH_RADIUS, 0);
        hi[p] = min(y + GBF_SMOOTH_RADIUS, last);
        l[p] = gauss_line(real(GBF_SIGMA), lo[p] - y);
        na[p] = real3(0);
        nb[p] = real3(0);
        d[p] = real(0);
    }
    for (int v = v0; v <= v1; ++v) {
        uint q = uint(v) * push.width + x;
        real3 ra = real3(sxx[q], sxy[q], sxz[q]);
        real3 rb = real3(syy[q], syz[q], szz[q]);
        real rd = real(den[q]);
        [[unroll]] for (int p = 0; p < GP_ROWS; ++p) {
            // A select, not a zero weight (a row outside the window may
            // hold anything; adding +0 leaves a sum as it is).
            bool in_ = v >= lo[p] && v <= hi[p];
            na[p] += in_ ? l[p].g * ra : real3(0);
            nb[p] += in_ ? l[p].g * rb : real3(0);
            d[p] += in_ ? l[p].g * rd : real(0);
            if (in_) {
                gauss_step(l[p]);
            }
        }
    }
    [[unroll]] for (int p = 0; p < GP_ROWS; ++p) {
        uint y = y0 + uint(p);
        if (y >= push.height) {
            continue;
        }
        real3 a = d[p] > real(0) ? na[p] / d[p] : real3(0);
        real3 b = d[p] > real(0) ? nb[p] / d[p] : real3(0);
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
}
