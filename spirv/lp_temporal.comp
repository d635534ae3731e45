#version 460
// Spec §10.1, the LP temporal filter, one frame: per pixel a recursive
// least-squares fit of (1, tau) -> y over the frames with forgetting factor
// lambda and the time origin at the current frame (TIME-ORIGIN). The state
// of the previous frame (origin t-1) is searched in a 7x7 window (SEARCH-7)
// for the valid pixel j with the least (eW + epsW)(ey + epsy) after the
// shift S = [[1,1],[0,1]] among those within 1 % of the viewing distance
// (eW <= (0.01 max(dep, 1e-3))^2 + RESET_NOISE * sum of W_i's variances,
// TEMPORAL-GATE and RESET-NOISE); none reinitialises the pixel (RESET):
// beta = (y, 0), P = I/delta.
// Otherwise G = P z / (lambda + z^T P z), P <- (P - G z^T P)/lambda,
// beta <- beta + G (y - beta^T z) with z = (1, 0). Output beta[ch][0],
// clamped to >= 0 (§0.4 step 5).
// State planes (TEMPORAL_STATE, mcdenoise::shared): b0 b1 per channel R G B,
// P00 P01 P11, W X Y Z, valid. `prev` is read, `next` written: the host
// copies next to prev after the frame.
// Scalar twin: src/reference/lp_temporal.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::TemporalPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint flags;
    float lambda;
    float delta;
    uint pad0;
    uint pad1;
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
PLANE_IN(11, prev)
PLANE_OUT(12, next)
PLANE_OUT(13, out_r)
PLANE_OUT(14, out_g)
PLANE_OUT(15, out_b)
PLANE_OUT(16, source)

// mcdenoise::shared: TEMPORAL_RESET, TEMPORAL_NO_SEARCH, TEMPORAL_SEARCH,
// TEMPORAL_RESET_REL, TEMPORAL_DEPTH_FLOOR, TEMPORAL_SOURCE_RESET,
// TEMPORAL_SOURCE_NONE.
#define TEMPORAL_RESET 1u
#define TEMPORAL_NO_SEARCH 2u
#define SEARCH 3
#define RESET_REL 0.01
#define DEPTH_FLOOR 1e-3
#define RESET_NOISE 18.0
#define SOURCE_RESET -1.0
#define SOURCE_NONE -2.0

// The state of pixel j (n pixels), shifted to the current frame's origin:
// beta as (b0, b1) per channel, P as (p00, p01, p11).
void load_shifted(uint j, uint n, out real2 b[3], out real3 p, out real3 w)
{
    for (int c = 0; c < 3; ++c) {
        real b0 = real(prev[(2 * c) * n + j]);
        real b1 = real(prev[(2 * c + 1) * n + j]);
        b[c] = real2(b0 + b1, b1);
    }
    real a = real(prev[6 * n + j]);
    real o = real(prev[7 * n + j]);
    real d = real(prev[8 * n + j]);
    p = real3(a + real(2) * o + d, o + d, d);
    w = real3(prev[9 * n + j], prev[10 * n + j], prev[11 * n + j]);
}

bool valid_at(uint j, uint n) { return prev[12 * n + j] == 1.0; }

void store(uint i, uint n, real2 b[3], real3 p, real3 w, float valid)
{
    for (int c = 0; c < 3; ++c) {
        next[(2 * c) * n + i] = float(b[c].x);
        next[(2 * c + 1) * n + i] = float(b[c].y);
    }
    next[6 * n + i] = float(p.x);
    next[7 * n + i] = float(p.y);
    next[8 * n + i] = float(p.z);
    next[9 * n + i] = float(w.x);
    next[10 * n + i] = float(w.y);
    next[11 * n + i] = float(w.z);
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
    vec3 col = vec3(yr[i], yg[i], yb[i]);
    real3 yi = real3(col);
    real3 wi = real3(px[i], py[i], pz[i]);
    real2 b[3];
    real3 p;
    real3 w;
    if (spp_of(spp[i]) < 1.0 || !is_finite(col.x) || !is_finite(col.y) || !is_finite(col.z)) {
        b[0] = real2(0); b[1] = real2(0); b[2] = real2(0);
        store(i, n, b, real3(0), real3(0), 0.0);
        out_r[i] = col.x;
        out_g[i] = col.y;
        out_b[i] = col.z;
        source[i] = SOURCE_NONE;
        return;
    }
    bool found = false;
    int best_off = 0;
    if ((push.flags & TEMPORAL_RESET) == 0u) {
        if ((push.flags & TEMPORAL_NO_SEARCH) != 0u) {
            if (valid_at(i, n)) {
                load_shifted(i, n, b, p, w);
                found = true;
                best_off = SEARCH * (2 * SEARCH + 1) + SEARCH;
            }
        } else {
            real ew_floor = real(1e-12) * (real(1) + dot(wi, wi));
            real limit = real(RESET_REL) * max(real(depth[i]), real(DEPTH_FLOOR));
            limit = limit * limit + real(RESET_NOISE) * (real(vx[i]) + real(vy[i]) + real(vz[i]));
            real best_cost = real(0);
            int x0 = max(int(x) - SEARCH, 0), x1 = min(int(x) + SEARCH, int(push.width) - 1);
            int y0 = max(int(y) - SEARCH, 0), y1 = min(int(y) + SEARCH, int(push.height) - 1);
            for (int jy = y0; jy <= y1; ++jy) {
                for (int jx = x0; jx <= x1; ++jx) {
                    uint j = uint(jy) * push.width + uint(jx);
                    if (!valid_at(j, n)) {
                        continue;
                    }
                    real2 cb[3];
                    real3 cp;
                    real3 cw;
                    load_shifted(j, n, cb, cp, cw);
                    real3 dw = cw - wi;
                    real ew = dot(dw, dw);
                    if (ew > limit) {
                        continue;
                    }
                    real3 dy3 = yi - real3(cb[0].x, cb[1].x, cb[2].x);
                    real ey = dot(dy3, dy3);
                    real cost = (ew + ew_floor) * (ey + real(1e-12));
                    if (!found || cost < best_cost) {
                        found = true;
                        best_cost = cost;
                        best_off = (jy - int(y) + SEARCH) * (2 * SEARCH + 1) + (jx - int(x) + SEARCH);
                        b = cb;
                        p = cp;
                        w = cw;
                    }
                }
            }
        }
    }
    if (found) {
        real lambda = real(push.lambda);
        real den = lambda + p.x;
        real2 g = real2(p.x, p.y) / den;
        p = real3(p.x - g.x * p.x, p.y - g.x * p.y, p.z - g.y * p.y) / lambda;
        for (int c = 0; c < 3; ++c) {
            real r = yi[c] - b[c].x;
            b[c] += g * r;
        }
        source[i] = float(best_off);
    } else {
        for (int c = 0; c < 3; ++c) {
            b[c] = real2(yi[c], real(0));
        }
        real inv = real(1) / real(push.delta);
        p = real3(inv, real(0), inv);
        source[i] = SOURCE_RESET;
    }
    store(i, n, b, p, wi, 1.0);
    out_r[i] = float(max(b[0].x, real(0)));
    out_g[i] = float(max(b[1].x, real(0)));
    out_b[i] = float(max(b[2].x, real(0)));
}
