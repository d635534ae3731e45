// Per-pixel WLR routines (spec §2.3), shared by wlr_fit.comp and
// wlr_final.comp. Scalar twin: src/reference/wlr.rs, routine by routine
// (wlr_x here <-> wlr::x there).
//
// The including kernel defines, before the include:
//   WLR_NFIT   number of bandwidths fitted at once by wlr_fits (5 trials in
//              wlr_fit, 1 in wlr_final); only 1 and 5 are supported.
// and, before or after it (prototypes below):
//   bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
//              the 9 WLR features (spec §2.1), with WLR_VIS defined the
//              prefiltered visibility as a tenth (WLR-VIS: `_vis` kernels,
//              at most 9 local coordinates), and validity (tsvd.glsl hook);
//   void load_colour(ivec2 p, out real3 y, out real vbar)
//              colour and vbar of a pixel.
//
// GPU notes (§2.4, docs/lavapipe.md): no per-neighbour state is
// kept between passes; every pass over the window reloads the features and
// recomputes dz = P (x_i - x_c) (P = V_k^T diag(1/rho), equal to §0.6 step 7).
// The normal equations are accumulated as real4 outer products into
// constant-indexed realmat4 blocks (dz_1..dz_9 padded to vec4 lanes, the
// unused lanes exactly 0) and factored in place by a masked block Cholesky
// with the RIDGE / SOLVE-FAIL rules of §0.5 (wlr_factor12, wlr_factor20).
// Nothing is indexed dynamically: on lavapipe a dynamically indexed local
// array compiles to code proportional to its size (a 19x19 generic solve cost
// ~5 s of pipeline creation) and runs slower. The bandwidth loop of the fits
// is unrolled by macro for the same reason. Responses are centred (y - y_c;
// the intercept is unpenalised, so only the intercept changes), which keeps
// the f32 biases f-hat - y_c free of cancellation.
// Steps 6-7 (parametric fits, h_opt) are double in every variant (§0.3).

#ifndef MC_WLR_GLSL
#define MC_WLR_GLSL

#ifdef WLR_VIS
#define MAX_D 10
#define TSVD_D 10
#define TSVD_MAX_RANK 9
#else
#define MAX_D 9
#define TSVD_D 9
#endif
// The fits solve their systems with the block routines below, not with
// linalg.glsl's WLS: keep its (unused) arrays small.
#define MAX_P 4
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
#define WLR_SKIP_DEBUG 8u
#define WLR_SKIP_MSE 16u

// Debug flag bits (§2.5; mirror reference::wlr::FLAG_*).
#define WLR_F_SOLVE_FAIL 1
#define WLR_F_FEW 2
#define WLR_F_K0 4
#define WLR_F_KAPPA 8
#define WLR_F_CLAMPED 16
#define WLR_F_INVALID 32

// Trial bandwidths h_s (step 5).
#ifdef MC_DD
// (no double anywhere in the `_dd` variant: float literals, the nearest
// floats to the decimals as float(0.2lf) is)
real wlr_trial_h_real(int s)
{
    return s == 0 ? 0.2 : s == 1 ? 0.4 : s == 2 ? 0.6 : s == 3 ? 0.8 : 1.0;
}
#else
double wlr_trial_h(int s)
{
    return s == 0 ? 0.2lf : s == 1 ? 0.4lf : s == 2 ? 0.6lf : s == 3 ? 0.8lf : 1.0lf;
}
#define wlr_trial_h_real(s) real(wlr_trial_h(s))
#endif

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

// Local coordinates: TsvdProj / tsvd_projection / tsvd_dz of lib/tsvd.glsl.

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
real wlr_kernel(TsvdProj pr, real4 t0, real4 t1, real t8)
{
    real4 k0 = mix(real4(1), max(real4(0), real(0.75) * (real4(1) - t0 * t0)), pr.m0);
    real4 k1 = mix(real4(1), max(real4(0), real(0.75) * (real4(1) - t1 * t1)), pr.m1);
    real k8 = pr.m8 ? max(real(0), real(0.75) * (real(1) - t8 * t8)) : real(1);
    return ((k0.x * k0.y) * (k0.z * k0.w)) * ((k1.x * k1.y) * (k1.z * k1.w)) * k8;
}

// wlr_kernel for k <= 3, with the same products (the factors of components
// >= k are exactly 1): t1 and t8 are not needed.
real wlr_kernel3(TsvdProj pr, real4 t0)
{
    real4 k0 = mix(real4(1), max(real4(0), real(0.75) * (real4(1) - t0 * t0)), pr.m0);
    return ((k0.x * k0.y) * (k0.z * k0.w)) * ((real(1) * real(1)) * (real(1) * real(1))) * real(1);
}

// --- rank classes -------------------------------------------------------------
// Most pixels have k <= 3 (88 % of WLR's at 512^2 on the built-in mix scene),
// where every design component beyond dz_3 is exactly 0. Each loop over the
// window that builds on the local coordinates comes twice: a short one for
// k <= 3 (only the non-zero blocks, dz_1..4 only) and the general one. A
// pixel runs exactly one of the two (the other's row range is empty), and
// each of its sums takes the same terms in the same order either way, so
// the output is the same. The point is lavapipe (Mesa 22.3), which runs both
// sides of every branch under a lane mask (gallivm's if_cond only pushes a
// mask) but leaves a loop once no lane of the SIMD vector iterates: where
// all 8 lanes have k <= 3 the general loop costs one idle iteration. On a
// GPU with uniform branches the two loops cost what one does.

// --- curvature fit (step 4) -------------------------------------------------

// --- masked block Cholesky ---------------------------------------------------
// The normal matrices are accumulated as 4x4 blocks (a, b), a <= b, of a
// padded design whose unused components (beyond k, and padding) are exactly
// zero. They are factored here with constant indices only (lavapipe compiles
// dynamically indexed local arrays into code proportional to their size):
// A + Lambda = U^T U with U block upper triangular, right-looking. An
// inactive component gets diagonal 1 (its row and column are zero), so the
// active components see exactly the pivots, in the same order, of the
// Cholesky of the compact p x p system that linalg.glsl's wls_factor (and the
// twin's ridge_cholesky) factor; the RIDGE and SOLVE-FAIL rules of §0.5 are
// applied over the active components (wlr_ridge_attempt).

