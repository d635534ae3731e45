// Per-centre LP routines (spec §3.1-3.4), used by lp_centres.comp.
// Scalar twin: src/reference/lp.rs (lp_x here <-> lp::x there).
//
// The including kernel defines, before or after the include (prototypes
// below):
//   bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
//              the 9 features of spec §2.1 and validity (tsvd.glsl hook);
//   void load_colour(ivec2 p, out real3 y, out real3 v)
//              colour and its per-channel variance of the mean;
//   bool lp_valid(uint i)
//              whether pixel i (y * width + x) is valid (spp_of >= 1).
//
// GPU notes (§3.6): one thread per centre. The regressor zeta = (1, dz) is
// three real4 lanes (z0 = (1, dz1, dz2, dz3), z1 = dz4..7,
// z2 = (dz8, dz9, 0, 0); lanes beyond k + 1 are exactly 0). P is 3x3
// blocks of realmat4 (block (a, b) at P[3a + b], entry (row 4a + r,
// column 4b + c) at [c][r]). Every lane starts at I/delta; the lanes beyond
// k + 1 never mix with the others because their zeta entries are 0, so the
// result equals the twin's k+1 x k+1 recursion. beta[ch] is B[3ch + a].
// Nothing is indexed dynamically. The model is snapshotted only when a ring
// improves the error (strict <, ties to the smaller r), not per ring.

#ifndef MC_LP_GLSL
#define MC_LP_GLSL

#define MAX_D 9
#define TSVD_D 9
// LP solves nothing with linalg.glsl's WLS: keep its (unused) arrays small.
#define MAX_P 4
#include "lib/tsvd.glsl"

#ifdef MC_F64
#define lpmat4 dmat4
#else
#define lpmat4 mat4
#endif

// Constants of §3 (twins: the consts of src/reference/lp.rs).
#define LP_RADIUS 9
#define LP_DELTA 1e-3lf
#define LP_LOO_DEN_MIN 1e-4lf
// LpPush.options bit (mirror mcdenoise::shared::LP_VARSUB).
#define LP_VARSUB 1u
// LpPush.options bit (mirror mcdenoise::shared::LP_CENTRE_TEST).
#define LP_CENTRE_TEST 16u
// LpPush.options bit (mirror mcdenoise::shared::LP_OUTLIER_W).
#define LP_OUTLIER_W 64u
// LP-CENTRE-TEST's threshold (mirror reference::lp::CENTRE_TEST_Z2).
#define LP_CENTRE_TEST_Z2 9.0

void load_colour(ivec2 p, out real3 y, out real3 v);
bool lp_valid(uint i);

struct LpRls {
    lpmat4 P[9];
    real4 B[9];
    // Active lane blocks: 1 + (k >= 4) + (k >= 8). The blocks of inactive
    // lanes hold I/delta and 0 and would stay so (their zeta lanes are 0),
    // so they are skipped: most centres have k <= 3 and need one block.
    int nb;
};

// beta(0) = (y_c, 0, ..., 0), P(0) = I/delta (§3.3).
// Every block operation below is written out with constant indices (no
// loops over blocks): on lavapipe a loop that NIR does not unroll turns the
// struct's arrays into scratch memory.
LpRls lp_rls_new(real3 yc, int k)
{
    LpRls s;
    s.nb = 1 + (k >= 4 ? 1 : 0) + (k >= 8 ? 1 : 0);
    lpmat4 d = lpmat4(real(1.0lf / LP_DELTA));
    lpmat4 o = lpmat4(real(0));
    s.P[0] = d; s.P[1] = o; s.P[2] = o;
    s.P[3] = o; s.P[4] = d; s.P[5] = o;
    s.P[6] = o; s.P[7] = o; s.P[8] = d;
    s.B[0] = real4(yc.r, 0, 0, 0); s.B[1] = real4(0); s.B[2] = real4(0);
    s.B[3] = real4(yc.g, 0, 0, 0); s.B[4] = real4(0); s.B[5] = real4(0);
    s.B[6] = real4(yc.b, 0, 0, 0); s.B[7] = real4(0); s.B[8] = real4(0);
    return s;
}

