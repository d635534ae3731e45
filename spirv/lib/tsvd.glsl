// Feature normalisation and TSVD local space (spec §0.6, [WLR §4 Eq.5-6, §7]),
// shared by the WLR, LP and AOS kernels. Scalar twin: src/reference/tsvd.rs.
//
// Feature hook. Before including this file the kernel may define the
// feature count TSVD_D (default 9; <= MAX_D) and shrink MAX_D (default 11,
// e.g. `#define MAX_D 9`). It must define, before or after the include (this
// file declares the prototype), the loader:
//
//     bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
//     {
//         // x[0..TSVD_D): raw features of pixel p (e.g. px, py, normal xyz,
//         //               depth, albedo rgb), e2: their variances of the mean
//         //               (0 for pixel coordinates).
//         return spp_of(spp[index]) >= 1.0;   // false: p is not in any window
//     }
//
// The routine calls load_features once per window pixel (twice in a window
// wide enough to overflow raw f32 co-moments, see TSVD_WIDE_RANGE).

#ifndef MC_TSVD_GLSL
#define MC_TSVD_GLSL

#include "lib/linalg.glsl"

#ifndef TSVD_D
#define TSVD_D 9
#endif
#if TSVD_D > MAX_D
#error "tsvd.glsl: TSVD_D exceeds MAX_D"
#endif
// The largest rank the kernel's local coordinates hold (default TSVD_D):
// a higher one is cut to it after MINRANK (WLR-VIS: 9 of 10 features).
#ifndef TSVD_MAX_RANK
#define TSVD_MAX_RANK TSVD_D
#endif

// Spec §0.6: constant-component range (natural units), tau = C ||E||_2,
// numerically-zero singular values, MINRANK.
#define TSVD_RANGE_EPS 1e-6
#define TSVD_TAU_C 2.0
#define TSVD_SIGMA_REL 1e-6
#define TSVD_MIN_RANK 2
// NOISE-CONST (reference::tsvd::NOISE_RANGE_C): a component whose window
// range is at most this times its RMS noise sqrt(mean e2) is constant.
#define TSVD_NOISE_RANGE_C 2.0

// The kernel's feature loader (see the top of this file).
bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D]);

// The TSVD local space of one window. Arrays hold TSVD_D (resp. TSVD_D^2)
// meaningful entries.
struct LocalSpace {
    int n;          // valid window pixels
    int k;          // rank after MINRANK (0 only if every component is constant)
    int k_nz;       // #{sigma_m > 1e-6 sigma_1}
    real tau;       // 2 ||E||_2
    real specnorm;  // ||E||_2: exact (SPECNORM) where it decides k, else an upper bound
    real sigma[MAX_D];        // sigma_1 >= ... >= sigma_D
    real V[MAX_D * MAX_D];    // row-major D x D (stride TSVD_D), column m = v_m
    real mn[MAX_D];           // window minimum m_j (raw units)
    real range[MAX_D];        // rho_j = M_j - m_j; constant if <= TSVD_RANGE_EPS
};

#if TSVD_D > 12
#error "tsvd.glsl: the block accumulation supports TSVD_D <= 12"
#endif

#ifdef MC_F64
#define tsvd_mat4 dmat4
#else
#define tsvd_mat4 mat4
#endif

// Macros rather than functions: array arguments would be copied in and
// out (and inout 81-entry copies cost compile time). Constant b/br/bc/l
// only, so every index is constant after unrolling.
//
// v = lanes [b, b+4) of the feature array a; lanes >= TSVD_D are 0.
#define TSVD_PACK4(v, a, b) \
    v = real4(0); \
    for (int i_ = 0; i_ < 4; ++i_) { \
        if ((b) + i_ < TSVD_D) { v[i_] = a[(b) + i_]; } \
    }
// a[b..] = lanes of v (lanes < TSVD_D only).
#define TSVD_UNPACK4(a, v, b) \
    for (int i_ = 0; i_ < 4; ++i_) { \
        if ((b) + i_ < TSVD_D) { a[(b) + i_] = v[i_]; } \
    }
