// Per-pixel WLR routines (spec §2.3), shared by wlr_fit.comp and
// wlr_final.comp. Scalar twin: src/reference/wlr.rs, routine by routine
// (wlr_x here <-> wlr::x there).
//
// The including kernel defines, before the include:
//   WLR_NFIT   number of bandwidths fitted at once by wlr_fits (5 trials in
//              wlr_fit, 1 in wlr_final); only 1 and 5 are supported.
// and, before or after it (prototypes below):
//   bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
//              the 9 WLR features (spec §2.1) and validity (tsvd.glsl hook);
//   void load_colour(ivec2 p, out real3 y, out real vbar)
//              colour and vbar of a pixel.
//
// GPU notes (§2.4, /work/shared/docs/lavapipe.md): no per-neighbour state is
// kept between passes; every pass over the window reloads the features and
// recomputes dz = P (x_i - x_c) (P = V_k^T diag(1/rho), equal to §0.6 step 7).
// The normal equations are accumulated as real4 outer products into
// constant-indexed realmat4 blocks (dz_1..dz_9 padded to vec4 lanes; the
// padding lanes are exactly 0 and are dropped when the p x p system is packed
// for the shared ridge Cholesky of linalg.glsl). The bandwidth loop of the
// fits is unrolled by macro so that every accumulator index is a constant.
// Steps 6-7 (parametric fits, h_opt) are double in every variant (§0.3).

#ifndef MC_WLR_GLSL
#define MC_WLR_GLSL

#define MAX_D 9
#define TSVD_D 9
#include "lib/tsvd.glsl"

#ifndef WLR_NFIT
#error "wlr.glsl: define WLR_NFIT (1 or 5) before the include"
#endif

#ifdef MC_F64
#define realmat4 dmat4
#else
#define realmat4 mat4
#endif

// Constants of §2.3 (twins: the consts of src/reference/wlr.rs). Double
// literals so that the f64 variant is not rounded through float.
#define WLR_CURV_LAMBDA 1e-3lf
#define WLR_FIT_LAMBDA 1e-4lf
#define WLR_BETA0 0.64lf
#define WLR_CI_SIGMAS 3.0lf
#define WLR_CI_MARGIN 0.005lf
#define WLR_NONNEG_FLOOR 1e-3lf
#define WLR_H_MIN 0.01lf
#define WLR_H_MAX 1.0lf
#define WLR_LAMBDA_TINY 1e-30lf

// WlrPush.options bits (mirror mcdenoise::shared::WLR_*).
#define WLR_REJECT 1u
#define WLR_OUTLIER_CLAMPED 2u
#define WLR_NONNEG 4u

// Debug flag bits (§2.5; mirror reference::wlr::FLAG_*).
#define WLR_F_SOLVE_FAIL 1
#define WLR_F_FEW 2
#define WLR_F_K0 4
#define WLR_F_KAPPA 8
#define WLR_F_CLAMPED 16
#define WLR_F_INVALID 32

// Trial bandwidths h_s (step 5).
double wlr_trial_h(int s)
{
    return s == 0 ? 0.2lf : s == 1 ? 0.4lf : s == 2 ? 0.6lf : s == 3 ? 0.8lf : 1.0lf;
}

void load_colour(ivec2 p, out real3 y, out real vbar);

// --- centre -------------------------------------------------------------

struct WlrCentre {
    ivec2 c;
    real x[MAX_D];  // raw features
    real3 y;        // colour y_c
    real vbar;
    real grey;
    real sd;        // sqrt(max(vbar_c, 0))
    real n;         // n_c = spp_of(spp_c)
};

WlrCentre wlr_centre(ivec2 c, real n)
{
    WlrCentre cc;
    real e2[MAX_D];
    cc.c = c;
    load_features(c, cc.x, e2);
    load_colour(c, cc.y, cc.vbar);
    cc.grey = (cc.y.r + cc.y.g + cc.y.b) / real(3);
    cc.sd = sqrt(max(cc.vbar, real(0)));
    cc.n = n;
    return cc;
}

// --- local coordinates ----------------------------------------------------

// dz = P (x - x_c), P[m][j] = V_jm / rho_j (0 for constant j and m >= k).
// Column j of P is (P0[j], P1[j], P8[j]) = rows 0-3, 4-7, 8.
struct WlrProj {
    real4 P0[9];
    real4 P1[9];
    real P8[9];
    int k;
    bvec4 m0;  // components 0-3 active (m < k)
    bvec4 m1;  // components 4-7
    bool m8;   // component 8
};

