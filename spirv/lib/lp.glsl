// Per-centre LP routines (spec §3.1-3.4), used by lp_centres.comp.
// Scalar twin: src/reference/lp.rs (lp_x here <-> lp::x there).
//
// The including kernel defines, before or after the include (prototypes
// below):
//   bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
//              the 9 features of spec §2.1 and validity (tsvd.glsl hook);
//   void load_colour(ivec2 p, out real3 y, out real3 v)
//              colour and its per-channel variance of the mean;
// and it declares the plane `spp` (validity of ring pixels, spp_of >= 1).
//
// GPU notes (§3.6): one thread per centre. The regressor zeta = (1, dz) is
// three real4 lanes (z[0] = (1, dz1, dz2, dz3), z[1] = dz4..7,
// z[2] = (dz8, dz9, 0, 0); lanes beyond k + 1 are exactly 0). P is 3x3
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

void load_colour(ivec2 p, out real3 y, out real3 v);

struct LpRls {
    lpmat4 P[9];
    real4 B[9];
    // Active lane blocks: 1 + (k >= 4) + (k >= 8). The blocks of inactive
    // lanes hold I/delta and 0 and would stay so (their zeta lanes are 0),
    // so they are skipped: most centres have k <= 3 and need one block.
    int nb;
};

// beta(0) = (y_c, 0, ..., 0), P(0) = I/delta (§3.3).
LpRls lp_rls_new(real3 yc, int k)
{
    LpRls s;
    s.nb = 1 + (k >= 4 ? 1 : 0) + (k >= 8 ? 1 : 0);
    for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
            s.P[3 * a + b] = lpmat4(a == b ? real(1.0lf / LP_DELTA) : real(0));
        }
    }
    for (int ch = 0; ch < 3; ++ch) {
        s.B[3 * ch] = real4(yc[ch], 0, 0, 0);
        s.B[3 * ch + 1] = real4(0);
        s.B[3 * ch + 2] = real4(0);
    }
    return s;
}

// beta[ch]^T zeta.
real3 lp_predict(LpRls s, real4 z[3])
{
    real3 f;
    for (int ch = 0; ch < 3; ++ch) {
        f[ch] = dot(s.B[3 * ch], z[0]) + dot(s.B[3 * ch + 1], z[1]) + dot(s.B[3 * ch + 2], z[2]);
    }
    return f;
}

// q = P zeta.
void lp_p_zeta(LpRls s, real4 z[3], out real4 q[3])
{
    for (int a = 0; a < 3; ++a) {
        q[a] = real4(0);
        if (a < s.nb) {
            q[a] = s.P[3 * a] * z[0];
            if (s.nb > 1) {
                q[a] += s.P[3 * a + 1] * z[1];
            }
            if (s.nb > 2) {
                q[a] += s.P[3 * a + 2] * z[2];
            }
        }
    }
}

// zeta^T P zeta.
real lp_leverage(LpRls s, real4 z[3])
{
    real4 q[3];
    lp_p_zeta(s, z, q);
    return dot(z[0], q[0]) + dot(z[1], q[1]) + dot(z[2], q[2]);
}

// One RLS update (§3.3): q = P zeta, G = q / (1 + zeta^T q), P -= G q^T,
// beta[ch] += G (y[ch] - beta[ch]^T zeta).
void lp_update(inout LpRls s, real4 z[3], real3 y)
{
    real4 q[3];
    lp_p_zeta(s, z, q);
    real den = real(1) + dot(z[0], q[0]) + dot(z[1], q[1]) + dot(z[2], q[2]);
    real4 g[3];
    for (int a = 0; a < 3; ++a) {
        g[a] = q[a] / den;
    }
    real3 e = y - lp_predict(s, z);
    for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
            if (a < s.nb && b < s.nb) {
                s.P[3 * a + b] -= outerProduct(g[a], q[b]);
            }
        }
    }
    for (int ch = 0; ch < 3; ++ch) {
        for (int a = 0; a < 3; ++a) {
            s.B[3 * ch + a] += g[a] * e[ch];
        }
    }
}