// beta[ch]^T zeta over block 0 only: all of it when nb = 1.
real3 lp_predict3(LpRls s, real4 z0)
{
    return real3(dot(s.B[0], z0), dot(s.B[3], z0), dot(s.B[6], z0));
}

// beta[ch]^T zeta.
real3 lp_predict(LpRls s, real4 z0, real4 z1, real4 z2)
{
    real3 f = lp_predict3(s, z0);
    if (s.nb > 1) {
        f += real3(dot(s.B[1], z1), dot(s.B[4], z1), dot(s.B[7], z1));
    }
    if (s.nb > 2) {
        f += real3(dot(s.B[2], z2), dot(s.B[5], z2), dot(s.B[8], z2));
    }
    return f;
}

// q = P zeta.
void lp_p_zeta(LpRls s, real4 z0, real4 z1, real4 z2, out real4 q0, out real4 q1, out real4 q2)
{
    q0 = s.P[0] * z0;
    q1 = real4(0);
    q2 = real4(0);
    if (s.nb > 1) {
        q0 += s.P[1] * z1;
        q1 = s.P[3] * z0 + s.P[4] * z1;
    }
    if (s.nb > 2) {
        q0 += s.P[2] * z2;
        q1 += s.P[5] * z2;
        q2 = s.P[6] * z0 + s.P[7] * z1 + s.P[8] * z2;
    }
}

// zeta^T P zeta.
real lp_leverage(LpRls s, real4 z0, real4 z1, real4 z2)
{
    real4 q0, q1, q2;
    lp_p_zeta(s, z0, z1, z2, q0, q1, q2);
    return dot(z0, q0) + dot(z1, q1) + dot(z2, q2);
}

// LP-OUTLIER-W (twins: reference::lp::weight_scale, inverse_weight): a
// centre with colour variances vc weighs the row of a pixel with variances
// v by 1 / lp_inverse_weight(v, lp_weight_scale(vc, clamped)) =
// 1 / max(vbar / max(vbar_c, 1), 1); scale 0 (option off) gives 1, and so
// does the centre's own row.
real lp_weight_scale(real3 vc, bool clamped)
{
    return clamped ? max((vc.r + vc.g + vc.b) / real(3), real(1)) : real(0);
}

real lp_inverse_weight(real3 v, real scale)
{
    return scale > real(0) ? max((v.r + v.g + v.b) / real(3) / scale, real(1)) : real(1);
}

// One RLS update (§3.3) of a row of weight 1/c (LP-OUTLIER-W; c = 1: the
// spec's): q = P zeta, G = q / (c + zeta^T q), P -= G q^T,
// beta[ch] += G (y[ch] - beta[ch]^T zeta).
void lp_update(inout LpRls s, real4 z0, real4 z1, real4 z2, real3 y, real c)
{
    real4 q0, q1, q2;
    lp_p_zeta(s, z0, z1, z2, q0, q1, q2);
    real den = c + dot(z0, q0) + dot(z1, q1) + dot(z2, q2);
    real4 g0 = q0 / den;
    real4 g1 = q1 / den;
    real4 g2 = q2 / den;
    real3 e = y - lp_predict(s, z0, z1, z2);
    s.P[0] -= outerProduct(g0, q0);
    s.B[0] += g0 * e.r;
    s.B[3] += g0 * e.g;
    s.B[6] += g0 * e.b;
    if (s.nb > 1) {
        s.P[1] -= outerProduct(g0, q1);
        s.P[3] -= outerProduct(g1, q0);
        s.P[4] -= outerProduct(g1, q1);
        s.B[1] += g1 * e.r;
        s.B[4] += g1 * e.g;
        s.B[7] += g1 * e.b;
    }
    if (s.nb > 2) {
        s.P[2] -= outerProduct(g0, q2);
        s.P[5] -= outerProduct(g1, q2);
        s.P[6] -= outerProduct(g2, q0);
        s.P[7] -= outerProduct(g2, q1);
        s.P[8] -= outerProduct(g2, q2);
        s.B[2] += g2 * e.r;
        s.B[5] += g2 * e.g;
        s.B[8] += g2 * e.b;
    }
}