WlrProj wlr_projection(LocalSpace ls)
{
    WlrProj pr;
    pr.k = ls.k;
    for (int j = 0; j < 9; ++j) {
        real inv = ls.range[j] > real(TSVD_RANGE_EPS) ? real(1) / ls.range[j] : real(0);
        real col[9];
        for (int m = 0; m < 9; ++m) {
            col[m] = m < ls.k ? ls.V[j * 9 + m] * inv : real(0);
        }
        pr.P0[j] = real4(col[0], col[1], col[2], col[3]);
        pr.P1[j] = real4(col[4], col[5], col[6], col[7]);
        pr.P8[j] = col[8];
    }
    pr.m0 = lessThan(ivec4(0, 1, 2, 3), ivec4(ls.k));
    pr.m1 = lessThan(ivec4(4, 5, 6, 7), ivec4(ls.k));
    pr.m8 = 8 < ls.k;
    return pr;
}

// Local coordinates of raw features x: d0 = dz_1..4, d1 = dz_5..8, d8 = dz_9
// (0 beyond k).
void wlr_dz(WlrProj pr, real xc[MAX_D], real x[MAX_D], out real4 d0, out real4 d1, out real d8)
{
    d0 = real4(0);
    d1 = real4(0);
    d8 = real(0);
    for (int j = 0; j < 9; ++j) {
        real dx = x[j] - xc[j];
        d0 += pr.P0[j] * dx;
        d1 += pr.P1[j] * dx;
        d8 += pr.P8[j] * dx;
    }
}

// --- weights --------------------------------------------------------------

// Step 2 (OUTLIER-W).
real wlr_outlier_weight(real vbar, uint options)
{
    return (options & WLR_OUTLIER_CLAMPED) != 0u ? real(1) / max(vbar, real(1)) : real(1);
}

// Step 3 (WLR-CI): acceptance on grey; the centre always passes.
bool wlr_accepted(real grey_i, real vbar_i, WlrCentre cc, bool is_centre, uint options)
{
    if ((options & WLR_REJECT) == 0u || is_centre) {
        return true;
    }
    return !(abs(grey_i - cc.grey) >
             real(WLR_CI_SIGMAS) * (sqrt(max(vbar_i, real(0))) + cc.sd) + real(WLR_CI_MARGIN));
}

// Product Epanechnikov kernel prod_{j<k} K_E(t_j), t = dz * inverse bandwidth.
real wlr_kernel(WlrProj pr, real4 t0, real4 t1, real t8)
{
    real4 k0 = mix(real4(1), max(real4(0), real(0.75) * (real4(1) - t0 * t0)), pr.m0);
    real4 k1 = mix(real4(1), max(real4(0), real(0.75) * (real4(1) - t1 * t1)), pr.m1);
    real k8 = pr.m8 ? max(real(0), real(0.75) * (real(1) - t8 * t8)) : real(1);
    return ((k0.x * k0.y) * (k0.z * k0.w)) * ((k1.x * k1.y) * (k1.z * k1.w)) * k8;
}

// --- curvature fit (step 4) -------------------------------------------------

// Full design index f (0..19) of (1, dz_1..dz_9, dz_1^2..dz_9^2, pad) for the
// compact index i (0..2k) of (1, dz_1..dz_k, dz_1^2..dz_k^2).
int wlr_curv_full(int i, int k)
{
    return i <= k ? i : i + 9 - k;
}

// Element (r, c), r <= c, of the upper block triangle of a 20 x 20 matrix
// held as 15 blocks (a, b), a <= b, in row order.
real wlr_block20(realmat4 M[15], int r, int c)
{
    int a = r >> 2;
    int b = c >> 2;
    int bi = a * 5 - (a * (a - 1)) / 2 + (b - a);
    return M[bi][c & 3][r & 3];
}