// Block B (B[c][r] = M[br*4 + r][bc*4 + c]) of the symmetric matrix M
// (row-major, stride TSVD_D): upper triangle j <= l and its mirror.
#define TSVD_UNPACK_BLOCK(M, B, br, bc) \
    for (int r_ = 0; r_ < 4; ++r_) { \
        for (int c_ = 0; c_ < 4; ++c_) { \
            int j_ = (br) * 4 + r_; \
            int l_ = (bc) * 4 + c_; \
            if (j_ < TSVD_D && l_ < TSVD_D && j_ <= l_) { \
                M[j_ * TSVD_D + l_] = B[c_][r_]; \
                M[l_ * TSVD_D + j_] = B[c_][r_]; \
            } \
        } \
    }
// Column l of M, rows [br*4, br*4 + 4) from v (j <= l) and its mirror.
#define TSVD_UNPACK_COL(M, v, br, l) \
    for (int r_ = 0; r_ < 4; ++r_) { \
        int j_ = (br) * 4 + r_; \
        if (j_ < TSVD_D && j_ <= (l)) { \
            M[j_ * TSVD_D + (l)] = v[r_]; \
            M[(l) * TSVD_D + j_] = v[r_]; \
        } \
    }

// 1/rho per lane, or 0 for a constant component (rho <= TSVD_RANGE_EPS).
real4 tsvd_inv4(real4 rg)
{
    return mix(real4(0), real4(1) / rg, greaterThan(rg, real4(TSVD_RANGE_EPS)));
}

// NOISE-CONST's mask of a block: entries of columns or rows whose keep is 0
// become 0 by selection (not by multiplication, which would turn an
// overflowed inf into NaN where the twin has 0).
tsvd_mat4 tsvd_keep_block(tsvd_mat4 m, real4 krow, real4 kcol)
{
    for (int c_ = 0; c_ < 4; ++c_) {
        m[c_] = mix(real4(0), m[c_], greaterThan(krow * kcol[c_], real4(0)));
    }
    return m;
}
real4 tsvd_keep4(real4 v, real4 k) { return mix(real4(0), v, greaterThan(k, real4(0))); }

// Bounds on lambda_max of the D x D matrix A = E^T E (symmetric, no negative
// entry): TSVD_POWER_STEPS power iterations from the ones vector give v >= 0
// with max 1; with the positive p = v + 1e-3, lo = p^T A p / p^T p (a Rayleigh
// quotient never exceeds lambda_max) and hi = max_j (A p)_j / p_j (the
// Collatz-Wielandt bound of a non-negative matrix). Both 0 for A = 0.
#define TSVD_POWER_STEPS 6
#define TSVD_BOUND_MARGIN 1e-4
void tsvd_lmax_bounds(real A[MAX_D * MAX_D], out real lo, out real hi)
{
    real v[MAX_D];
    real u[MAX_D];
    for (int j = 0; j < MAX_D; ++j) {
        v[j] = j < TSVD_D ? real(1) : real(0);
        u[j] = real(0);
    }
    for (int it = 0; it <= TSVD_POWER_STEPS; ++it) {
        if (it == TSVD_POWER_STEPS) {
            // The final vector (max 1), made positive.
            for (int j = 0; j < TSVD_D; ++j) {
                v[j] += real(1e-3);
            }
        }
        real mx = real(0);
        for (int j = 0; j < TSVD_D; ++j) {
            real s = real(0);
            for (int l = 0; l < TSVD_D; ++l) {
                s += A[j * TSVD_D + l] * v[l];
            }
            u[j] = s;
            mx = max(mx, s);
        }
        if (it == TSVD_POWER_STEPS) {
            break;
        }
        if (mx <= real(0)) {
            lo = real(0);
            hi = real(0);
            return;
        }
        for (int j = 0; j < TSVD_D; ++j) {
            v[j] = u[j] / mx;
        }
    }
    real pap = real(0), pp = real(0);
    hi = real(0);
    for (int j = 0; j < TSVD_D; ++j) {
        pap += v[j] * u[j];
        pp += v[j] * v[j];
        hi = max(hi, u[j] / v[j]);
    }
    lo = pap / pp;
}

