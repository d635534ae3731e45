#version 460
// `--method auto` (ours, AUTO-BLEND): how far each pair of its members
// disagrees, in the units of rMSE (spec §0.3):
//   dis_ab = sum_c (f_a,c - f_b,c)^2 / (fbar_c^2 + 0.01)
// with fbar the mean of the push.members (3 or 4) members' colours. The
// pairs are in the order (0,1), (0,2), ..., (0,n-1), (1,2), ...; with three
// members the bindings of member 3 and of maps 3-5 are not read or
// written. gauss_rows / gauss_smooth smooth the maps; auto_blend reads
// them. A non-finite value becomes AUTO_SCORE_MAX.
// Scalar twin: src/reference/auto_dis.rs.
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

PLANE_IN(0, c0r)
PLANE_IN(1, c0g)
PLANE_IN(2, c0b)
PLANE_IN(3, c1r)
PLANE_IN(4, c1g)
PLANE_IN(5, c1b)
PLANE_IN(6, c2r)
PLANE_IN(7, c2g)
PLANE_IN(8, c2b)
PLANE_IN(9, c3r)
PLANE_IN(10, c3g)
PLANE_IN(11, c3b)
PLANE_OUT(12, dis0)
PLANE_OUT(13, dis1)
PLANE_OUT(14, dis2)
PLANE_OUT(15, dis3)
PLANE_OUT(16, dis4)
PLANE_OUT(17, dis5)

// mcdenoise::shared::AUTO_SCORE_MAX.
#define AUTO_SCORE_MAX 1e30

float rel(real3 d, real3 fbar)
{
    real3 t = d * d / (fbar * fbar + real3(0.01));
    float s = float(t.x + t.y + t.z);
    return is_finite(s) ? s : AUTO_SCORE_MAX;
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
    if (push.members == 4u) {
        real3 f3 = real3(c3r[i], c3g[i], c3b[i]);
        real3 fbar = (f0 + f1 + f2 + f3) / real(4);
        dis0[i] = rel(f0 - f1, fbar);
        dis1[i] = rel(f0 - f2, fbar);
        dis2[i] = rel(f0 - f3, fbar);
        dis3[i] = rel(f1 - f2, fbar);
        dis4[i] = rel(f1 - f3, fbar);
        dis5[i] = rel(f2 - f3, fbar);
    } else {
        real3 fbar = (f0 + f1 + f2) / real(3);
        dis0[i] = rel(f0 - f1, fbar);
        dis1[i] = rel(f0 - f2, fbar);
        dis2[i] = rel(f1 - f2, fbar);
    }
}