// P <- (P + P^T)/2, after each ring (§3.3).
void lp_symmetrise(inout LpRls s)
{
    s.P[0] = (s.P[0] + transpose(s.P[0])) * real(0.5);
    if (s.nb > 1) {
        lpmat4 m = (s.P[1] + transpose(s.P[3])) * real(0.5);
        s.P[1] = m;
        s.P[3] = transpose(m);
        s.P[4] = (s.P[4] + transpose(s.P[4])) * real(0.5);
    }
    if (s.nb > 2) {
        lpmat4 m2 = (s.P[2] + transpose(s.P[6])) * real(0.5);
        s.P[2] = m2;
        s.P[6] = transpose(m2);
        lpmat4 m5 = (s.P[5] + transpose(s.P[7])) * real(0.5);
        s.P[5] = m5;
        s.P[7] = transpose(m5);
        s.P[8] = (s.P[8] + transpose(s.P[8])) * real(0.5);
    }
}

// zeta = (1, dz) of pixel q for the centre with projection pr and raw
// features xc.
void lp_regressor(TsvdProj pr, real xc[MAX_D], ivec2 q, out real4 z0, out real4 z1, out real4 z2)
{
    real x[MAX_D];
    real e2[MAX_D];
    load_features(q, x, e2);
    // tsvd_dz, with the components 5..9 (zero for k <= 4) under a branch on
    // the centre's rank (skipped where branches are uniform; lavapipe runs
    // it anyway, and centres with k <= 3 use lp_regressor3).
    real4 d0 = tsvd_dz0(pr, xc, x);
    real4 d1 = real4(0);
    real d8 = real(0);
    if (pr.k > 4) {
        for (int j = 0; j < 9; ++j) {
            real dx = x[j] - xc[j];
            d1 += pr.P1[j] * dx;
            d8 += pr.P8[j] * dx;
        }
    }
    z0 = real4(1, d0.xyz);
    z1 = real4(d0.w, d1.xyz);
    z2 = real4(d1.w, d8, 0, 0);
}

// Ring r of centre c (|q - c|_inf = r), clipped, valid pixels, raster order
// (RING-ORDER), in one pass: each pixel is scored with the model of the
// previous rings (snapshot `prev` of beta taken before the ring: xi += (f - y)^2
// - s v, n += 1) and then added to the RLS. Scoring the whole ring first and
// then adding it, as §3.4 words it, gives the same numbers; one pass loads
// and projects every pixel once. With `score` false the ring is only added.
void lp_ring(inout LpRls st, TsvdProj pr, real xc[MAX_D], ivec2 c, int r, ivec2 size, bool score,
             real s, real ws, inout real3 xi, inout int n)
{
    LpRls prev;
    prev.B = st.B;
    prev.nb = st.nb;
    // A centre with one block (k <= 3) takes lp_ring3 instead: no rows here.
    int y0 = max(c.y - r, 0);
    int y1 = st.nb == 1 ? y0 - 1 : min(c.y + r, size.y - 1);
    for (int qy = y0; qy <= y1; ++qy) {
        int step = (qy == c.y - r || qy == c.y + r) ? 1 : 2 * r;
        for (int qx = c.x - r; qx <= c.x + r; qx += step) {
            ivec2 q = ivec2(qx, qy);
            if (qx < 0 || qx >= size.x || !lp_valid(uint(qy * size.x + qx))) {
                continue;
            }
            real4 z0, z1, z2;
            lp_regressor(pr, xc, q, z0, z1, z2);
            real3 y, v;
            load_colour(q, y, v);
            if (score) {
                real3 e = lp_predict(prev, z0, z1, z2) - y;
                xi += e * e - s * v;
                n += 1;
            }
            lp_update(st, z0, z1, z2, y, lp_inverse_weight(v, ws));
        }
    }
}