// In place: the upper Cholesky factor of the symmetric block D (upper
// triangle read; D = U^T U, lower part zeroed). Pivots of active components
// must be > thr and finite; inactive ones are taken as 1.
bool wlr_chol4(inout realmat4 D, bvec4 act, real thr)
{
    // D[c][r] is element (r, c).
    bool ok = true;
    real p0 = act.x ? D[0][0] : real(1);
    ok = ok && p0 > thr && !isinf(p0);
    real u00 = sqrt(max(p0, real(0)));
    real u01 = D[1][0] / u00;
    real u02 = D[2][0] / u00;
    real u03 = D[3][0] / u00;
    real p1 = act.y ? D[1][1] - u01 * u01 : real(1);
    ok = ok && p1 > thr && !isinf(p1);
    real u11 = sqrt(max(p1, real(0)));
    real u12 = (D[2][1] - u01 * u02) / u11;
    real u13 = (D[3][1] - u01 * u03) / u11;
    real p2 = act.z ? D[2][2] - u02 * u02 - u12 * u12 : real(1);
    ok = ok && p2 > thr && !isinf(p2);
    real u22 = sqrt(max(p2, real(0)));
    real u23 = (D[3][2] - u02 * u03 - u12 * u13) / u22;
    real p3 = act.w ? D[3][3] - u03 * u03 - u13 * u13 - u23 * u23 : real(1);
    ok = ok && p3 > thr && !isinf(p3);
    real u33 = sqrt(max(p3, real(0)));
    D = realmat4(u00, real(0), real(0), real(0),
                 u01, u11, real(0), real(0),
                 u02, u12, u22, real(0),
                 u03, u13, u23, u33);
    return ok;
}

// U^{-T} X for an upper-triangular block U (forward substitution on rows).
realmat4 wlr_solve_ut(realmat4 U, realmat4 X)
{
    realmat4 Xt = transpose(X);  // Xt[r] = row r of X
    real4 y0 = Xt[0] / U[0][0];
    real4 y1 = (Xt[1] - U[1][0] * y0) / U[1][1];
    real4 y2 = (Xt[2] - U[2][0] * y0 - U[2][1] * y1) / U[2][2];
    real4 y3 = (Xt[3] - U[3][0] * y0 - U[3][1] * y1 - U[3][2] * y2) / U[3][3];
    return transpose(realmat4(y0, y1, y2, y3));
}

// U^{-T} v.
real4 wlr_solve_ut_v(realmat4 U, real4 v)
{
    real y0 = v.x / U[0][0];
    real y1 = (v.y - U[1][0] * y0) / U[1][1];
    real y2 = (v.z - U[2][0] * y0 - U[2][1] * y1) / U[2][2];
    real y3 = (v.w - U[3][0] * y0 - U[3][1] * y1 - U[3][2] * y2) / U[3][3];
    return real4(y0, y1, y2, y3);
}

// U^{-1} v (back substitution).
real4 wlr_solve_u_v(realmat4 U, real4 v)
{
    real x3 = v.w / U[3][3];
    real x2 = (v.z - U[3][2] * x3) / U[2][2];
    real x1 = (v.y - U[2][1] * x2 - U[3][1] * x3) / U[1][1];
    real x0 = (v.x - U[1][0] * x1 - U[2][0] * x2 - U[3][0] * x3) / U[0][0];
    return real4(x0, x1, x2, x3);
}

// Diagonal of a block as a vector.
real4 wlr_diag(realmat4 D)
{
    return real4(D[0][0], D[1][1], D[2][2], D[3][3]);
}

// Sets the diagonal of block D to d.
void wlr_set_diag(inout realmat4 D, real4 d)
{
    D[0][0] = d.x;
    D[1][1] = d.y;
    D[2][2] = d.z;
    D[3][3] = d.w;
}

// Regularised diagonal of one block for attempt `attempt`: active and
// ridged (all but the intercept) components get + lambda, inactive ones 1.
real4 wlr_ridge_diag(real4 d, bvec4 act, bvec4 ridged, real lambda)
{
    return mix(real4(1), d + mix(real4(0), real4(lambda), ridged), act);
}

// The RIDGE / SOLVE-FAIL bookkeeping of §0.5 for NB diagonal blocks: the
// ridge of this attempt (raised from the second attempt on) and the pivot
// threshold EPS_PIVOT * max diag(A + Lambda) over the active components.
// dsum/dcnt: sum and count of the active unregularised diagonal; dmax0/
// dmaxr: max active diagonal without / with ridge candidates.
#define WLR_RIDGE_STEP(attempt, lambda, mean_diag)                                   \
    if ((attempt) > 0) {                                                             \
        lambda = max(real(10) * lambda, real(RIDGE_FLOOR) * (mean_diag));            \
    }

// Active components of the 12-vector (1, dz_1..dz_9, pad, pad): f <= k.
bvec4 wlr_act12(int blk, int k)
{
    return lessThanEqual(ivec4(4 * blk) + ivec4(0, 1, 2, 3), ivec4(k));
}

// Active components of the 20-vector (1, dz_1..dz_9, dz_1^2..dz_9^2, pad).
bvec4 wlr_act20(int blk, int k)
{
    ivec4 f = ivec4(4 * blk) + ivec4(0, 1, 2, 3);
    return bvec4(f.x <= 9 ? f.x <= k : f.x - 10 < k && f.x < 19,
                 f.y <= 9 ? f.y <= k : f.y - 10 < k && f.y < 19,
                 f.z <= 9 ? f.z <= k : f.z - 10 < k && f.z < 19,
                 f.w <= 9 ? f.w <= k : f.w - 10 < k && f.w < 19);
}