// Scales block m (m[c][r] = M[4a + r][4b + c]) to M_jl inv_j inv_l: the
// column factor first, then the row's, so that two small factors do not
// underflow as a product.
tsvd_mat4 tsvd_scale_block(tsvd_mat4 m, real4 inv_row, real4 inv_col)
{
    for (int c_ = 0; c_ < 4; ++c_) {
        m[c_] = (m[c_] * inv_col[c_]) * inv_row;
    }
    return m;
}

// TSVD-ONE-PASS's limits: the pass below accumulates raw (unnormalised)
// sums. A window whose feature range exceeds TSVD_WIDE_RANGE could overflow
// f32 there (n S2 and S1 S1^T grow as n^2 rho^2: safe for n up to ~1.8e4,
// R <= 66) and takes the normalised second pass instead. TSVD_WIDE_E2 is
// belt and braces: a component whose variances sum past it is kept only if
// its range exceeds ~1e17 (NOISE-CONST), which is wide already, and a
// dropped one's overflowed entries are zeroed by selection.
#define TSVD_WIDE_RANGE 1e15
#define TSVD_WIDE_E2 1e36

// One pixel's terms of G (from a*) and E^T E (from b*), lanes as x0, x1,
// x2, into the blocks of tsvd_local_space_with (declared there).
#define TSVD_ACC0(a0, b0) \
    G00 += outerProduct(a0, a0); \
    E00 += outerProduct(b0, b0);
#define TSVD_ACC1(a0, a1, b0, b1) \
    G01 += outerProduct(a0, a1); \
    E01 += outerProduct(b0, b1); \
    G11 += outerProduct(a1, a1); \
    E11 += outerProduct(b1, b1);
#if TSVD_D == 9
#define TSVD_ACC2(a0, a1, a2, b0, b1, b2) \
    G08 += a0 * a2.x; \
    E08 += b0 * b2.x; \
    G18 += a1 * a2.x; \
    E18 += b1 * b2.x; \
    G88 += a2.x * a2.x; \
    E88 += b2.x * b2.x;
#else
#define TSVD_ACC2(a0, a1, a2, b0, b1, b2) \
    G02 += outerProduct(a0, a2); \
    E02 += outerProduct(b0, b2); \
    G12 += outerProduct(a1, a2); \
    E12 += outerProduct(b1, b2); \
    G22 += outerProduct(a2, a2); \
    E22 += outerProduct(b2, b2);
#endif