// The one-block forms of lp_regressor, lp_update and lp_ring, for a centre
// with k <= 3 (nb = 1: zeta = (1, dz_1..3), the other blocks inactive).
// They compute the same numbers with only block 0: lavapipe (Mesa 22.3) runs
// both sides of every branch under a lane mask, so the general functions'
// `if (s.nb > 1)` blocks cost even where no lane needs them, but it leaves a
// loop once no lane iterates. Each ring is visited by lp_ring3 (rows only
// when nb = 1) and by lp_ring (rows only when nb > 1): a centre takes
// exactly one, in the same order, and a SIMD vector of one-block centres
// skips the general loop's work.
real4 lp_regressor3(TsvdProj pr, real xc[MAX_D], ivec2 q)
{
    real x[MAX_D];
    real e2[MAX_D];
    load_features(q, x, e2);
    return real4(1, tsvd_dz0(pr, xc, x).xyz);
}

void lp_update3(inout LpRls s, real4 z0, real3 y, real c)
{
    real4 q0 = s.P[0] * z0;
    real den = c + dot(z0, q0);
    real4 g0 = q0 / den;
    real3 e = y - lp_predict3(s, z0);
    s.P[0] -= outerProduct(g0, q0);
    s.B[0] += g0 * e.r;
    s.B[3] += g0 * e.g;
    s.B[6] += g0 * e.b;
}

void lp_ring3(inout LpRls st, TsvdProj pr, real xc[MAX_D], ivec2 c, int r, ivec2 size, bool score,
              real s, real ws, inout real3 xi, inout int n)
{
    LpRls prev;  // the model of the previous rings, as in lp_ring
    prev.B = st.B;
    int y0 = max(c.y - r, 0);
    int y1 = st.nb == 1 ? min(c.y + r, size.y - 1) : y0 - 1;
    for (int qy = y0; qy <= y1; ++qy) {
        int step = (qy == c.y - r || qy == c.y + r) ? 1 : 2 * r;
        for (int qx = c.x - r; qx <= c.x + r; qx += step) {
            ivec2 q = ivec2(qx, qy);
            if (qx < 0 || qx >= size.x || !lp_valid(uint(qy * size.x + qx))) {
                continue;
            }
            real4 z0 = lp_regressor3(pr, xc, q);
            real3 y, v;
            load_colour(q, y, v);
            if (score) {
                real3 e = lp_predict3(prev, z0) - y;
                xi += e * e - s * v;
                n += 1;
            }
            lp_update3(st, z0, y, lp_inverse_weight(v, ws));
        }
    }
}

// What a centre's optimisation gives (twin: lp::CentreFit).
struct LpFit {
    int k;
    int r_opt;
    real4 B[9];  // beta(k(r_opt))
    real3 xi;    // xi-hat_ch(r_opt)
};

// LP-CENTRE-TEST (twin: reference::lp::centre_miss): the error a window's
// model adds for missing its own centre by more than 3 standard errors.
real3 lp_centre_miss(real3 miss, real3 vc, real s)
{
    real3 m2 = miss * miss;
    real3 add = m2 - s * vc;
    return mix(real3(0), add, greaterThan(m2, real(LP_CENTRE_TEST_Z2) * vc));
}