// Factors the 12 x 12 system of a local linear fit (blocks B[6]: (0,0),
// (0,1), (0,2), (1,1), (1,2), (2,2)) with the RIDGE / SOLVE-FAIL rules; on
// success B holds U. Returns false after SOLVE_RETRIES failed retries.
bool wlr_factor12(inout realmat4 B[6], int k, real lambda)
{
    bvec4 act0 = wlr_act12(0, k);
    bvec4 act1 = wlr_act12(1, k);
    bvec4 act2 = wlr_act12(2, k);
    bvec4 rid0 = bvec4(false, act0.yzw);
    real4 d0 = wlr_diag(B[0]);
    real4 d1 = wlr_diag(B[3]);
    real4 d2 = wlr_diag(B[5]);
    real4 z = real4(0);
    real4 dact = mix(z, d0, act0) + mix(z, d1, act1) + mix(z, d2, act2);
    real mean_diag = (dact.x + dact.y + dact.z + dact.w) / real(k + 1);
    for (int attempt = 0; attempt <= SOLVE_RETRIES; ++attempt) {
        WLR_RIDGE_STEP(attempt, lambda, mean_diag)
        real4 e0 = wlr_ridge_diag(d0, act0, rid0, lambda);
        real4 e1 = wlr_ridge_diag(d1, act1, act1, lambda);
        real4 e2 = wlr_ridge_diag(d2, act2, act2, lambda);
        real4 m = max(mix(z, e0, act0), max(mix(z, e1, act1), mix(z, e2, act2)));
        real thr = real(EPS_PIVOT) * max(max(m.x, m.y), max(m.z, m.w));
        realmat4 U0 = B[0];
        realmat4 U1 = B[1];
        realmat4 U2 = B[2];
        realmat4 U3 = B[3];
        realmat4 U4 = B[4];
        realmat4 U5 = B[5];
        wlr_set_diag(U0, e0);
        wlr_set_diag(U3, e1);
        wlr_set_diag(U5, e2);
        bool ok = wlr_chol4(U0, act0, thr);
        U1 = wlr_solve_ut(U0, U1);
        U2 = wlr_solve_ut(U0, U2);
        U3 -= transpose(U1) * U1;
        U4 -= transpose(U1) * U2;
        U5 -= transpose(U2) * U2;
        ok = wlr_chol4(U3, act1, thr) && ok;
        U4 = wlr_solve_ut(U3, U4);
        U5 -= transpose(U4) * U4;
        ok = wlr_chol4(U5, act2, thr) && ok;
        if (ok) {
            B[0] = U0;
            B[1] = U1;
            B[2] = U2;
            B[3] = U3;
            B[4] = U4;
            B[5] = U5;
            return true;
        }
    }
    return false;
}

// The first column u = (A + Lambda)^{-1} e_1 from the factor of wlr_factor12.
void wlr_first_column12(realmat4 U[6], out real4 u0, out real4 u1, out real4 u2)
{
    real4 z0 = wlr_solve_ut_v(U[0], real4(1, 0, 0, 0));
    real4 z1 = wlr_solve_ut_v(U[3], -(z0 * U[1]));
    real4 z2 = wlr_solve_ut_v(U[5], -(z0 * U[2]) - z1 * U[4]);
    u2 = wlr_solve_u_v(U[5], z2);
    u1 = wlr_solve_u_v(U[3], z1 - U[4] * u2);
    u0 = wlr_solve_u_v(U[0], z0 - U[1] * u1 - U[2] * u2);
}

// Factors the 20 x 20 curvature system (15 blocks (a, b), a <= b, row
// order) like wlr_factor12; on success M holds U.
bool wlr_factor20(inout realmat4 M[15], int k, real lambda)
{
    bvec4 act[5];
    real4 d[5];
    real4 z = real4(0);
    real4 dact = z;
    for (int b = 0; b < 5; ++b) {
        act[b] = wlr_act20(b, k);
    }
    d[0] = wlr_diag(M[0]);
    d[1] = wlr_diag(M[5]);
    d[2] = wlr_diag(M[9]);
    d[3] = wlr_diag(M[12]);
    d[4] = wlr_diag(M[14]);
    for (int b = 0; b < 5; ++b) {
        dact += mix(z, d[b], act[b]);
    }
    real mean_diag = (dact.x + dact.y + dact.z + dact.w) / real(1 + 2 * k);
    for (int attempt = 0; attempt <= SOLVE_RETRIES; ++attempt) {
        WLR_RIDGE_STEP(attempt, lambda, mean_diag)
        real4 e[5];
        real4 m = z;
        for (int b = 0; b < 5; ++b) {
            bvec4 rid = b == 0 ? bvec4(false, act[0].yzw) : act[b];
            e[b] = wlr_ridge_diag(d[b], act[b], rid, lambda);
            m = max(m, mix(z, e[b], act[b]));
        }
        real thr = real(EPS_PIVOT) * max(max(m.x, m.y), max(m.z, m.w));
        realmat4 U[15] = M;
        wlr_set_diag(U[0], e[0]);
        wlr_set_diag(U[5], e[1]);
        wlr_set_diag(U[9], e[2]);
        wlr_set_diag(U[12], e[3]);
        wlr_set_diag(U[14], e[4]);
        // block column 0
        bool ok = wlr_chol4(U[0], act[0], thr);
        U[1] = wlr_solve_ut(U[0], U[1]);
        U[2] = wlr_solve_ut(U[0], U[2]);
        U[3] = wlr_solve_ut(U[0], U[3]);
        U[4] = wlr_solve_ut(U[0], U[4]);
        U[5] -= transpose(U[1]) * U[1];
        U[6] -= transpose(U[1]) * U[2];
        U[7] -= transpose(U[1]) * U[3];
        U[8] -= transpose(U[1]) * U[4];
        U[9] -= transpose(U[2]) * U[2];
        U[10] -= transpose(U[2]) * U[3];
        U[11] -= transpose(U[2]) * U[4];
        U[12] -= transpose(U[3]) * U[3];
        U[13] -= transpose(U[3]) * U[4];
        U[14] -= transpose(U[4]) * U[4];
        // block column 1
        ok = wlr_chol4(U[5], act[1], thr) && ok;
        U[6] = wlr_solve_ut(U[5], U[6]);
        U[7] = wlr_solve_ut(U[5], U[7]);
        U[8] = wlr_solve_ut(U[5], U[8]);
        U[9] -= transpose(U[6]) * U[6];
        U[10] -= transpose(U[6]) * U[7];
        U[11] -= transpose(U[6]) * U[8];
        U[12] -= transpose(U[7]) * U[7];
        U[13] -= transpose(U[7]) * U[8];
        U[14] -= transpose(U[8]) * U[8];
        // block column 2
        ok = wlr_chol4(U[9], act[2], thr) && ok;
        U[10] = wlr_solve_ut(U[9], U[10]);
        U[11] = wlr_solve_ut(U[9], U[11]);
        U[12] -= transpose(U[10]) * U[10];
        U[13] -= transpose(U[10]) * U[11];
        U[14] -= transpose(U[11]) * U[11];
        // block columns 3, 4
        ok = wlr_chol4(U[12], act[3], thr) && ok;
        U[13] = wlr_solve_ut(U[12], U[13]);
        U[14] -= transpose(U[13]) * U[13];
        ok = wlr_chol4(U[14], act[4], thr) && ok;
        if (ok) {
            M = U;
            return true;
        }
    }
    return false;
}