// Step 4: weighted quadratic fit (1, dz, dz o dz), weights o_i prod K_E(dz_ij),
// ridge 1e-3, per channel; b_j = (Hbar_j + 0.64)^(-1/2) for j < k, 0 beyond.
// Returns false on SOLVE-FAIL (b = 0). No rejection in this fit.
bool wlr_curvature(WlrProj pr, WlrCentre cc, int R, ivec2 size, uint options,
                   out real b[MAX_D], out real Hb[MAX_D])
{
    realmat4 M[15];
    real4 Y[15];  // channel ch, block a at Y[ch * 5 + a]
    for (int i = 0; i < 15; ++i) {
        M[i] = realmat4(0);
        Y[i] = real4(0);
    }
    for (int j = 0; j < MAX_D; ++j) {
        b[j] = real(0);
        Hb[j] = real(0);
    }
    ivec2 lo = max(cc.c - ivec2(R), ivec2(0));
    ivec2 up = min(cc.c + ivec2(R), size - ivec2(1));
    for (int qy = lo.y; qy <= up.y; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            ivec2 q = ivec2(qx, qy);
            real x[MAX_D];
            real e2[MAX_D];
            if (!load_features(q, x, e2)) {
                continue;
            }
            real3 y;
            real vb;
            load_colour(q, y, vb);
            real4 d0;
            real4 d1;
            real d8;
            wlr_dz(pr, cc.x, x, d0, d1, d8);
            real w = wlr_outlier_weight(vb, options) * wlr_kernel(pr, d0, d1, d8);
            if (w > real(0)) {
                real4 s0 = d0 * d0;
                real4 s1 = d1 * d1;
                real4 X0 = real4(real(1), d0.xyz);
                real4 X1 = real4(d0.w, d1.xyz);
                real4 X2 = real4(d1.w, d8, s0.xy);
                real4 X3 = real4(s0.zw, s1.xy);
                real4 X4 = real4(s1.zw, d8 * d8, real(0));
                real4 W0 = w * X0;
                real4 W1 = w * X1;
                real4 W2 = w * X2;
                real4 W3 = w * X3;
                real4 W4 = w * X4;
                M[0] += outerProduct(W0, X0);
                M[1] += outerProduct(W0, X1);
                M[2] += outerProduct(W0, X2);
                M[3] += outerProduct(W0, X3);
                M[4] += outerProduct(W0, X4);
                M[5] += outerProduct(W1, X1);
                M[6] += outerProduct(W1, X2);
                M[7] += outerProduct(W1, X3);
                M[8] += outerProduct(W1, X4);
                M[9] += outerProduct(W2, X2);
                M[10] += outerProduct(W2, X3);
                M[11] += outerProduct(W2, X4);
                M[12] += outerProduct(W3, X3);
                M[13] += outerProduct(W3, X4);
                M[14] += outerProduct(W4, X4);
                Y[0] += y.r * W0;
                Y[1] += y.r * W1;
                Y[2] += y.r * W2;
                Y[3] += y.r * W3;
                Y[4] += y.r * W4;
                Y[5] += y.g * W0;
                Y[6] += y.g * W1;
                Y[7] += y.g * W2;
                Y[8] += y.g * W3;
                Y[9] += y.g * W4;
                Y[10] += y.b * W0;
                Y[11] += y.b * W1;
                Y[12] += y.b * W2;
                Y[13] += y.b * W3;
                Y[14] += y.b * W4;
            }
        }
    }

    // Pack the (1+2k) x (1+2k) system (upper triangle) for the ridge Cholesky.
    int k = pr.k;
    int p = 1 + 2 * k;
    realmat4 Mc[15] = M;
    real4 Yc[15] = Y;
    real A[MAX_P * MAX_P];
    for (int i = 0; i < p; ++i) {
        int fi = wlr_curv_full(i, k);
        for (int j = i; j < p; ++j) {
            A[i * p + j] = wlr_block20(Mc, fi, wlr_curv_full(j, k));
        }
    }
    real lambda = real(WLR_CURV_LAMBDA);
    if (!wls_factor(A, p, lambda)) {
        return false;
    }
    for (int ch = 0; ch < 3; ++ch) {
        real rhs[MAX_P];
        for (int i = 0; i < MAX_P; ++i) {
            rhs[i] = real(0);
        }
        for (int i = 0; i < p; ++i) {
            int fi = wlr_curv_full(i, k);
            rhs[i] = Yc[ch * 5 + (fi >> 2)][fi & 3];
        }
        wls_backsolve(A, p, rhs);
        for (int j = 0; j < k; ++j) {
            Hb[j] += abs(real(2) * rhs[1 + k + j]) / real(3);
        }
    }
    for (int j = 0; j < k; ++j) {
        b[j] = real(1) / sqrt(Hb[j] + real(WLR_BETA0));
    }
    return true;
}

