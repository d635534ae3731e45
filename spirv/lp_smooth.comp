#version 460
// TEMPORAL-SMOOTH (ours, beyond §10.1): the LP temporal filter run over a
// sequence in frame order (F, P00f) and in reverse order (B, P00b), combined
// per pixel and channel as a two-filter smoother. With a = 1/P00 of each
// direction after its update (its estimate's information in units of one
// frame's) and y the method's output, which both directions hold once, each
// direction weighs w = a, but at most the other's a where the other is below
// SMOOTH_SHORT of the information it would hold had it met no change
// (SMOOTH-SHORT: push.full_forward, push.full_backward):
//   out = max((wf * F + wb * B - y) / (wf + wb - 1), 0)
// A pixel either direction passed through (P00 = 0: no state) keeps F.
// Scalar twin: src/reference/lp_smooth.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::TwoWayPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint pad0;
    float full_forward;
    float full_backward;
    uint pad1;
    uint pad2;
} push;

// mcdenoise::shared::SMOOTH_SHORT (tests/temporal.rs checks it).
#define SMOOTH_SHORT 0.9

PLANE_IN(0, yr)
PLANE_IN(1, yg)
PLANE_IN(2, yb)
PLANE_IN(3, fr)
PLANE_IN(4, fg)
PLANE_IN(5, fb)
PLANE_IN(6, pf)
PLANE_IN(7, br)
PLANE_IN(8, bg)
PLANE_IN(9, bb)
PLANE_IN(10, pb)
PLANE_OUT(11, out_r)
PLANE_OUT(12, out_g)
PLANE_OUT(13, out_b)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    real3 f = real3(fr[i], fg[i], fb[i]);
    real p0 = real(pf[i]);
    real p1 = real(pb[i]);
    // Also false for NaN.
    if (!(p0 > real(0) && p1 > real(0))) {
        out_r[i] = fr[i];
        out_g[i] = fg[i];
        out_b[i] = fb[i];
        return;
    }
    real af = real(1) / p0;
    real ab = real(1) / p1;
    real wf = ab < real(SMOOTH_SHORT) * real(push.full_backward) ? min(af, ab) : af;
    real wb = af < real(SMOOTH_SHORT) * real(push.full_forward) ? min(ab, af) : ab;
    real den = wf + wb - real(1);
    if (!(den > real(1e-6))) {
        out_r[i] = fr[i];
        out_g[i] = fg[i];
        out_b[i] = fb[i];
        return;
    }
    real3 b = real3(br[i], bg[i], bb[i]);
    real3 yy = real3(yr[i], yg[i], yb[i]);
    real3 o = max((wf * f + wb * b - yy) / den, real3(0));
    out_r[i] = float(o.x);
    out_g[i] = float(o.y);
    out_b[i] = float(o.z);
}