// Solves U^T U x = r for the factor of wlr_factor20 and returns the
// quadratic part (x_10..x_18) as q0 = x_10..11 (in .xy), q1 = x_12..15,
// q2 = x_16..18 (in .xyz).
void wlr_solve20_quadratic(realmat4 U[15], real4 r[5], out real4 q0, out real4 q1, out real4 q2)
{
    real4 z0 = wlr_solve_ut_v(U[0], r[0]);
    real4 z1 = wlr_solve_ut_v(U[5], r[1] - z0 * U[1]);
    real4 z2 = wlr_solve_ut_v(U[9], r[2] - z0 * U[2] - z1 * U[6]);
    real4 z3 = wlr_solve_ut_v(U[12], r[3] - z0 * U[3] - z1 * U[7] - z2 * U[10]);
    real4 z4 = wlr_solve_ut_v(U[14], r[4] - z0 * U[4] - z1 * U[8] - z2 * U[11] - z3 * U[13]);
    real4 x4 = wlr_solve_u_v(U[14], z4);
    real4 x3 = wlr_solve_u_v(U[12], z3 - U[13] * x4);
    real4 x2 = wlr_solve_u_v(U[9], z2 - U[10] * x3 - U[11] * x4);
    q0 = real4(x2.zw, real(0), real(0));
    q1 = x3;
    q2 = real4(x4.xyz, real(0));
}

// A valid neighbour q of the curvature fit: raw features, centred colour
// y - y_c (only the intercept changes, and the f32 normal equations lose
// less to cancellation) and the outlier weight o_q.
bool wlr_curvature_neighbour(WlrCentre cc, ivec2 q, uint options, out real x[MAX_D], out real3 y,
                             out real w)
{
    real e2[MAX_D];
    y = real3(0);
    w = real(0);
    if (!load_features(q, x, e2)) {
        return false;
    }
    real vb;
    load_colour(q, y, vb);
    w = wlr_outlier_weight(vb, options);
    y -= cc.y;
    return true;
}

