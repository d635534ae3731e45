#version 460
// Spec §10.1, the LP temporal filter, one frame: per pixel a recursive
// least-squares fit of (1, tau) -> y over the frames with forgetting factor
// lambda and the time origin at the current frame (TIME-ORIGIN; with
// TEMPORAL-PRIOR's reset the slope stays 0: a mean with forgetting), the state
// reprojected from the previous frame (SEARCH-7, TEMPORAL-GATE, RESET,
// RESET-NOISE, TEMPORAL-INFLATE: lib/temporal.glsl). Output beta[ch][0], clamped to >= 0
// (§0.4 step 5); a pixel passed through keeps its colour and no state.
// `prev` is read, `next` written: the host copies next to prev after the
// frame. Scalar twin: src/reference/lp_temporal.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::TemporalPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint flags;
    float lambda;
    float p00;
    float p11;
    float error_scale;
    float inflate_scale;
} push;

PLANE_IN(0, yr)
PLANE_IN(1, yg)
PLANE_IN(2, yb)
PLANE_IN(3, px)
PLANE_IN(4, py)
PLANE_IN(5, pz)
PLANE_IN(6, vx)
PLANE_IN(7, vy)
PLANE_IN(8, vz)
PLANE_IN(9, depth)
PLANE_IN(10, spp)
PLANE_IN(11, er)
PLANE_IN(12, eg)
PLANE_IN(13, eb)
PLANE_IN(14, prev)
PLANE_IN(15, mx)
PLANE_IN(16, my)
PLANE_OUT(17, next)
PLANE_OUT(18, out_r)
PLANE_OUT(19, out_g)
PLANE_OUT(20, out_b)
PLANE_OUT(21, source)

#include "lib/temporal.glsl"

// mcdenoise::shared: TEMPORAL_SOURCE_RESET, TEMPORAL_SOURCE_NONE.
#define SOURCE_RESET -1.0
#define SOURCE_NONE -2.0

void store(uint i, uint n, real2 b[3], real3 p, vec3 w, float valid)
{
    for (int c = 0; c < 3; ++c) {
        next[(2 * c) * n + i] = float(b[c].x);
        next[(2 * c + 1) * n + i] = float(b[c].y);
    }
    next[6 * n + i] = float(p.x);
    next[7 * n + i] = float(p.y);
    next[8 * n + i] = float(p.z);
    next[9 * n + i] = w.x;
    next[10 * n + i] = w.y;
    next[11 * n + i] = w.z;
    next[12 * n + i] = valid;
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint n = push.width * push.height;
    uint i = y * push.width + x;
    real2 b[3];
    real3 p;
    int off;
    int step = temporal_step(x, y, b, p, off);
    if (step == STEP_PASS) {
        store(i, n, b, real3(0), vec3(0), 0.0);
        out_r[i] = yr[i];
        out_g[i] = yg[i];
        out_b[i] = yb[i];
        source[i] = SOURCE_NONE;
        return;
    }
    store(i, n, b, p, vec3(px[i], py[i], pz[i]), 1.0);
    source[i] = step == STEP_RESET ? SOURCE_RESET : float(off);
    out_r[i] = float(max(b[0].x, real(0)));
    out_g[i] = float(max(b[1].x, real(0)));
    out_b[i] = float(max(b[2].x, real(0)));
}