// Spec §0.6 steps 1-6 for the window Omega_c(R) of centre c: the clipped
// square |q - c|_inf <= R inside [0, size), restricted to the pixels for
// which load_features returns true, visited in raster order.
//
// The features are handled as real4 lanes (x0 = x[0..4), x1 = x[4..8),
// x2 = x[8..12), lanes >= TSVD_D zero) and the Gram matrices G and E^T E
// are accumulated as outer products into constant-indexed 4x4 blocks (the
// upper block triangle), unpacked into the arrays of jacobi_eigen once per
// window.
//
// Decision TSVD-ONE-PASS (ours): one pass over the window (the twin
// computes the same formula in f64): min, max, the sums S1 = sum y and S2 = sum y y^T of
// y = x - x_c, sqrt(e2) sqrt(e2)^T and sum e2, all in raw units; then
// G_jl = ((n S2_jl - S1_j S1_l) / n) / (rho_j rho_l) and E^T E scaled alike
// once the ranges are known. Pixel coordinates become small integers whose
// sums and n S2 - S1 S1^T are exact for R <= 11 (n S2 < 2^24): a tile's
// offset changes no rounding, and the coordinate block is rounded once,
// where near-equal spreads in x and y make the eigenvectors sensitive.
// Shifting by the centre rather than the mean amplifies f32 rounding in
// n S2 - S1 S1^T by (var + d^2)/var, d = mean - x_c: at most n - 1 (a
// centre that is an outlier of an otherwise flat feature), typically
// ~n^1.5 eps ~ 4e-4 relative at R = 9, inside §0.3's 1e-3. A window wide
// enough to overflow raw f32 sums (never in a real image) runs the spec's
// normalised second pass.
LocalSpace tsvd_local_space_with(ivec2 c, int R, ivec2 size, bool exact_specnorm)
{
    LocalSpace ls;
    real x[MAX_D];
    real e2[MAX_D];
    real xc[MAX_D];
    load_features(c, xc, e2);
    real4 xc0;
    TSVD_PACK4(xc0, xc, 0)
    real4 mn0 = real4(0), hi0 = real4(0), sy0 = real4(0), es0 = real4(0);
    tsvd_mat4 G00 = tsvd_mat4(0), E00 = tsvd_mat4(0);
#if TSVD_D > 4
    real4 xc1;
    TSVD_PACK4(xc1, xc, 4)
    real4 mn1 = real4(0), hi1 = real4(0), sy1 = real4(0), es1 = real4(0);
    tsvd_mat4 G01 = tsvd_mat4(0), E01 = tsvd_mat4(0);
    tsvd_mat4 G11 = tsvd_mat4(0), E11 = tsvd_mat4(0);
#endif
#if TSVD_D > 8
    real4 xc2;
    TSVD_PACK4(xc2, xc, 8)
    real4 mn2 = real4(0), hi2 = real4(0), sy2 = real4(0), es2 = real4(0);
#endif
#if TSVD_D == 9
    // A one-lane tail: column 8 as real4s and the scalar (8, 8).
    real4 G08 = real4(0), E08 = real4(0);
    real4 G18 = real4(0), E18 = real4(0);
    real G88 = real(0), E88 = real(0);
#elif TSVD_D > 8
    tsvd_mat4 G02 = tsvd_mat4(0), E02 = tsvd_mat4(0);
    tsvd_mat4 G12 = tsvd_mat4(0), E12 = tsvd_mat4(0);
    tsvd_mat4 G22 = tsvd_mat4(0), E22 = tsvd_mat4(0);
#endif
    ivec2 lo = max(c - ivec2(R), ivec2(0));
    ivec2 up = min(c + ivec2(R), size - ivec2(1));

    int n = 0;
    for (int qy = lo.y; qy <= up.y; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            if (!load_features(ivec2(qx, qy), x, e2)) {
                continue;
            }
            bool first = n == 0;
            ++n;
            real4 x0, v0;
            TSVD_PACK4(x0, x, 0)
            TSVD_PACK4(v0, e2, 0)
            mn0 = first ? x0 : min(mn0, x0);
            hi0 = first ? x0 : max(hi0, x0);
            real4 y0 = x0 - xc0;
            sy0 += y0;
            real4 r0 = sqrt(max(v0, real4(0)));
            es0 += max(v0, real4(0));
            TSVD_ACC0(y0, r0)
#if TSVD_D > 4
            real4 x1, v1;
            TSVD_PACK4(x1, x, 4)
            TSVD_PACK4(v1, e2, 4)
            mn1 = first ? x1 : min(mn1, x1);
            hi1 = first ? x1 : max(hi1, x1);
            real4 y1 = x1 - xc1;
            sy1 += y1;
            real4 r1 = sqrt(max(v1, real4(0)));
            es1 += max(v1, real4(0));
            TSVD_ACC1(y0, y1, r0, r1)
#endif
#if TSVD_D > 8
            real4 x2, v2;
            TSVD_PACK4(x2, x, 8)
            TSVD_PACK4(v2, e2, 8)
            mn2 = first ? x2 : min(mn2, x2);
            hi2 = first ? x2 : max(hi2, x2);
            real4 y2 = x2 - xc2;
            sy2 += y2;
            real4 r2 = sqrt(max(v2, real4(0)));
            es2 += max(v2, real4(0));
            TSVD_ACC2(y0, y1, y2, r0, r1, r2)
#endif
        }
    }
    ls.n = n;

    // Step 1: min-max normalisation. inv = 1/rho, or 0 for a constant
    // component (x' = 0, e2' = 0).
    for (int j = 0; j < MAX_D; ++j) {
        ls.mn[j] = real(0);
        ls.range[j] = real(0);
    }
    real4 rg0 = hi0 - mn0;
    real4 inv0 = tsvd_inv4(rg0);
    TSVD_UNPACK4(ls.mn, mn0, 0)
    bool wide = any(greaterThan(rg0, real4(TSVD_WIDE_RANGE))) || any(greaterThan(es0, real4(TSVD_WIDE_E2)));