// --- local linear fits (steps 5 and 9) ----------------------------------------

struct WlrFit {
    real3 f;    // f-hat (NONNEG applied when on)
    real bias;  // (1/3) sum_ch (f-hat - y_c)
    real var;   // sum_i l_i^2 vbar_i
    int flags;  // WLR_F_SOLVE_FAIL | WLR_F_FEW
    int npos;   // neighbours with w_i > 0
};

// Element (r, c), r <= c, of a 12 x 12 matrix held as 6 blocks (a, b), a <= b.
real wlr_block12(realmat4 T[6 * WLR_NFIT], int s, int r, int c)
{
    int a = r >> 2;
    int b = c >> 2;
    int bi = a * 3 - (a * (a - 1)) / 2 + (b - a);
    return T[6 * s + bi][c & 3][r & 3];
}

// Per-neighbour data shared by the two passes of wlr_fits: base weight
// acc_i o_i (0 = skip), local coordinates, colour, vbar.
bool wlr_fit_neighbour(WlrProj pr, WlrCentre cc, ivec2 q, uint options,
                       out real base, out real4 d0, out real4 d1, out real d8,
                       out real3 y, out real vb)
{
    real x[MAX_D];
    real e2[MAX_D];
    base = real(0);
    d0 = real4(0);
    d1 = real4(0);
    d8 = real(0);
    y = real3(0);
    vb = real(0);
    if (!load_features(q, x, e2)) {
        return false;
    }
    load_colour(q, y, vb);
    real g = (y.r + y.g + y.b) / real(3);
    if (!wlr_accepted(g, vb, cc, all(equal(q, cc.c)), options)) {
        return false;
    }
    base = wlr_outlier_weight(vb, options);
    wlr_dz(pr, cc.x, x, d0, d1, d8);
    return base > real(0);
}

// Pass A body for bandwidth s (a literal): weight, count, normal matrix.
#define WLR_PASS_A(s)                                                               \
    {                                                                               \
        real w = base * wlr_kernel(pr, d0 * I0[s], d1 * I1[s], d8 * I8[s]);         \
        if (w > real(0)) {                                                          \
            cnt[s] += 1;                                                            \
            real4 W0 = w * X0;                                                      \
            real4 W1 = w * X1;                                                      \
            real4 W2 = w * X2;                                                      \
            T[6 * s + 0] += outerProduct(W0, X0);                                   \
            T[6 * s + 1] += outerProduct(W0, X1);                                   \
            T[6 * s + 2] += outerProduct(W0, X2);                                   \
            T[6 * s + 3] += outerProduct(W1, X1);                                   \
            T[6 * s + 4] += outerProduct(W1, X2);                                   \
            T[6 * s + 5] += outerProduct(W2, X2);                                   \
        }                                                                           \
    }

// Pass B body for bandwidth s: l_i = w_i u^T x_i and the sums of step 5.
#define WLR_PASS_B(s)                                                               \
    {                                                                               \
        real w = base * wlr_kernel(pr, d0 * I0[s], d1 * I1[s], d8 * I8[s]);         \
        if (w > real(0)) {                                                          \
            real l = w * (dot(U0[s], X0) + dot(U1[s], X1) + dot(U2[s], X2));        \
            real lp = max(l, real(0));                                              \
            S1[s] += real4(l * y, l * l * vb);                                      \
            S2[s] += real4(lp * y, lp * lp * vb);                                   \
            S3[s] += lp;                                                            \
        }                                                                           \
    }

