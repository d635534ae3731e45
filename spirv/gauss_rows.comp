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

// Register blocking: an invocation sums GR_PX consecutive pixels of a row.
// Each tap of their joint window (GR_PX + 2r wide) is loaded once and added
// to every pixel whose window holds it (lavapipe pays per lane and float
// loaded: (GR_PX + 2r) / GR_PX taps per pixel instead of 2r + 1). Each
// pixel's weights step only inside its own window, so every pixel's sum
// takes the same taps, weights and order as one invocation per pixel.
#extension GL_EXT_control_flow_attributes : require
#define GR_PX 8

void main()
{
    uint x0 = gl_GlobalInvocationID.x * uint(GR_PX);
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x0 >= push.width || y >= push.height) {
        return;
    }
    int r = int(push.radius);
    int last = int(push.width) - 1;
    int u0 = max(int(x0) - r, 0), u1 = min(int(x0) + GR_PX - 1 + r, last);
    GaussLine l[GR_PX];
    int lo[GR_PX], hi[GR_PX];  // each pixel's clipped window
    real4 a[GR_PX];
    real2 b[GR_PX];
    real d[GR_PX];
    [[unroll]] for (int p = 0; p < GR_PX; ++p) {
        int x = int(x0) + p;
        lo[p] = max(x - r, 0);
        hi[p] = min(x + r, last);
        l[p] = gauss_line(real(push.sigma), lo[p] - x);
        a[p] = real4(0);
        b[p] = real2(0);
        d[p] = real(0);
    }
    uint row = y * push.width;
    // One tap loop per plane count, the other's range empty: lavapipe runs
    // both sides of a branch (an `if (push.count > 1u)` read and summed the
    // five other planes in a one-plane dispatch too) but leaves a loop
    // whose lanes are all done after one idle pass. The sums are the same.
    bool many = push.count > 1u;
    for (int u = u0; u <= (many ? u0 - 1 : u1); ++u) {
        uint i = row + uint(u);
        bool valid = spp_of(spp[i]) >= 1.0;
        real v0 = real(m0[i]);
        [[unroll]] for (int p = 0; p < GR_PX; ++p) {
            bool in_ = u >= lo[p] && u <= hi[p];
            // A select, not a zero weight: a tap outside the window or
            // invalid may hold anything (0 * inf is NaN), and adding +0
            // leaves a sum as it is.
            bool use = in_ && valid;
            a[p].x += use ? l[p].g * v0 : real(0);
            d[p] += use ? l[p].g : real(0);
            if (in_) {
                gauss_step(l[p]);
            }
        }
    }
    for (int u = u0; u <= (many ? u1 : u0 - 1); ++u) {
        uint i = row + uint(u);
        bool valid = spp_of(spp[i]) >= 1.0;
        real4 va = real4(m0[i], m1[i], m2[i], m3[i]);
        real2 vb = real2(m4[i], m5[i]);
        [[unroll]] for (int p = 0; p < GR_PX; ++p) {
            bool in_ = u >= lo[p] && u <= hi[p];
            bool use = in_ && valid;
            a[p] += use ? l[p].g * va : real4(0);
            b[p] += use ? l[p].g * vb : real2(0);
            d[p] += use ? l[p].g : real(0);
            if (in_) {
                gauss_step(l[p]);
            }
        }
    }
    [[unroll]] for (int p = 0; p < GR_PX; ++p) {
        if (x0 + uint(p) >= push.width) {
            continue;
        }
        uint o = row + x0 + uint(p);
        s0[o] = float(a[p].x);
        if (push.count > 1u) {
            s1[o] = float(a[p].y);
            s2[o] = float(a[p].z);
            s3[o] = float(a[p].w);
            s4[o] = float(b[p].x);
            s5[o] = float(b[p].y);
        }
        den[o] = float(d[p]);
    }
}