#if TSVD_D > 4
    real4 rg1 = hi1 - mn1;
    real4 inv1 = tsvd_inv4(rg1);
    TSVD_UNPACK4(ls.mn, mn1, 4)
    wide = wide || any(greaterThan(rg1, real4(TSVD_WIDE_RANGE))) || any(greaterThan(es1, real4(TSVD_WIDE_E2)));
#endif
#if TSVD_D > 8
    real4 rg2 = hi2 - mn2;
    real4 inv2 = tsvd_inv4(rg2);
    TSVD_UNPACK4(ls.mn, mn2, 8)
    wide = wide || any(greaterThan(rg2, real4(TSVD_WIDE_RANGE))) || any(greaterThan(es2, real4(TSVD_WIDE_E2)));
#endif

    // Steps 2-4 from the raw sums: G = Z^T Z with Z_ij = (x_ij - mean_j)/rho_j,
    // i.e. ((n S2_jl - S1_j S1_l) / n) / (rho_j rho_l), and
    // (E^T E)_jl = sum_i sqrt(e2'_ij e2'_il) (sy = S1, G = S2 before this).
    real nn = real(max(n, 1));
    G00 = tsvd_scale_block((G00 * nn - outerProduct(sy0, sy0)) / nn, inv0, inv0);
    E00 = tsvd_scale_block(E00, inv0, inv0);
#if TSVD_D > 4
    G01 = tsvd_scale_block((G01 * nn - outerProduct(sy0, sy1)) / nn, inv0, inv1);
    E01 = tsvd_scale_block(E01, inv0, inv1);
    G11 = tsvd_scale_block((G11 * nn - outerProduct(sy1, sy1)) / nn, inv1, inv1);
    E11 = tsvd_scale_block(E11, inv1, inv1);
#endif
#if TSVD_D == 9
    G08 = (((G08 * nn - sy0 * sy2.x) / nn) * inv2.x) * inv0;
    E08 = (E08 * inv2.x) * inv0;
    G18 = (((G18 * nn - sy1 * sy2.x) / nn) * inv2.x) * inv1;
    E18 = (E18 * inv2.x) * inv1;
    G88 = (((G88 * nn - sy2.x * sy2.x) / nn) * inv2.x) * inv2.x;
    E88 = (E88 * inv2.x) * inv2.x;
#elif TSVD_D > 8
    G02 = tsvd_scale_block((G02 * nn - outerProduct(sy0, sy2)) / nn, inv0, inv2);
    E02 = tsvd_scale_block(E02, inv0, inv2);
    G12 = tsvd_scale_block((G12 * nn - outerProduct(sy1, sy2)) / nn, inv1, inv2);
    E12 = tsvd_scale_block(E12, inv1, inv2);
    G22 = tsvd_scale_block((G22 * nn - outerProduct(sy2, sy2)) / nn, inv2, inv2);
    E22 = tsvd_scale_block(E22, inv2, inv2);