// Steps 5 / 9: local linear fits (1, dz) (p = k+1, ridge `lambda`) at the
// WLR_NFIT bandwidths h[s], weights acc_i o_i prod_j K_E(dz_ij / (h_s b_j)).
// FEW (<= 1 positive weight) and SOLVE-FAIL give f = y_c, bias 0, var vbar_c
// (flag bits 1 / 0); NONNEG when the option is on. b_j > 0 for j < k.
void wlr_fits(WlrProj pr, WlrCentre cc, real b[MAX_D], real h[WLR_NFIT], int R, ivec2 size,
              uint options, real lambda, out WlrFit fit[WLR_NFIT])
{
    int k = pr.k;
    int np = k + 1;
    real4 I0[WLR_NFIT];
    real4 I1[WLR_NFIT];
    real I8[WLR_NFIT];
    realmat4 T[6 * WLR_NFIT];
    int cnt[WLR_NFIT];
    for (int s = 0; s < WLR_NFIT; ++s) {
        real inv[9];
        for (int j = 0; j < 9; ++j) {
            inv[j] = j < k ? real(1) / (h[s] * b[j]) : real(0);
        }
        I0[s] = real4(inv[0], inv[1], inv[2], inv[3]);
        I1[s] = real4(inv[4], inv[5], inv[6], inv[7]);
        I8[s] = inv[8];
        cnt[s] = 0;
        for (int i = 0; i < 6; ++i) {
            T[6 * s + i] = realmat4(0);
        }
    }
    ivec2 lo = max(cc.c - ivec2(R), ivec2(0));
    ivec2 up = min(cc.c + ivec2(R), size - ivec2(1));

    // Pass A: normal matrices and positive-weight counts.
    for (int qy = lo.y; qy <= up.y; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            real base;
            real4 d0;
            real4 d1;
            real d8;
            real3 y;
            real vb;
            if (!wlr_fit_neighbour(pr, cc, ivec2(qx, qy), options, base, d0, d1, d8, y, vb)) {
                continue;
            }
            real4 X0 = real4(real(1), d0.xyz);
            real4 X1 = real4(d0.w, d1.xyz);
            real4 X2 = real4(d1.w, d8, real(0), real(0));
            WLR_PASS_A(0)
#if WLR_NFIT > 1
            WLR_PASS_A(1)
            WLR_PASS_A(2)
            WLR_PASS_A(3)
            WLR_PASS_A(4)
#endif
        }
    }

    // Solves: u_s = (A_s + Lambda)^{-1} e_1.
    realmat4 Tc[6 * WLR_NFIT] = T;
    real4 U0[WLR_NFIT];
    real4 U1[WLR_NFIT];
    real4 U2[WLR_NFIT];
    bool any_solved = false;
    for (int s = 0; s < WLR_NFIT; ++s) {
        fit[s].f = cc.y;
        fit[s].bias = real(0);
        fit[s].var = cc.vbar;
        fit[s].flags = 0;
        fit[s].npos = cnt[s];
        U0[s] = real4(0);
        U1[s] = real4(0);
        U2[s] = real4(0);
        if (cnt[s] <= 1) {
            fit[s].flags |= WLR_F_FEW;
            continue;
        }
        real A[MAX_P * MAX_P];
        for (int i = 0; i < np; ++i) {
            for (int j = i; j < np; ++j) {
                A[i * np + j] = wlr_block12(Tc, s, i, j);
            }
        }
        real lam = lambda;
        real u[MAX_P];
        if (!wls_first_column(A, np, lam, u)) {
            fit[s].flags |= WLR_F_SOLVE_FAIL;
            continue;
        }
        U0[s] = real4(u[0], u[1], u[2], u[3]);
        U1[s] = real4(u[4], u[5], u[6], u[7]);
        U2[s] = real4(u[8], u[9], real(0), real(0));
        any_solved = true;
    }
    if (!any_solved) {
        return;
    }

    // Pass B: equivalent kernels and the sums of step 5.
    real4 S1[WLR_NFIT];  // sum l y, sum l^2 vbar
    real4 S2[WLR_NFIT];  // sum l+ y, sum l+^2 vbar
    real S3[WLR_NFIT];   // sum l+
    for (int s = 0; s < WLR_NFIT; ++s) {
        S1[s] = real4(0);
        S2[s] = real4(0);
        S3[s] = real(0);
    }
    for (int qy = lo.y; qy <= up.y; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            real base;
            real4 d0;
            real4 d1;
            real d8;
            real3 y;
            real vb;
            if (!wlr_fit_neighbour(pr, cc, ivec2(qx, qy), options, base, d0, d1, d8, y, vb)) {
                continue;
            }
            real4 X0 = real4(real(1), d0.xyz);
            real4 X1 = real4(d0.w, d1.xyz);
            real4 X2 = real4(d1.w, d8, real(0), real(0));
            WLR_PASS_B(0)
#if WLR_NFIT > 1
            WLR_PASS_B(1)
            WLR_PASS_B(2)
            WLR_PASS_B(3)
            WLR_PASS_B(4)
#endif
        }
    }
    for (int s = 0; s < WLR_NFIT; ++s) {
        if (fit[s].flags != 0) {
            continue;  // FEW or SOLVE-FAIL: y_c, bias 0, var vbar_c
        }
        real3 f = S1[s].xyz;
        real var = S1[s].w;
        if ((options & WLR_NONNEG) != 0u && any(lessThan(f, real3(0)))) {
            real den = max(S3[s], real(WLR_NONNEG_FLOOR));
            f = max(S2[s].xyz / den, real3(0));
            var = S2[s].w / (den * den);
        }
        fit[s].f = f;
        fit[s].var = var;
        fit[s].bias = ((f.r - cc.y.r) + (f.g - cc.y.g) + (f.b - cc.y.b)) / real(3);
    }
}

