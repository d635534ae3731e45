#version 460
// `--method auto` (ours, AUTO-BLEND): one member's score map, from its
// colour f and error estimate E (one dispatch per member):
//   score = sum_c max(E_c, 0) / (f_c^2 + 0.01)
// the member's own relative error in the units of rMSE (spec §0.3).
// gauss_rows / gauss_smooth smooth it; auto_blend reads it. A non-finite
// value becomes AUTO_SCORE_MAX (the member then weighs almost nothing).
// Scalar twin: src/reference/auto_score.rs.
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
PLANE_OUT(6, score)

// mcdenoise::shared::AUTO_SCORE_MAX.
#define AUTO_SCORE_MAX 1e30

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    real3 f = real3(cr[i], cg[i], cb[i]);
    real3 t = max(real3(er[i], eg[i], eb[i]), real3(0)) / (f * f + real3(0.01));
    float s = float(t.x + t.y + t.z);
    score[i] = is_finite(s) ? s : AUTO_SCORE_MAX;
}