#endif

    // The normalised second pass of a wide window (normalise, centre,
    // multiply, as the spec words it; skipped by every SIMD vector without
    // such a window).
    ONLY(wide)
    {
        G00 = tsvd_mat4(0); E00 = tsvd_mat4(0);
#if TSVD_D > 4
        G01 = tsvd_mat4(0); E01 = tsvd_mat4(0);
        G11 = tsvd_mat4(0); E11 = tsvd_mat4(0);
#endif
#if TSVD_D == 9
        G08 = real4(0); E08 = real4(0);
        G18 = real4(0); E18 = real4(0);
        G88 = real(0); E88 = real(0);
#elif TSVD_D > 8
        G02 = tsvd_mat4(0); E02 = tsvd_mat4(0);
        G12 = tsvd_mat4(0); E12 = tsvd_mat4(0);
        G22 = tsvd_mat4(0); E22 = tsvd_mat4(0);
#endif
        for (int qy = lo.y; qy <= up.y; ++qy) {
            for (int qx = lo.x; qx <= up.x; ++qx) {
                if (!load_features(ivec2(qx, qy), x, e2)) {
                    continue;
                }
                real4 x0, v0;
                TSVD_PACK4(x0, x, 0)
                TSVD_PACK4(v0, e2, 0)
                real4 z0 = ((x0 - xc0) - sy0 / nn) * inv0;
                real4 s0 = sqrt(max(v0, real4(0))) * inv0;
                TSVD_ACC0(z0, s0)
#if TSVD_D > 4
                real4 x1, v1;
                TSVD_PACK4(x1, x, 4)
                TSVD_PACK4(v1, e2, 4)
                real4 z1 = ((x1 - xc1) - sy1 / nn) * inv1;
                real4 s1 = sqrt(max(v1, real4(0))) * inv1;
                TSVD_ACC1(z0, z1, s0, s1)
#endif
#if TSVD_D > 8
                real4 x2, v2;
                TSVD_PACK4(x2, x, 8)
                TSVD_PACK4(v2, e2, 8)
                real4 z2 = ((x2 - xc2) - sy2 / nn) * inv2;
                real4 s2 = sqrt(max(v2, real4(0))) * inv2;
                TSVD_ACC2(z0, z1, z2, s0, s1, s2)
#endif
            }
        }
    }
    // NOISE-CONST: a component no wider than TSVD_NOISE_RANGE_C RMS noise
    // is constant (range 0). Its mean noise comes from the one pass, which
    // loads e2 anyway; its rows and columns of G and E^T E are set to 0 by
    // selection, which is what x' = 0, e2' = 0 would have accumulated.
    real4 keep0 = mix(real4(1), real4(0), lessThanEqual(rg0, real(TSVD_NOISE_RANGE_C) * sqrt(es0 / nn)));
    rg0 *= keep0;
    TSVD_UNPACK4(ls.range, rg0, 0)
    G00 = tsvd_keep_block(G00, keep0, keep0);
    E00 = tsvd_keep_block(E00, keep0, keep0);
#if TSVD_D > 4
    real4 keep1 = mix(real4(1), real4(0), lessThanEqual(rg1, real(TSVD_NOISE_RANGE_C) * sqrt(es1 / nn)));
    rg1 *= keep1;
    TSVD_UNPACK4(ls.range, rg1, 4)
    G01 = tsvd_keep_block(G01, keep0, keep1);
    E01 = tsvd_keep_block(E01, keep0, keep1);
    G11 = tsvd_keep_block(G11, keep1, keep1);
    E11 = tsvd_keep_block(E11, keep1, keep1);
#endif
#if TSVD_D > 8
    real4 keep2 = mix(real4(1), real4(0), lessThanEqual(rg2, real(TSVD_NOISE_RANGE_C) * sqrt(es2 / nn)));
    rg2 *= keep2;
    TSVD_UNPACK4(ls.range, rg2, 8)
#if TSVD_D == 9
    G08 = tsvd_keep4(G08, keep0 * keep2.x);
    E08 = tsvd_keep4(E08, keep0 * keep2.x);
    G18 = tsvd_keep4(G18, keep1 * keep2.x);
    E18 = tsvd_keep4(E18, keep1 * keep2.x);
    G88 = keep2.x > real(0) ? G88 : real(0);
    E88 = keep2.x > real(0) ? E88 : real(0);
#else
    G02 = tsvd_keep_block(G02, keep0, keep2);
    E02 = tsvd_keep_block(E02, keep0, keep2);
    G12 = tsvd_keep_block(G12, keep1, keep2);
    E12 = tsvd_keep_block(E12, keep1, keep2);
    G22 = tsvd_keep_block(G22, keep2, keep2);
    E22 = tsvd_keep_block(E22, keep2, keep2);
#endif
#endif
    real G[MAX_D * MAX_D];
    real EE[MAX_D * MAX_D];
    for (int j = 0; j < MAX_D * MAX_D; ++j) {
        G[j] = real(0);
        EE[j] = real(0);
    }
    TSVD_UNPACK_BLOCK(G, G00, 0, 0)
    TSVD_UNPACK_BLOCK(EE, E00, 0, 0)