// Spec §3.3-3.4 for the valid centre c with projection pr; s = 1 (VARSUB)
// or 0 (paper-literal); centre_test: LP-CENTRE-TEST; clamped: LP-OUTLIER-W
// (weighted rows, LOO residual e / (1 - w zeta^T P zeta), unweighted error
// terms).
LpFit lp_centre_fit(ivec2 c, ivec2 size, TsvdProj pr, real s, bool centre_test, bool clamped)
{
    real xc[MAX_D];
    real e2[MAX_D];
    load_features(c, xc, e2);
    real3 yc, vc;
    load_colour(c, yc, vc);
    LpRls st = lp_rls_new(yc, pr.k);
    real ws = lp_weight_scale(vc, clamped);
    LpFit best;
    best.k = pr.k;

    // r = 0: the centre; xi(0) = v_c.
    real4 z0, z1, z2;
    lp_regressor(pr, xc, c, z0, z1, z2);
    real4 c0 = z0, c1 = z1, c2 = z2;  // the centre's regressor
    lp_update(st, z0, z1, z2, yc, real(1));  // its own row weighs 1
    lp_symmetrise(st);
    best.r_opt = 0;
    best.B = st.B;
    best.xi = vc;
    real best_total = vc.r + vc.g + vc.b;
    int n = 1;

    // r = 1: add ring 1, then the closed-form leave-one-out error over the
    // 3x3 block (LOO-DEN).
    real3 xi = real3(0);
    int n1 = 0;
    lp_ring3(st, pr, xc, c, 1, size, false, s, ws, xi, n1);
    lp_ring(st, pr, xc, c, 1, size, false, s, ws, xi, n1);
    lp_symmetrise(st);
    for (int qy = max(c.y - 1, 0); qy <= min(c.y + 1, size.y - 1); ++qy) {
        for (int qx = max(c.x - 1, 0); qx <= min(c.x + 1, size.x - 1); ++qx) {
            if (!lp_valid(uint(qy * size.x + qx))) {
                continue;
            }
            ivec2 q = ivec2(qx, qy);
            lp_regressor(pr, xc, q, z0, z1, z2);
            real3 y, v;
            load_colour(q, y, v);
            real den = max(real(1) - lp_leverage(st, z0, z1, z2) / lp_inverse_weight(v, ws),
                           real(LP_LOO_DEN_MIN));
            real3 e = (lp_predict(st, z0, z1, z2) - y) / den;
            xi += e * e - s * v;
            n += (qx == c.x && qy == c.y) ? 0 : 1;
        }
    }
    {
        real3 xr = xi / real(n);
        if (centre_test) {
            xr += lp_centre_miss(lp_predict(st, c0, c1, c2) - yc, vc, s);
        }
        real total = xr.r + xr.g + xr.b;
        if (total < best_total) {
            best_total = total;
            best.r_opt = 1;
            best.B = st.B;
            best.xi = xr;
        }
    }

    // r >= 2: score the previous model on ring r, then add the ring.
    for (int r = 2; r <= LP_RADIUS; ++r) {
        lp_ring3(st, pr, xc, c, r, size, true, s, ws, xi, n);
        lp_ring(st, pr, xc, c, r, size, true, s, ws, xi, n);
        lp_symmetrise(st);
        real3 xr = xi / real(n);
        if (centre_test) {
            xr += lp_centre_miss(lp_predict(st, c0, c1, c2) - yc, vc, s);
        }
        real total = xr.r + xr.g + xr.b;
        if (total < best_total) {
            best_total = total;
            best.r_opt = r;
            best.B = st.B;
            best.xi = xr;
        }
    }
    return best;
}

// The collapsed prediction map u[ch][j] = sum_m beta[ch][1+m] P[m][j]
// (twin: CentreFit::u), so that f_c(i)[ch] = beta[ch][0] + u[ch] . (x_i - x_c).
real lp_u(TsvdProj pr, LpFit f, int ch, int j)
{
    real4 b0 = f.B[3 * ch];
    real4 b1 = f.B[3 * ch + 1];
    real4 b2 = f.B[3 * ch + 2];
    return dot(pr.P0[j], real4(b0.yzw, b1.x)) + dot(pr.P1[j], real4(b1.yzw, b2.x)) + pr.P8[j] * b2.y;
}

#endif // MC_LP_GLSL
