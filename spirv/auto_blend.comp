#version 460
// `--method auto` (ours, AUTO-BLEND): the blend of three members from their
// smoothed maps (auto_score, then gauss_rows / gauss_smooth). Per member m,
// its error seen by the others (the three-cornered hat: if the members'
// errors were independent, the smoothed disagreements would be
// dis_ab = e_a + e_b), t_0 = (dis01 + dis02 - dis12) / 2 and so on, bounds
// its own estimate from below: s_m = max(score_m, t_m). Then
//   w_m = 1 / max(s_m, AUTO_SCORE_FLOOR),  k_m = s_m / score_m (1 if 0),
//   f_c = sum w_m f_m,c / sum w_m (as f_0 + sum w_m (f_m - f_0) / sum w_m),
//   E_c = (sum w_m sqrt(k_m E_m,c) / sum w_m)^2:
// each member's error estimate raised by the factor its score was, and
// combined as the RMS error of a weighted mean is bounded (Minkowski; equal
// when the members' errors are fully correlated, as errors computed from
// the same samples largely are). A member with a non-finite colour or error
// weighs 0; where all do, f = E = 0.
// Scalar twin: src/reference/auto_blend.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::AutoPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint pad;
} push;

PLANE_IN(0, c0r)
PLANE_IN(1, c0g)
PLANE_IN(2, c0b)
PLANE_IN(3, c1r)
PLANE_IN(4, c1g)
PLANE_IN(5, c1b)
PLANE_IN(6, c2r)
PLANE_IN(7, c2g)
PLANE_IN(8, c2b)
PLANE_IN(9, e0r)
PLANE_IN(10, e0g)
PLANE_IN(11, e0b)
PLANE_IN(12, e1r)
PLANE_IN(13, e1g)
PLANE_IN(14, e1b)
PLANE_IN(15, e2r)
PLANE_IN(16, e2g)
PLANE_IN(17, e2b)
PLANE_IN(18, score0)
PLANE_IN(19, score1)
PLANE_IN(20, score2)
PLANE_IN(21, dis01)
PLANE_IN(22, dis02)
PLANE_IN(23, dis12)
PLANE_OUT(24, out_r)
PLANE_OUT(25, out_g)
PLANE_OUT(26, out_b)
PLANE_OUT(27, err_r)
PLANE_OUT(28, err_g)
PLANE_OUT(29, err_b)

// mcdenoise::shared::AUTO_SCORE_FLOOR.
#define AUTO_SCORE_FLOOR 1e-12

bool finite3(float a, float b, float c) { return is_finite(a) && is_finite(b) && is_finite(c); }

// Member (f, e) with smoothed score s and hat estimate t: its weight (0
// when not ok), and adds w sqrt(k e) to root.
real weigh(inout real3 root, bool ok, real3 e, real s, real t)
{
    real m = max(s, t);
    real w = ok ? real(1) / max(m, real(AUTO_SCORE_FLOOR)) : real(0);
    real k = s > real(0) ? m / s : real(1);
    root += ok ? w * sqrt(k * max(e, real3(0))) : real3(0);
    return w;
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    real d01 = real(dis01[i]), d02 = real(dis02[i]), d12 = real(dis12[i]);
    real3 f0 = real3(c0r[i], c0g[i], c0b[i]);
    real3 f1 = real3(c1r[i], c1g[i], c1b[i]);
    real3 f2 = real3(c2r[i], c2g[i], c2b[i]);
    bool ok0 = finite3(c0r[i], c0g[i], c0b[i]) && finite3(e0r[i], e0g[i], e0b[i]) && is_finite(score0[i]);
    bool ok1 = finite3(c1r[i], c1g[i], c1b[i]) && finite3(e1r[i], e1g[i], e1b[i]) && is_finite(score1[i]);
    bool ok2 = finite3(c2r[i], c2g[i], c2b[i]) && finite3(e2r[i], e2g[i], e2b[i]) && is_finite(score2[i]);
    real3 root = real3(0);
    real w0 = weigh(root, ok0, real3(e0r[i], e0g[i], e0b[i]), real(score0[i]), real(0.5) * (d01 + d02 - d12));
    real w1 = weigh(root, ok1, real3(e1r[i], e1g[i], e1b[i]), real(score1[i]), real(0.5) * (d01 + d12 - d02));
    real w2 = weigh(root, ok2, real3(e2r[i], e2g[i], e2b[i]), real(score2[i]), real(0.5) * (d02 + d12 - d01));
    real ws = w0 + w1 + w2;
    real inv = ws > real(0) ? real(1) / ws : real(0);
    // The blend as the first usable member plus the weighted differences:
    // members that agree give their colour back exactly.
    real3 base = ok0 ? f0 : (ok1 ? f1 : (ok2 ? f2 : real3(0)));
    real3 num = real3(0);
    num += ok0 ? w0 * (f0 - base) : real3(0);
    num += ok1 ? w1 * (f1 - base) : real3(0);
    num += ok2 ? w2 * (f2 - base) : real3(0);
    num = base + num * inv;
    root *= inv;
    root *= root;
    out_r[i] = float(num.x);
    out_g[i] = float(num.y);
    out_b[i] = float(num.z);
    err_r[i] = float(root.x);
    err_g[i] = float(root.y);
    err_b[i] = float(root.z);
}