// --- parametric fits and h_opt (steps 6-7, double always) ---------------------

// (intercept, slope) of the least-squares line through the 5 points (t, u).
dvec2 wlr_simple_regression(double t[5], double u[5])
{
    double tm = (t[0] + t[1] + t[2] + t[3] + t[4]) / 5.0lf;
    double um = (u[0] + u[1] + u[2] + u[3] + u[4]) / 5.0lf;
    double stu = 0.0lf;
    double stt = 0.0lf;
    for (int s = 0; s < 5; ++s) {
        stu += (t[s] - tm) * (u[s] - um);
        stt += (t[s] - tm) * (t[s] - tm);
    }
    double slope = stu / stt;
    return dvec2(um - slope * tm, slope);
}

// h^{-k} by repeated multiplication.
double wlr_inv_pow(double h, int k)
{
    double hk = 1.0lf;
    for (int i = 0; i < k; ++i) {
        hk *= h;
    }
    return 1.0lf / hk;
}

// a^{1/m} for a in (0, 1]: float pow refined by Newton steps in double
// (GLSL has no double pow).
double wlr_root(double a, int m)
{
    double x = double(pow(float(a), 1.0 / float(m)));
    for (int it = 0; it < 4; ++it) {
        double xm1 = 1.0lf;
        for (int i = 0; i < m - 1; ++i) {
            xm1 *= x;
        }
        x -= (x * xm1 - a) / (double(m) * xm1);
    }
    return x;
}

// Step 6: (lambda0, lambda1, kappa0, kappa1); bias on h^2, n_c var on h^-k.
dvec4 wlr_parametric(double bias[5], double var[5], int k, double n)
{
    double t2[5];
    double tk[5];
    double nv[5];
    for (int s = 0; s < 5; ++s) {
        double h = wlr_trial_h(s);
        t2[s] = h * h;
        tk[s] = wlr_inv_pow(h, k);
        nv[s] = n * var[s];
    }
    return dvec4(wlr_simple_regression(t2, bias), wlr_simple_regression(tk, nv));
}

// Step 7 with H-CASES (k >= 1). Returns (h_opt, lambda1, kappa0, kappa1) of
// the stored MSE model; flags gets WLR_F_KAPPA / WLR_F_CLAMPED.
dvec4 wlr_choose_h(dvec4 par, int k, double n, double bias1, double var1, inout int flags)
{
    if (!(par.w > 0.0lf)) {
        flags |= WLR_F_KAPPA;
        return dvec4(wlr_trial_h(0), 0.0lf, n * (bias1 * bias1 + var1), 0.0lf);
    }
    double l2n = par.y * par.y * n;
    if (l2n < WLR_LAMBDA_TINY) {
        return dvec4(WLR_H_MAX, par.yzw);
    }
    double a = double(k) * par.w / (4.0lf * l2n);
    int m = k + 4;
    double lo = 1.0lf / wlr_inv_pow(WLR_H_MIN, m);  // H_MIN^m
    double h;
    if (a > 1.0lf) {
        h = WLR_H_MAX;
        flags |= WLR_F_CLAMPED;
    } else if (a < lo) {
        h = WLR_H_MIN;
        flags |= WLR_F_CLAMPED;
    } else {
        h = clamp(wlr_root(a, m), WLR_H_MIN, WLR_H_MAX);
    }
    return dvec4(h, par.yzw);
}

// Step 10: (lambda1 h^2)^2 + (kappa0 + kappa1 h^-k)/n_c, clamped >= 0.
double wlr_mse_model(double lambda1, double kappa0, double kappa1, int k, double n, double h)
{
    double bb = lambda1 * h * h;
    return max(bb * bb + (kappa0 + kappa1 * wlr_inv_pow(h, k)) / n, 0.0lf);
}

#endif // MC_WLR_GLSL
