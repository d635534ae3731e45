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
// The routine calls load_features twice per window pixel (min/max/mean pass,
// then the centred sums); loads a pass does not use are dead code.

#ifndef MC_TSVD_GLSL
#define MC_TSVD_GLSL

#include "lib/linalg.glsl"

#ifndef TSVD_D
#define TSVD_D 9
#endif
#if TSVD_D > MAX_D
#error "tsvd.glsl: TSVD_D exceeds MAX_D"
#endif

// Spec §0.6: constant-component range (natural units), tau = C ||E||_2,
// numerically-zero singular values, MINRANK.
#define TSVD_RANGE_EPS 1e-6
#define TSVD_TAU_C 2.0
#define TSVD_SIGMA_REL 1e-6
#define TSVD_MIN_RANK 2

// The kernel's feature loader (see the top of this file).
bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D]);

// The TSVD local space of one window. Arrays hold TSVD_D (resp. TSVD_D^2)
// meaningful entries.
struct LocalSpace {
    int n;          // valid window pixels
    int k;          // rank after MINRANK (0 only if every component is constant)
    int k_nz;       // #{sigma_m > 1e-6 sigma_1}
    real tau;       // 2 ||E||_2
    real specnorm;  // ||E||_2, exact (SPECNORM)
    real sigma[MAX_D];        // sigma_1 >= ... >= sigma_D
    real V[MAX_D * MAX_D];    // row-major D x D (stride TSVD_D), column m = v_m
    real mn[MAX_D];           // window minimum m_j (raw units)
    real range[MAX_D];        // rho_j = M_j - m_j; constant if <= TSVD_RANGE_EPS
};

// Spec §0.6 steps 1-6 for the window Omega_c(R) of centre c: the clipped
// square |q - c|_inf <= R inside [0, size), restricted to the pixels for
// which load_features returns true, visited in raster order.
LocalSpace tsvd_local_space(ivec2 c, int R, ivec2 size)
{
    LocalSpace ls;
    real x[MAX_D];
    real e2[MAX_D];
    real xc[MAX_D];
    real sum[MAX_D];
    real hi[MAX_D];
    load_features(c, xc, e2);
    for (int j = 0; j < MAX_D; ++j) {
        ls.mn[j] = real(0);
        ls.range[j] = real(0);
        sum[j] = real(0);
        hi[j] = real(0);
    }
    ivec2 lo = max(c - ivec2(R), ivec2(0));
    ivec2 up = min(c + ivec2(R), size - ivec2(1));

    // Pass 1: min, max and the mean (shifted by the centre for precision).
    int n = 0;
    for (int qy = lo.y; qy <= up.y; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            if (!load_features(ivec2(qx, qy), x, e2)) {
                continue;
            }
            for (int j = 0; j < TSVD_D; ++j) {
                ls.mn[j] = n == 0 ? x[j] : min(ls.mn[j], x[j]);
                hi[j] = n == 0 ? x[j] : max(hi[j], x[j]);
                sum[j] += x[j] - xc[j];
            }
            ++n;
        }
    }
    ls.n = n;

    // Step 1: min-max normalisation. inv = 1/rho, or 0 for a constant
    // component (x' = 0, e2' = 0). mean = window mean in raw units.
    real inv[MAX_D];
    real mean[MAX_D];
    for (int j = 0; j < MAX_D; ++j) {
        inv[j] = real(0);
        mean[j] = real(0);
    }
    for (int j = 0; j < TSVD_D; ++j) {
        ls.range[j] = hi[j] - ls.mn[j];
        inv[j] = ls.range[j] > real(TSVD_RANGE_EPS) ? real(1) / ls.range[j] : real(0);
        mean[j] = n > 0 ? xc[j] + sum[j] / real(n) : real(0);
    }

    // Pass 2, steps 2-4: G = Z^T Z with Z_ij = (x_ij - mean_j)/rho_j, and
    // (E^T E)_jl = sum_i sqrt(e2'_ij e2'_il); upper triangles only.
    real G[MAX_D * MAX_D];
    real EE[MAX_D * MAX_D];
    for (int j = 0; j < MAX_D * MAX_D; ++j) {
        G[j] = real(0);
        EE[j] = real(0);
    }
    for (int qy = lo.y; qy <= up.y; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            if (!load_features(ivec2(qx, qy), x, e2)) {
                continue;
            }
            real z[MAX_D];
            real s[MAX_D];
            for (int j = 0; j < TSVD_D; ++j) {
                z[j] = (x[j] - mean[j]) * inv[j];
                s[j] = sqrt(max(e2[j], real(0))) * inv[j];
            }
            for (int j = 0; j < TSVD_D; ++j) {
                for (int l = j; l < TSVD_D; ++l) {
                    G[j * TSVD_D + l] += z[j] * z[l];
                    EE[j * TSVD_D + l] += s[j] * s[l];
                }
            }
        }
    }
    for (int j = 0; j < TSVD_D; ++j) {
        for (int l = 0; l < j; ++l) {
            G[j * TSVD_D + l] = G[l * TSVD_D + j];
            EE[j * TSVD_D + l] = EE[l * TSVD_D + j];
        }
    }

    // Step 3: singular values and right singular vectors.
    real w[MAX_D];
    jacobi_eigen(G, TSVD_D, ls.V, w);
    for (int m = 0; m < MAX_D; ++m) {
        ls.sigma[m] = sqrt(max(w[m], real(0)));
    }

    // Steps 4-5: SPECNORM, tau.
    real Ve[MAX_D * MAX_D];
    jacobi_eigen(EE, TSVD_D, Ve, w);
    ls.specnorm = sqrt(max(w[0], real(0)));
    ls.tau = real(TSVD_TAU_C) * ls.specnorm;

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
    ls.k = max(k, min(TSVD_MIN_RANK, k_nz));
    return ls;
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

#endif // MC_TSVD_GLSL
