#version 460
// Row pass of the separable Gaussian map smoothing G_sigma (spec §0.5). Per
// pixel (x, y) and each map (push.count: 1, the first only, or all 6): the sum over
// the valid pixels q (spp_of >= 1) of row y with |q.x - x| <= push.radius
// (clipped) of gx(q.x - x) map(q), and in `den` the sum of gx over them.
// A column pass (gauss_smooth.comp, gbf_prepare.comp) sums both with gy:
// their quotient is the 2-D mean with weights g = gx gy over the valid
// pixels of the window, at 2(2r+1) taps per pixel instead of (2r+1)^2.
// Scalar twin: src/reference/gauss_rows.rs.
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

PLANE_IN(0, m0)
PLANE_IN(1, m1)
PLANE_IN(2, m2)
PLANE_IN(3, m3)
PLANE_IN(4, m4)
PLANE_IN(5, m5)
PLANE_IN(6, spp)
PLANE_OUT(7, s0)
PLANE_OUT(8, s1)
PLANE_OUT(9, s2)
PLANE_OUT(10, s3)
PLANE_OUT(11, s4)
PLANE_OUT(12, s5)
PLANE_OUT(13, den)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    int r = int(push.radius);
    int x0 = max(int(x) - r, 0), x1 = min(int(x) + r, int(push.width) - 1);
    GaussLine l = gauss_line(real(push.sigma), x0 - int(x));
    real4 a = real4(0);
    real2 b = real2(0);
    real d = real(0);
    uint row = y * push.width;
    // One tap loop per plane count, the other's range empty: lavapipe runs
    // both sides of a branch (an `if (push.count > 1u)` read and summed the
    // five other planes in a one-plane dispatch too) but leaves a loop
    // whose lanes are all done after one idle pass. The sums are the same.
    bool many = push.count > 1u;
    for (int qx = x0; qx <= (many ? x0 - 1 : x1); ++qx) {
        uint i = row + uint(qx);
        if (spp_of(spp[i]) >= 1.0) {
            a.x += l.g * real(m0[i]);
            d += l.g;
        }
        gauss_step(l);
    }
    for (int qx = x0; qx <= (many ? x1 : x0 - 1); ++qx) {
        uint i = row + uint(qx);
        if (spp_of(spp[i]) >= 1.0) {
            a.x += l.g * real(m0[i]);
            a.yzw += l.g * real3(m1[i], m2[i], m3[i]);
            b += l.g * real2(m4[i], m5[i]);
            d += l.g;
        }
        gauss_step(l);
    }
    uint o = row + x;
    s0[o] = float(a.x);
    if (push.count > 1u) {
        s1[o] = float(a.y);
        s2[o] = float(a.z);
        s3[o] = float(a.w);
        s4[o] = float(b.x);
        s5[o] = float(b.y);
    }
    den[o] = float(d);
}