// P <- (P + P^T)/2, after each ring (§3.3).
void lp_symmetrise(inout LpRls s)
{
    for (int a = 0; a < 3; ++a) {
        if (a >= s.nb) {
            continue;
        }
        s.P[4 * a] = (s.P[4 * a] + transpose(s.P[4 * a])) * real(0.5);
        for (int b = a + 1; b < 3; ++b) {
            if (b >= s.nb) {
                continue;
            }
            lpmat4 m = (s.P[3 * a + b] + transpose(s.P[3 * b + a])) * real(0.5);
            s.P[3 * a + b] = m;
            s.P[3 * b + a] = transpose(m);
        }
    }
}

// zeta = (1, dz) of pixel q for the centre with projection pr and raw
// features xc.
void lp_regressor(TsvdProj pr, real xc[MAX_D], ivec2 q, out real4 z[3])
{
    real x[MAX_D];
    real e2[MAX_D];
    load_features(q, x, e2);
    real4 d0, d1;
    real d8;
    tsvd_dz(pr, xc, x, d0, d1, d8);
    z[0] = real4(1, d0.xyz);
    z[1] = real4(d0.w, d1.xyz);
    z[2] = real4(d1.w, d8, 0, 0);
}

// Ring r of centre c (|q - c|_inf = r), clipped, valid pixels, raster order
// (RING-ORDER), in one pass: each pixel is scored with the model of the
// previous rings (snapshot `prev` of beta taken before the ring: xi += (f - y)^2
// - s v, n += 1) and then added to the RLS. Scoring the whole ring first and
// then adding it, as §3.4 words it, gives the same numbers; one pass loads
// and projects every pixel once. With `score` false the ring is only added.
void lp_ring(inout LpRls st, TsvdProj pr, real xc[MAX_D], ivec2 c, int r, ivec2 size, bool score,
             real s, inout real3 xi, inout int n)
{
    LpRls prev;
    prev.B = st.B;
    for (int qy = max(c.y - r, 0); qy <= min(c.y + r, size.y - 1); ++qy) {
        int step = (qy == c.y - r || qy == c.y + r) ? 1 : 2 * r;
        for (int qx = c.x - r; qx <= c.x + r; qx += step) {
            ivec2 q = ivec2(qx, qy);
            if (qx < 0 || qx >= size.x || spp_of(spp[qy * size.x + qx]) < 1.0) {
                continue;
            }
            real4 z[3];
            lp_regressor(pr, xc, q, z);
            real3 y, v;
            load_colour(q, y, v);
            if (score) {
                real3 e = lp_predict(prev, z) - y;
                xi += e * e - s * v;
                n += 1;
            }
            lp_update(st, z, y);
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

// Spec §3.3-3.4 for the valid centre c with projection pr; s = 1 (VARSUB)
// or 0 (paper-literal).
LpFit lp_centre_fit(ivec2 c, ivec2 size, TsvdProj pr, real s)
{
    real xc[MAX_D];
    real e2[MAX_D];
    load_features(c, xc, e2);
    real3 yc, vc;
    load_colour(c, yc, vc);
    LpRls st = lp_rls_new(yc, pr.k);
    LpFit best;
    best.k = pr.k;

    // r = 0: the centre; xi(0) = v_c.
    real4 z[3];
    lp_regressor(pr, xc, c, z);
    lp_update(st, z, yc);
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
    lp_ring(st, pr, xc, c, 1, size, false, s, xi, n1);
    lp_symmetrise(st);
    for (int qy = max(c.y - 1, 0); qy <= min(c.y + 1, size.y - 1); ++qy) {
        for (int qx = max(c.x - 1, 0); qx <= min(c.x + 1, size.x - 1); ++qx) {
            if (spp_of(spp[qy * size.x + qx]) < 1.0) {
                continue;
            }
            ivec2 q = ivec2(qx, qy);
            lp_regressor(pr, xc, q, z);
            real3 y, v;
            load_colour(q, y, v);
            real den = max(real(1) - lp_leverage(st, z), real(LP_LOO_DEN_MIN));
            real3 e = (lp_predict(st, z) - y) / den;
            xi += e * e - s * v;
            n += (qx == c.x && qy == c.y) ? 0 : 1;
        }
    }
    {
        real3 xr = xi / real(n);
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
        lp_ring(st, pr, xc, c, r, size, true, s, xi, n);
        lp_symmetrise(st);
        real3 xr = xi / real(n);
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