#if TSVD_D > 4
    TSVD_UNPACK_BLOCK(G, G01, 0, 1)
    TSVD_UNPACK_BLOCK(EE, E01, 0, 1)
    TSVD_UNPACK_BLOCK(G, G11, 1, 1)
    TSVD_UNPACK_BLOCK(EE, E11, 1, 1)
#endif
#if TSVD_D == 9
    TSVD_UNPACK_COL(G, G08, 0, 8)
    TSVD_UNPACK_COL(EE, E08, 0, 8)
    TSVD_UNPACK_COL(G, G18, 1, 8)
    TSVD_UNPACK_COL(EE, E18, 1, 8)
    G[8 * TSVD_D + 8] = G88;
    EE[8 * TSVD_D + 8] = E88;
#elif TSVD_D > 8
    TSVD_UNPACK_BLOCK(G, G02, 0, 2)
    TSVD_UNPACK_BLOCK(EE, E02, 0, 2)
    TSVD_UNPACK_BLOCK(G, G12, 1, 2)
    TSVD_UNPACK_BLOCK(EE, E12, 1, 2)
    TSVD_UNPACK_BLOCK(G, G22, 2, 2)
    TSVD_UNPACK_BLOCK(EE, E22, 2, 2)
#endif

    // Step 3: singular values and right singular vectors; then, where
    // needed, step 5's exact ||E||_2 = sqrt(lambda_max(E^T E)). Both
    // eigenproblems go through one call site (a pass loop): lavapipe
    // inlines every call, and a second copy of the solver made the pipeline
    // builds of every kernel that includes this file slower
    // (TSVD-ONE-JACOBI).
    real w[MAX_D];
    real A[MAX_D * MAX_D] = G;
    real Vj[MAX_D * MAX_D];
    bool exact = true;
    for (int pass = 0; pass < 2; ++pass) {
        jacobi_eigen(A, TSVD_D, Vj, w);
        if (pass == 1) {
            ls.specnorm = sqrt(max(w[0], real(0)));
            ls.tau = real(TSVD_TAU_C) * ls.specnorm;
            break;
        }
        ls.V = Vj;
        for (int m = 0; m < MAX_D; ++m) {
            ls.sigma[m] = sqrt(max(w[m], real(0)));
        }

        // Steps 4-5: SPECNORM, tau. Unless exact_specnorm (tsvd_debug's tau
        // and ||E||_2 outputs) only the rank k depends on tau, and
        // lambda_max(E^T E) lies in [lo, hi] (tsvd_lmax_bounds). Unless some
        // sigma_m above the floor falls where the two bounds (widened by
        // TSVD_BOUND_MARGIN) could rank it differently, tau = C sqrt(hi)
        // ranks every sigma_m as the exact value would, and the second
        // eigenproblem is skipped: the same k, at a fraction of the cost.
        if (!exact_specnorm) {
            real lo, hi;
            tsvd_lmax_bounds(EE, lo, hi);
            real tl = real(TSVD_TAU_C) * sqrt(max(lo, real(0))) * (real(1) - real(TSVD_BOUND_MARGIN));
            real tu = real(TSVD_TAU_C) * sqrt(max(hi, real(0))) * (real(1) + real(TSVD_BOUND_MARGIN));
            real floor_b = real(TSVD_SIGMA_REL) * ls.sigma[0];
            exact = false;
            for (int m = 0; m < TSVD_D; ++m) {
                if (ls.sigma[m] > floor_b && ls.sigma[m] > tl && ls.sigma[m] <= tu) {
                    exact = true;
                }
            }
            if (!exact) {
                ls.specnorm = sqrt(max(hi, real(0)));
                ls.tau = real(TSVD_TAU_C) * ls.specnorm;
                break;
            }
        }
        A = EE;
    }

    // Step 6: rank with MINRANK.
    real floor_s = real(TSVD_SIGMA_REL) * ls.sigma[0];
    int k_nz = 0;
    int k = 0;
    for (int m = 0; m < TSVD_D; ++m) {
        if (ls.sigma[m] > floor_s) {
            ++k_nz;
            if (ls.sigma[m] > ls.tau) {
                ++k;
            }
        }
    }
    ls.k_nz = k_nz;
    ls.k = min(max(k, min(TSVD_MIN_RANK, k_nz)), TSVD_MAX_RANK);
    return ls;
}