// Step 4: weighted quadratic fit (1, dz, dz o dz), weights o_i prod K_E(dz_ij),
// ridge 1e-3, per channel; b_j = (Hbar_j + 0.64)^(-1/2) for j < k, 0 beyond.
// Returns false on SOLVE-FAIL (b = 0). No rejection in this fit.
bool wlr_curvature(TsvdProj pr, WlrCentre cc, int R, ivec2 size, uint options,
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
    // k <= 3: the design (1, dz_1..3, dz_1^2..3^2) has non-zero blocks 0,
    // 2, 3, 9, 10, 12 only (see "rank classes" above); the general loop
    // below gives the same sums.
    int end = up.y + 1;
    int lo3 = pr.k <= 3 ? lo.y : end;
    int lo9 = pr.k <= 3 ? end : lo.y;
    // Their non-zero entries come from A = (1, dz_1..3) and B = (dz_1^2..3^2,
    // 0): three outer products (AA, AB, BB) and two right-hand sides per
    // channel, each entry the same products summed in the same order as
    // the general loop's; scattered into the blocks after the loop.
    realmat4 AA = realmat4(0);
    realmat4 AB = realmat4(0);
    realmat4 BB = realmat4(0);
    real4 YA[3] = real4[3](real4(0), real4(0), real4(0));
    real4 YB[3] = real4[3](real4(0), real4(0), real4(0));
    for (int qy = lo3; qy < end; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            real x[MAX_D];
            real3 y;
            real w;
            if (!wlr_curvature_neighbour(cc, ivec2(qx, qy), options, x, y, w)) {
                continue;
            }
            real4 d0 = tsvd_dz0(pr, cc.x, x);
            w *= wlr_kernel3(pr, d0);
            if (w > real(0)) {
                real4 s0 = d0 * d0;
                real4 A = real4(real(1), d0.xyz);
                real4 B = real4(s0.xyz, real(0));
                real4 WA = w * A;
                real4 WB = w * B;
                AA += outerProduct(WA, A);
                AB += outerProduct(WA, B);
                BB += outerProduct(WB, B);
                YA[0] += y.r * WA;
                YB[0] += y.r * WB;
                YA[1] += y.g * WA;
                YB[1] += y.g * WB;
                YA[2] += y.b * WA;
                YB[2] += y.b * WB;
            }
        }
    }
    if (pr.k <= 3) {
        // Design layout (1, dz_1..9, dz_1^2..9^2, pad): dz_1^2, dz_2^2 are
        // components 10, 11 (block 2, lanes z, w), dz_3^2 is 12 (block 3,
        // lane x). M[c][r] is entry (r, c).
        real4 z = real4(0);
        M[0] = AA;
        M[2] = realmat4(z, z, AB[0], AB[1]);
        M[3] = realmat4(AB[2], z, z, z);
        M[9] = realmat4(z, z, real4(real(0), real(0), BB[0].xy), real4(real(0), real(0), BB[1].xy));
        M[10] = realmat4(real4(real(0), real(0), BB[2].xy), z, z, z);
        M[12] = realmat4(real4(BB[2].z, real(0), real(0), real(0)), z, z, z);
        for (int ch = 0; ch < 3; ++ch) {
            Y[ch * 5 + 0] = YA[ch];
            Y[ch * 5 + 2] = real4(real(0), real(0), YB[ch].xy);
            Y[ch * 5 + 3] = real4(YB[ch].z, real(0), real(0), real(0));
        }
    }
    for (int qy = lo9; qy < end; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            real x[MAX_D];
            real3 y;
            real w;
            if (!wlr_curvature_neighbour(cc, ivec2(qx, qy), options, x, y, w)) {
                continue;
            }
            real4 d0;
            real4 d1;
            real d8;
            tsvd_dz(pr, cc.x, x, d0, d1, d8);
            w *= wlr_kernel(pr, d0, d1, d8);
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
                // Blocks with X1 (dz_4..7) vanish for k <= 3, with X4
                // (dz_7^2..9^2) for k <= 6: skipped (exactly zero).
                M[0] += outerProduct(W0, X0);
                M[2] += outerProduct(W0, X2);
                M[3] += outerProduct(W0, X3);
                M[9] += outerProduct(W2, X2);
                M[10] += outerProduct(W2, X3);
                M[12] += outerProduct(W3, X3);
                Y[0] += y.r * W0;
                Y[2] += y.r * W2;
                Y[3] += y.r * W3;
                Y[5] += y.g * W0;
                Y[7] += y.g * W2;
                Y[8] += y.g * W3;
                Y[10] += y.b * W0;
                Y[12] += y.b * W2;
                Y[13] += y.b * W3;
                if (pr.k > 3) {
                    M[1] += outerProduct(W0, X1);
                    M[5] += outerProduct(W1, X1);
                    M[6] += outerProduct(W1, X2);
                    M[7] += outerProduct(W1, X3);
                    Y[1] += y.r * W1;
                    Y[6] += y.g * W1;
                    Y[11] += y.b * W1;
                }
                if (pr.k > 6) {
                    M[4] += outerProduct(W0, X4);
                    M[8] += outerProduct(W1, X4);
                    M[11] += outerProduct(W2, X4);
                    M[13] += outerProduct(W3, X4);
                    M[14] += outerProduct(W4, X4);
                    Y[4] += y.r * W4;
                    Y[9] += y.g * W4;
                    Y[14] += y.b * W4;
                }
            }
        }
    }

    // Factor, then per channel the quadratic coefficients gamma_j (step 4).
    int k = pr.k;
    if (!wlr_factor20(M, k, real(WLR_CURV_LAMBDA))) {
        return false;
    }
    real4 h0 = real4(0);
    real4 h1 = real4(0);
    real4 h2 = real4(0);
    for (int ch = 0; ch < 3; ++ch) {
        real4 r[5];
        for (int a = 0; a < 5; ++a) {
            r[a] = Y[ch * 5 + a];
        }
        real4 q0;
        real4 q1;
        real4 q2;
        wlr_solve20_quadratic(M, r, q0, q1, q2);
        h0 += abs(real(2) * q0) / real(3);
        h1 += abs(real(2) * q1) / real(3);
        h2 += abs(real(2) * q2) / real(3);
    }
    real Hv[9] = real[9](h0.x, h0.y, h1.x, h1.y, h1.z, h1.w, h2.x, h2.y, h2.z);
    for (int j = 0; j < 9; ++j) {  // b[9] (WLR_VIS) stays 0: k <= 9
        Hb[j] = j < k ? Hv[j] : real(0);
        b[j] = j < k ? real(1) / sqrt(Hv[j] + real(WLR_BETA0)) : real(0);
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

// Solve of fit s (a literal): factor its 6 blocks and take the first column
// of the inverse; FEW / SOLVE-FAIL set the fit's flags.
#define WLR_SOLVE(s)                                                                 \
    if (cnt[s] <= 1) {                                                               \
        fit[s].flags |= WLR_F_FEW;                                                   \
    } else {                                                                         \
        realmat4 B[6];                                                               \
        for (int bi = 0; bi < 6; ++bi) {                                             \
            B[bi] = T[6 * (s) + bi];                                                 \
        }                                                                            \
        if (!wlr_factor12(B, k, lambda)) {                                           \
            fit[s].flags |= WLR_F_SOLVE_FAIL;                                        \
        } else {                                                                     \
            wlr_first_column12(B, U0[s], U1[s], U2[s]);                              \
            any_solved = true;                                                       \
        }                                                                            \
    }

// Per-neighbour data shared by the two passes of wlr_fits: base weight
// acc_i o_i (0 = skip), raw features, colour, vbar.
bool wlr_fit_accept(WlrCentre cc, ivec2 q, uint options, out real base, out real x[MAX_D],
                    out real3 y, out real vb)
{
    real e2[MAX_D];
    base = real(0);
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
    y -= cc.y;  // centred responses (see wlr_fits)
    return base > real(0);
}

// wlr_fit_accept and the local coordinates.
bool wlr_fit_neighbour(TsvdProj pr, WlrCentre cc, ivec2 q, uint options,
                       out real base, out real4 d0, out real4 d1, out real d8,
                       out real3 y, out real vb)
{
    real x[MAX_D];
    d0 = real4(0);
    d1 = real4(0);
    d8 = real(0);
    if (!wlr_fit_accept(cc, q, options, base, x, y, vb)) {
        return false;
    }
    tsvd_dz(pr, cc.x, x, d0, d1, d8);
    return true;
}

// The same for k <= 3: dz_1..4 only (the rest is 0).
bool wlr_fit_neighbour3(TsvdProj pr, WlrCentre cc, ivec2 q, uint options,
                        out real base, out real4 d0, out real3 y, out real vb)
{
    real x[MAX_D];
    d0 = real4(0);
    if (!wlr_fit_accept(cc, q, options, base, x, y, vb)) {
        return false;
    }
    d0 = tsvd_dz0(pr, cc.x, x);
    return true;
}

// Pass A body for bandwidth s (a literal): weight, count, normal matrix
// (blocks with X1 = dz_4..7 vanish for k <= 3, with X2 = dz_8..9 for k <= 7).
#define WLR_PASS_A(s)                                                               \
    {                                                                               \
        real w = base * wlr_kernel(pr, d0 * I0[s], d1 * I1[s], d8 * I8[s]);         \
        if (w > real(0)) {                                                          \
            cnt[s] += 1;                                                            \
            real4 W0 = w * X0;                                                      \
            real4 W1 = w * X1;                                                      \
            real4 W2 = w * X2;                                                      \
            T[6 * s + 0] += outerProduct(W0, X0);                                   \
            if (k > 3) {                                                            \
                T[6 * s + 1] += outerProduct(W0, X1);                               \
                T[6 * s + 3] += outerProduct(W1, X1);                               \
                if (k > 7) {                                                        \
                    T[6 * s + 2] += outerProduct(W0, X2);                           \
                    T[6 * s + 4] += outerProduct(W1, X2);                           \
                    T[6 * s + 5] += outerProduct(W2, X2);                           \
                }                                                                   \
            }                                                                       \
        }                                                                           \
    }

// Pass A for k <= 3: block (0, 0) only (the others stay exactly 0).
#define WLR_PASS_A3(s)                                                              \
    {                                                                               \
        real w = base * wlr_kernel3(pr, d0 * I0[s]);                                \
        if (w > real(0)) {                                                          \
            cnt[s] += 1;                                                            \
            real4 W0 = w * X0;                                                      \
            T[6 * s + 0] += outerProduct(W0, X0);                                   \
        }                                                                           \
    }

// Pass B for k <= 3 (u's components beyond dz_3 are exactly 0).
#define WLR_PASS_B3(s)                                                              \
    {                                                                               \
        real w = base * wlr_kernel3(pr, d0 * I0[s]);                                \
        if (w > real(0)) {                                                          \
            real l = w * dot(U0[s], X0);                                            \
            real lp = max(l, real(0));                                              \
            S1[s] += real4(l * y, l * l * vb);  /* y centred */                     \
            S2[s] += real4(lp * y, lp * lp * vb);                                   \
            S3[s] += lp;                                                            \
        }                                                                           \
    }

// Pass B body for bandwidth s: l_i = w_i u^T x_i and the sums of step 5.
#define WLR_PASS_B(s)                                                               \
    {                                                                               \
        real w = base * wlr_kernel(pr, d0 * I0[s], d1 * I1[s], d8 * I8[s]);         \
        if (w > real(0)) {                                                          \
            real l = w * (dot(U0[s], X0) + dot(U1[s], X1) + dot(U2[s], X2));        \
            real lp = max(l, real(0));                                              \
            S1[s] += real4(l * y, l * l * vb);  /* y centred */                     \
            S2[s] += real4(lp * y, lp * lp * vb);                                   \
            S3[s] += lp;                                                            \
        }                                                                           \
    }

// PASS (a literal, WLR_PASS_A3 ... WLR_PASS_B) for every fit.
#if WLR_NFIT > 1
#define WLR_EACH_FIT(PASS) PASS(0) PASS(1) PASS(2) PASS(3) PASS(4)
#else
#define WLR_EACH_FIT(PASS) PASS(0)
#endif

// The k <= 3 loop of wlr_fits over the rows [lo3, end) of the window, with
// PASS (WLR_PASS_A3 or WLR_PASS_B3) per neighbour and fit.
#define WLR_LOOP3(PASS)                                                             \
    for (int qy = lo3; qy < end; ++qy) {                                            \
        for (int qx = lo.x; qx <= up.x; ++qx) {                                     \
            real base;                                                              \
            real4 d0;                                                               \
            real3 y;                                                                \
            real vb;                                                                \
            if (!wlr_fit_neighbour3(pr, cc, ivec2(qx, qy), options, base, d0, y, vb)) { \
                continue;                                                           \
            }                                                                       \
            real4 X0 = real4(real(1), d0.xyz);                                      \
            WLR_EACH_FIT(PASS)                                                      \
        }                                                                           \
    }

// The general loop over the rows [lo9, end), with PASS (WLR_PASS_A or
// WLR_PASS_B).
#define WLR_LOOP9(PASS)                                                             \
    for (int qy = lo9; qy < end; ++qy) {                                            \
        for (int qx = lo.x; qx <= up.x; ++qx) {                                     \
            real base;                                                              \
            real4 d0;                                                               \
            real4 d1;                                                               \
            real d8;                                                                \
            real3 y;                                                                \
            real vb;                                                                \
            if (!wlr_fit_neighbour(pr, cc, ivec2(qx, qy), options, base, d0, d1, d8, y, vb)) { \
                continue;                                                           \
            }                                                                       \
            real4 X0 = real4(real(1), d0.xyz);                                      \
            real4 X1 = real4(d0.w, d1.xyz);                                         \
            real4 X2 = real4(d1.w, d8, real(0), real(0));                           \
            WLR_EACH_FIT(PASS)                                                      \
        }                                                                           \
    }

// Steps 5 / 9: local linear fits (1, dz) (p = k+1, ridge `lambda`) at the
// WLR_NFIT bandwidths h[s], weights acc_i o_i prod_j K_E(dz_ij / (h_s b_j)).
// FEW (<= 1 positive weight) and SOLVE-FAIL give f = y_c, bias 0, var vbar_c
// (flag bits 1 / 0); NONNEG when the option is on. b_j > 0 for j < k.
void wlr_fits(TsvdProj pr, WlrCentre cc, real b[MAX_D], real h[WLR_NFIT], int R, ivec2 size,
              uint options, real lambda, out WlrFit fit[WLR_NFIT])
{
    int k = pr.k;
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

    // Rows of the k <= 3 loops and of the general ones: one range is empty
    // (see "rank classes" above).
    int end = up.y + 1;
    int lo3 = k <= 3 ? lo.y : end;
    int lo9 = k <= 3 ? end : lo.y;

    // Pass A: normal matrices and positive-weight counts.
    WLR_LOOP3(WLR_PASS_A3)
    WLR_LOOP9(WLR_PASS_A)

    // Solves: u_s = (A_s + Lambda)^{-1} e_1.
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
    }
    WLR_SOLVE(0)
#if WLR_NFIT > 1
    WLR_SOLVE(1)
    WLR_SOLVE(2)
    WLR_SOLVE(3)
    WLR_SOLVE(4)
#endif
    if (!any_solved) {
        return;
    }

    // Pass B: equivalent kernels and the sums of step 5.
    real4 S1[WLR_NFIT];  // sum l (y - y_c), sum l^2 vbar
    real4 S2[WLR_NFIT];  // sum l+ (y - y_c), sum l+^2 vbar
    real S3[WLR_NFIT];   // sum l+
    for (int s = 0; s < WLR_NFIT; ++s) {
        S1[s] = real4(0);
        S2[s] = real4(0);
        S3[s] = real(0);
    }
    WLR_LOOP3(WLR_PASS_B3)
    WLR_LOOP9(WLR_PASS_B)
    for (int s = 0; s < WLR_NFIT; ++s) {
        if (fit[s].flags != 0) {
            continue;  // FEW or SOLVE-FAIL: y_c, bias 0, var vbar_c
        }
        // delta = f-hat - y_c = sum_i l_i (y_i - y_c), exact because sum l = 1.
        real3 delta = S1[s].xyz;
        real var = S1[s].w;
        if ((options & WLR_NONNEG) != 0u && any(lessThan(cc.y + delta, real3(0)))) {
            real sp = S3[s];
            real den = max(sp, real(WLR_NONNEG_FLOOR));
            delta = sp >= real(WLR_NONNEG_FLOOR) ? S2[s].xyz / sp
                                                 : (S2[s].xyz + cc.y * sp) / den - cc.y;
            delta = max(delta, -cc.y);  // clamp f-hat >= 0
            var = S2[s].w / (den * den);
        }
        fit[s].f = cc.y + delta;
        fit[s].var = var;
        fit[s].bias = (delta.r + delta.g + delta.b) / real(3);
    }
}

