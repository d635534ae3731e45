#version 460
// `--method auto` (ours, AUTO-BLEND): the six maps the blend smooths, from
// its three members' colours f_m and error estimates E_m:
//   score_m = sum_c max(E_m,c, 0) / (f_m,c^2 + 0.01)       (m = 0, 1, 2)
//   dis_ab  = sum_c (f_a,c - f_b,c)^2 / (fbar_c^2 + 0.01)  (01, 02, 12)
// with fbar the members' mean: each member's own relative error, and how
// far each pair of members disagrees, in the units of rMSE (spec §0.3).
// gauss_rows / gauss_smooth smooth them; auto_blend reads them. A
// non-finite value becomes AUTO_SCORE_MAX (its member then weighs almost
// nothing). Scalar twin: src/reference/auto_score.rs.
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
PLANE_OUT(18, score0)
PLANE_OUT(19, score1)
PLANE_OUT(20, score2)
PLANE_OUT(21, dis01)
PLANE_OUT(22, dis02)
PLANE_OUT(23, dis12)

// mcdenoise::shared::AUTO_SCORE_MAX.
#define AUTO_SCORE_MAX 1e30

float finite_or_max(real v)
{
    float s = float(v);
    return is_finite(s) ? s : AUTO_SCORE_MAX;
}

real rel_sum(real3 num, real3 f)
{
    real3 t = num / (f * f + real3(0.01));
    return t.x + t.y + t.z;
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    real3 f0 = real3(c0r[i], c0g[i], c0b[i]);
    real3 f1 = real3(c1r[i], c1g[i], c1b[i]);
    real3 f2 = real3(c2r[i], c2g[i], c2b[i]);
    real3 zero = real3(0);
    score0[i] = finite_or_max(rel_sum(max(real3(e0r[i], e0g[i], e0b[i]), zero), f0));
    score1[i] = finite_or_max(rel_sum(max(real3(e1r[i], e1g[i], e1b[i]), zero), f1));
    score2[i] = finite_or_max(rel_sum(max(real3(e2r[i], e2g[i], e2b[i]), zero), f2));
    real3 fbar = (f0 + f1 + f2) / real(3);
    real3 d01 = f0 - f1, d02 = f0 - f2, d12 = f1 - f2;
    dis01[i] = finite_or_max(rel_sum(d01 * d01, fbar));
    dis02[i] = finite_or_max(rel_sum(d02 * d02, fbar));
    dis12[i] = finite_or_max(rel_sum(d12 * d12, fbar));
}
