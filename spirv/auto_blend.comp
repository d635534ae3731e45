#version 460
// `--method auto` (ours, AUTO-BLEND): the blend of its members from their
// smoothed maps (auto_score, auto_dis, then gauss_rows / gauss_smooth), one
// dispatch per member in order, the sums carried between dispatches in the
// acc planes. For member m of n, its error seen by the others (the n-cornered
// hat: if the members' errors were independent, the smoothed disagreements
// would be dis_ab = e_a + e_b, and least squares gives)
//   t_m = (sum_{b != m} dis_mb - D / (n - 1)) / (n - 2),  D = sum of all dis,
// (for three members t_0 = (dis01 + dis02 - dis12) / 2) bounds its own
// estimate from below: s_m = max(score_m, t_m). Then
//   w_m = 1 / max(s_m, AUTO_SCORE_FLOOR),  k_m = s_m / score_m (1 if 0),
//   f_c = sum w_m f_m,c / sum w_m (as base + sum w_m (f_m - base) / sum w_m,
//         base the first usable member's colour),
//   E_c = (sum w_m sqrt(k_m E_m,c) / sum w_m)^2:
// each member's error estimate raised by the factor its score was, and
// combined as the RMS error of a weighted mean is bounded (Minkowski; equal
// when the members' errors are fully correlated, as errors computed from
// the same samples largely are). A member with a non-finite colour or error
// weighs 0; where all do, f = E = 0. The first dispatch (member 0) reads no
// sums; the last (push.last) writes the outputs instead of the sums.
// Scalar twin: src/reference/auto_blend.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::AutoPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint members;
    uint member;
    uint last;
    uint pad0;
    uint pad1;
} push;

PLANE_IN(0, cr)
PLANE_IN(1, cg)
PLANE_IN(2, cb)
PLANE_IN(3, er)
PLANE_IN(4, eg)
PLANE_IN(5, eb)
PLANE_IN(6, score)
PLANE_IN(7, dis0)
PLANE_IN(8, dis1)
PLANE_IN(9, dis2)
PLANE_IN(10, dis3)
PLANE_IN(11, dis4)
PLANE_IN(12, dis5)
PLANE_OUT(13, base_r)
PLANE_OUT(14, base_g)
PLANE_OUT(15, base_b)
PLANE_OUT(16, num_r)
PLANE_OUT(17, num_g)
PLANE_OUT(18, num_b)
PLANE_OUT(19, root_r)
PLANE_OUT(20, root_g)
PLANE_OUT(21, root_b)
PLANE_OUT(22, wsum)
PLANE_OUT(23, out_r)
PLANE_OUT(24, out_g)
PLANE_OUT(25, out_b)
PLANE_OUT(26, err_r)
PLANE_OUT(27, err_g)
PLANE_OUT(28, err_b)

// mcdenoise::shared::AUTO_SCORE_FLOOR.
#define AUTO_SCORE_FLOOR 1e-12

bool finite3(float a, float b, float c) { return is_finite(a) && is_finite(b) && is_finite(c); }

// The pairs of three and of four members, in the maps' order.
const uint PA3[3] = uint[3](0u, 0u, 1u);
const uint PB3[3] = uint[3](1u, 2u, 2u);
const uint PA4[6] = uint[6](0u, 0u, 0u, 1u, 1u, 2u);
const uint PB4[6] = uint[6](1u, 2u, 3u, 2u, 3u, 3u);

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    uint n = push.members, m = push.member;
    bool four = n == 4u;
    real d[6];
    d[0] = real(dis0[i]);
    d[1] = real(dis1[i]);
    d[2] = real(dis2[i]);
    d[3] = four ? real(dis3[i]) : real(0);
    d[4] = four ? real(dis4[i]) : real(0);
    d[5] = four ? real(dis5[i]) : real(0);
    uint pairs = four ? 6u : 3u;
    real total = real(0), mine = real(0);
    for (uint k = 0u; k < pairs; k++) {
        uint a = four ? PA4[k] : PA3[k];
        uint b = four ? PB4[k] : PB3[k];
        total += d[k];
        mine += (a == m || b == m) ? d[k] : real(0);
    }
    real t = (mine - total / real(n - 1u)) / real(n - 2u);

    bool ok = finite3(cr[i], cg[i], cb[i]) && finite3(er[i], eg[i], eb[i]) && is_finite(score[i]);
    real s = real(score[i]);
    real mx = max(s, t);
    real w = ok ? real(1) / max(mx, real(AUTO_SCORE_FLOOR)) : real(0);
    real k = s > real(0) ? mx / s : real(1);
    real3 f = real3(cr[i], cg[i], cb[i]);

    bool first = m == 0u;
    real ws = first ? real(0) : real(wsum[i]);
    real3 base = first ? real3(0) : real3(base_r[i], base_g[i], base_b[i]);
    real3 num = first ? real3(0) : real3(num_r[i], num_g[i], num_b[i]);
    real3 root = first ? real3(0) : real3(root_r[i], root_g[i], root_b[i]);
    if (ok && ws == real(0)) {
        base = f;
    }
    num += ok ? w * (f - base) : real3(0);
    root += ok ? w * sqrt(k * max(real3(er[i], eg[i], eb[i]), real3(0))) : real3(0);
    ws += w;
    if (push.last != 0u) {
        real inv = ws > real(0) ? real(1) / ws : real(0);
        // Members that agree give their colour back exactly.
        real3 o = base + num * inv;
        root *= inv;
        root *= root;
        out_r[i] = float(o.x);
        out_g[i] = float(o.y);
        out_b[i] = float(o.z);
        err_r[i] = float(root.x);
        err_g[i] = float(root.y);
        err_b[i] = float(root.z);
    } else {
        base_r[i] = float(base.x);
        base_g[i] = float(base.y);
        base_b[i] = float(base.z);
        num_r[i] = float(num.x);
        num_g[i] = float(num.y);
        num_b[i] = float(num.z);
        root_r[i] = float(root.x);
        root_g[i] = float(root.y);
        root_b[i] = float(root.z);
        wsum[i] = float(ws);
    }
}