#ifndef MC_DD
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
#endif

#ifdef MC_DD
// --- steps 6-7 and 10 in double-float (the `_dd` variant, lib/dd.glsl) ----------
// The same formulas as the double functions above, for devices without
// shaderFloat64.
#include "lib/dd.glsl"

dd wlr_h_min_dd() { return dd_ratio(1.0, 100.0); }
dd wlr_h_max_dd() { return dd_from(1.0); }

dd wlr_trial_h_dd(int s) { return s == 4 ? dd_from(1.0) : dd_ratio(float(s + 1), 5.0); }

// (intercept, slope) of the least-squares line through the 5 points (t, u).
void wlr_simple_regression_dd(dd t[5], dd u[5], out dd intercept, out dd slope)
{
    dd five = dd_from(5.0);
    dd tm = dd_div(dd_add(dd_add(dd_add(dd_add(t[0], t[1]), t[2]), t[3]), t[4]), five);
    dd um = dd_div(dd_add(dd_add(dd_add(dd_add(u[0], u[1]), u[2]), u[3]), u[4]), five);
    dd stu = dd_from(0.0);
    dd stt = dd_from(0.0);
    for (int s = 0; s < 5; ++s) {
        dd dt = dd_sub(t[s], tm);
        stu = dd_add(stu, dd_mul(dt, dd_sub(u[s], um)));
        stt = dd_add(stt, dd_mul(dt, dt));
    }
    slope = dd_div(stu, stt);
    intercept = dd_sub(um, dd_mul(slope, tm));
}