// The local space as the methods use it: ||E||_2 exact only where it decides
// the rank.
LocalSpace tsvd_local_space(ivec2 c, int R, ivec2 size)
{
    return tsvd_local_space_with(c, R, size, false);
}

// Min-max normalised features x' of raw features x (step 1): (x_j - m_j)/rho_j,
// or 0 for a constant component.
void tsvd_normalise(LocalSpace ls, real x[MAX_D], out real xn[MAX_D])
{
    for (int j = 0; j < MAX_D; ++j) {
        xn[j] = real(0);
    }
    for (int j = 0; j < TSVD_D; ++j) {
        if (ls.range[j] > real(TSVD_RANGE_EPS)) {
            xn[j] = (x[j] - ls.mn[j]) / ls.range[j];
        }
    }
}

// Step 7: local coordinates dz = V_k^T (x'_i - x'_c) of raw features xi
// relative to the centre's raw features xc; dz[m] for m < ls.k, 0 beyond.
void tsvd_local_coords(LocalSpace ls, real xi[MAX_D], real xc[MAX_D], out real dz[MAX_D])
{
    real a[MAX_D];
    real b[MAX_D];
    tsvd_normalise(ls, xi, a);
    tsvd_normalise(ls, xc, b);
    for (int m = 0; m < MAX_D; ++m) {
        real acc = real(0);
        if (m < ls.k) {
            for (int j = 0; j < TSVD_D; ++j) {
                acc += ls.V[j * TSVD_D + m] * (a[j] - b[j]);
            }
        }
        dz[m] = acc;
    }
}

#if (TSVD_D == 9 || TSVD_D == 10) && TSVD_MAX_RANK <= 9

// Local coordinates for D = 9 (WLR, LP) or 10 with rank at most 9 (WLR
// with visibility), twin reference::tsvd::Projection: dz = P (x - x_c)
// with P[m][j] = V_jm / rho_j (0 for constant j and m >= k), which equals
// step 7 (the window minimum cancels).
// Column j of P is (P0[j], P1[j], P8[j]) = rows 0-3, 4-7, 8.
struct TsvdProj {
    real4 P0[TSVD_D];
    real4 P1[TSVD_D];
    real P8[TSVD_D];
    int k;
    bvec4 m0;  // components 0-3 active (m < k)
    bvec4 m1;  // components 4-7
    bool m8;   // component 8
};

TsvdProj tsvd_projection(LocalSpace ls)
{
    TsvdProj pr;
    pr.k = ls.k;
    for (int j = 0; j < TSVD_D; ++j) {
        real inv = ls.range[j] > real(TSVD_RANGE_EPS) ? real(1) / ls.range[j] : real(0);
        real col[9];
        for (int m = 0; m < 9; ++m) {
            col[m] = m < ls.k ? ls.V[j * TSVD_D + m] * inv : real(0);
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

// d0 of tsvd_dz alone (the same sums in the same order): all of dz when
// k <= 4.
real4 tsvd_dz0(TsvdProj pr, real xc[MAX_D], real x[MAX_D])
{
    real4 d0 = real4(0);
    for (int j = 0; j < TSVD_D; ++j) {
        d0 += pr.P0[j] * (x[j] - xc[j]);
    }
    return d0;
}

// Local coordinates of raw features x: d0 = dz_1..4, d1 = dz_5..8, d8 = dz_9
// (0 beyond k).
void tsvd_dz(TsvdProj pr, real xc[MAX_D], real x[MAX_D], out real4 d0, out real4 d1, out real d8)
{
    d0 = real4(0);
    d1 = real4(0);
    d8 = real(0);
    for (int j = 0; j < TSVD_D; ++j) {
        real dx = x[j] - xc[j];
        d0 += pr.P0[j] * dx;
        d1 += pr.P1[j] * dx;
        d8 += pr.P8[j] * dx;
    }
}
#endif

#endif // MC_TSVD_GLSL