// h^{-k} by repeated multiplication.
dd wlr_inv_pow_dd(dd h, int k)
{
    dd hk = dd_from(1.0);
    for (int i = 0; i < k; ++i) {
        hk = dd_mul(hk, h);
    }
    return dd_div(dd_from(1.0), hk);
}

// a^{1/m} for a in (0, 1]: float pow refined by Newton steps.
dd wlr_root_dd(dd a, int m)
{
    dd x = dd_from(pow(dd_to_float(a), 1.0 / float(m)));
    for (int it = 0; it < 4; ++it) {
        dd xm1 = dd_from(1.0);
        for (int i = 0; i < m - 1; ++i) {
            xm1 = dd_mul(xm1, x);
        }
        x = dd_sub(x, dd_div(dd_sub(dd_mul(x, xm1), a), dd_mul(dd_from(float(m)), xm1)));
    }
    return x;
}

// Step 6: par = (lambda0, lambda1, kappa0, kappa1).
void wlr_parametric_dd(dd bias[5], dd var[5], int k, dd n, out dd par[4])
{
    dd t2[5];
    dd tk[5];
    dd nv[5];
    for (int s = 0; s < 5; ++s) {
        dd h = wlr_trial_h_dd(s);
        t2[s] = dd_mul(h, h);
        tk[s] = wlr_inv_pow_dd(h, k);
        nv[s] = dd_mul(n, var[s]);
    }
    wlr_simple_regression_dd(t2, bias, par[0], par[1]);
    wlr_simple_regression_dd(tk, nv, par[2], par[3]);
}

// Step 7 with H-CASES (k >= 1): model = (h_opt, lambda1, kappa0, kappa1).
void wlr_choose_h_dd(dd par[4], int k, dd n, dd bias1, dd var1, inout int flags, out dd model[4])
{
    model[1] = par[1];
    model[2] = par[2];
    model[3] = par[3];
    if (!(dd_gt(par[3], dd_from(0.0)))) {
        flags |= WLR_F_KAPPA;
        model[0] = wlr_trial_h_dd(0);
        model[1] = dd_from(0.0);
        model[2] = dd_mul(n, dd_add(dd_mul(bias1, bias1), var1));
        model[3] = dd_from(0.0);
        return;
    }
    dd l2n = dd_mul(dd_mul(par[1], par[1]), n);
    if (dd_lt(l2n, dd_from(1e-30))  /* WLR_LAMBDA_TINY */) {
        model[0] = wlr_h_max_dd();
        return;
    }
    dd a = dd_div(dd_mul(dd_from(float(k)), par[3]), dd_mul(dd_from(4.0), l2n));
    int m = k + 4;
    dd lo = dd_div(dd_from(1.0), wlr_inv_pow_dd(wlr_h_min_dd(), m));  // H_MIN^m
    if (dd_gt(a, dd_from(1.0))) {
        model[0] = wlr_h_max_dd();
        flags |= WLR_F_CLAMPED;
    } else if (dd_lt(a, lo)) {
        model[0] = wlr_h_min_dd();
        flags |= WLR_F_CLAMPED;
    } else {
        model[0] = dd_clamp(wlr_root_dd(a, m), wlr_h_min_dd(), wlr_h_max_dd());
    }
}

// Step 10: (lambda1 h^2)^2 + (kappa0 + kappa1 h^-k)/n_c, clamped >= 0.
dd wlr_mse_model_dd(dd lambda1, dd kappa0, dd kappa1, int k, dd n, dd h)
{
    dd bb = dd_mul(dd_mul(lambda1, h), h);
    dd v = dd_div(dd_add(kappa0, dd_mul(kappa1, wlr_inv_pow_dd(h, k))), n);
    return dd_max(dd_add(dd_mul(bb, bb), v), dd_from(0.0));
}
#endif

// --- the centre state wlr_fit leaves for wlr_final -----------------------------
// wlr_final needs, per centre, the local space and the curvature bandwidths
// of wlr_fit (steps 1 and 4: the TSVD and the curvature fit are two thirds of
// a centre's work). wlr_fit stores them, wlr_final reads them back: the same
// values, so the same output as recomputing them. Per pixel WLR_STATE_VEC4
// real4 in `state`, declared by the kernel, which then defines WLR_STATE_OUT
// (wlr_fit: the store) or WLR_STATE_IN (wlr_final: the load):
//   [0, 9) P0[j], [9, 18) P1[j], 18 P8[0..4), 19 P8[4..8),
//   20 (P8[8], b_1, b_2, b_3), 21 (b_4..b_7), 22 (b_8, b_9, ok, P8[9]),
//   with WLR_VIS 23 P0[9], 24 P1[9] (the visibility's column),
// ok = 1 when the curvature fit succeeded. Pixel (x, y) lives in row
// y mod push.ring_rows of a ring of rows (src/methods/wlr.rs: the host runs
// wlr_fit a band of rows ahead of wlr_final).
#ifdef WLR_VIS
#define WLR_STATE_VEC4 25
#else
#define WLR_STATE_VEC4 23
#endif

#if defined(WLR_STATE_OUT) || defined(WLR_STATE_IN)

uint wlr_state_base(ivec2 c)
{
    return ((uint(c.y) % push.ring_rows) * push.width + uint(c.x)) * uint(WLR_STATE_VEC4);
}
#endif

#ifdef WLR_STATE_OUT
void wlr_state_store(ivec2 c, TsvdProj pr, real b[MAX_D], bool ok)
{
    uint s = wlr_state_base(c);
    for (int j = 0; j < 9; ++j) {
        state[s + j] = pr.P0[j];
        state[s + 9 + j] = pr.P1[j];
    }
    state[s + 18] = real4(pr.P8[0], pr.P8[1], pr.P8[2], pr.P8[3]);
    state[s + 19] = real4(pr.P8[4], pr.P8[5], pr.P8[6], pr.P8[7]);
    state[s + 20] = real4(pr.P8[8], b[0], b[1], b[2]);
    state[s + 21] = real4(b[3], b[4], b[5], b[6]);
#ifdef WLR_VIS
    state[s + 22] = real4(b[7], b[8], ok ? real(1) : real(0), pr.P8[9]);
    state[s + 23] = pr.P0[9];
    state[s + 24] = pr.P1[9];
#else
    state[s + 22] = real4(b[7], b[8], ok ? real(1) : real(0), real(0));
#endif
}
#endif // WLR_STATE_OUT

#ifdef WLR_STATE_IN

// The local space (rank k, from kflags) and b of centre c; false when the
// curvature fit failed (SOLVE-FAIL).
bool wlr_state_load(ivec2 c, int k, out TsvdProj pr, out real b[MAX_D])
{
    uint s = wlr_state_base(c);
    for (int j = 0; j < 9; ++j) {
        pr.P0[j] = state[s + j];
        pr.P1[j] = state[s + 9 + j];
    }
    real4 t18 = state[s + 18];
    real4 t19 = state[s + 19];
    real4 t20 = state[s + 20];
    real4 t21 = state[s + 21];
    real4 t22 = state[s + 22];
#ifdef WLR_VIS
    pr.P0[9] = state[s + 23];
    pr.P1[9] = state[s + 24];
    pr.P8 = real[10](t18.x, t18.y, t18.z, t18.w, t19.x, t19.y, t19.z, t19.w, t20.x, t22.w);
    b = real[10](t20.y, t20.z, t20.w, t21.x, t21.y, t21.z, t21.w, t22.x, t22.y, real(0));
#else
    pr.P8 = real[9](t18.x, t18.y, t18.z, t18.w, t19.x, t19.y, t19.z, t19.w, t20.x);
    b = real[9](t20.y, t20.z, t20.w, t21.x, t21.y, t21.z, t21.w, t22.x, t22.y);
#endif
    pr.k = k;
    pr.m0 = lessThan(ivec4(0, 1, 2, 3), ivec4(k));
    pr.m1 = lessThan(ivec4(4, 5, 6, 7), ivec4(k));
    pr.m8 = 8 < k;
    return t22.z != real(0);
}

#endif // WLR_STATE_IN

#endif // MC_WLR_GLSL
