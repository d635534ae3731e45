// Shared linear algebra of the kernels (spec §0.5, §7), in `real`.
// Scalar twin: src/reference/linalg.rs (same algorithms, same loop order).
//
// * jacobi_eigen: cyclic Jacobi eigen-decomposition, D <= MAX_D.
// * wls_factor / wls_backsolve / wls_solve / wls_first_column: ridge Cholesky
//   with the RIDGE and SOLVE-FAIL rules, p <= MAX_P.
// * gauss_radius / gauss_weight / GAUSS_SMOOTH: the map smoothing G_sigma.
//
// Matrices live in fixed-size local arrays but are packed row-major with the
// *actual* order as stride: element (r, c) of a d x d matrix is A[r*d + c].
// A kernel may shrink the arrays by defining MAX_D / MAX_P before the first
// include of this file.

#ifndef MC_LINALG_GLSL
#define MC_LINALG_GLSL

#include "lib/common.glsl"

#ifndef MAX_D
#define MAX_D 11
#endif
#ifndef MAX_P
#define MAX_P 19
#endif

// SOLVE-FAIL: ridge increases after a failed factorisation, and the floor of
// a raised ridge relative to the mean diagonal of the unregularised matrix.
#define SOLVE_RETRIES 3
#define RIDGE_FLOOR 1e-8

// Cyclic Jacobi (spec §0.5) on the symmetric d x d matrix A (destroyed: it
// ends up nearly diagonal). Sweeps rotate every pair (p, q), p < q, in row
// order; they stop when the off-diagonal Frobenius norm is < JACOBI_TOL *
// ||A||_F (or exactly 0), checked before each sweep, or after JACOBI_SWEEPS.
// Out: w = eigenvalues in decreasing order (signed), V = eigenvectors, column
// m (V[j*d + m]) for w[m], each with its largest-|.| component (first on a
// tie) positive. Entries beyond d (resp. d*d) are set to 0. Returns the
// number of sweeps performed.
int jacobi_eigen(inout real A[MAX_D * MAX_D], int d, out real V[MAX_D * MAX_D], out real w[MAX_D])
{
    for (int i = 0; i < MAX_D * MAX_D; ++i) {
        V[i] = real(0);
    }
    for (int i = 0; i < d; ++i) {
        V[i * d + i] = real(1);
    }
    real norm = real(0);
    for (int i = 0; i < d * d; ++i) {
        norm += A[i] * A[i];
    }
    norm = sqrt(norm);

    int sweeps = 0;
    for (; sweeps < JACOBI_SWEEPS; ++sweeps) {
        real off = real(0);
        for (int p = 0; p < d; ++p) {
            for (int q = 0; q < d; ++q) {
                if (p != q) {
                    off += A[p * d + q] * A[p * d + q];
                }
            }
        }
        off = sqrt(off);
        if (off == real(0) || off < real(JACOBI_TOL) * norm) {
            break;
        }
        for (int p = 0; p < d; ++p) {
            for (int q = p + 1; q < d; ++q) {
                real apq = A[p * d + q];
                if (apq == real(0)) {
                    continue;
                }
                real app = A[p * d + p];
                real aqq = A[q * d + q];
                real theta = (aqq - app) / (real(2) * apq);
                real t;
                if (abs(theta) > real(1e15)) {
                    t = real(0.5) / theta;
                } else {
                    real sgn = theta >= real(0) ? real(1) : real(-1);
                    t = sgn / (abs(theta) + sqrt(theta * theta + real(1)));
                }
                real c = real(1) / sqrt(t * t + real(1));
                real s = t * c;
                for (int k = 0; k < d; ++k) {
                    if (k != p && k != q) {
                        real akp = A[k * d + p];
                        real akq = A[k * d + q];
                        real np = c * akp - s * akq;
                        real nq = s * akp + c * akq;
                        A[k * d + p] = np;
                        A[p * d + k] = np;
                        A[k * d + q] = nq;
                        A[q * d + k] = nq;
                    }
                }
                A[p * d + p] = app - t * apq;
                A[q * d + q] = aqq + t * apq;
                A[p * d + q] = real(0);
                A[q * d + p] = real(0);
                for (int k = 0; k < d; ++k) {
                    real vkp = V[k * d + p];
                    real vkq = V[k * d + q];
                    V[k * d + p] = c * vkp - s * vkq;
                    V[k * d + q] = s * vkp + c * vkq;
                }
            }
        }
    }

    for (int i = 0; i < MAX_D; ++i) {
        w[i] = i < d ? A[i * d + i] : real(0);
    }
    // Selection sort, decreasing; the first maximum wins (stable for ties).
    for (int i = 0; i < d; ++i) {
        int best = i;
        for (int j = i + 1; j < d; ++j) {
            if (w[j] > w[best]) {
                best = j;
            }
        }
        if (best != i) {
            real tw = w[i];
            w[i] = w[best];
            w[best] = tw;
            for (int r = 0; r < d; ++r) {
                real tv = V[r * d + i];
                V[r * d + i] = V[r * d + best];
                V[r * d + best] = tv;
            }
        }
    }
    // Sign convention: largest-magnitude component positive.
    for (int m = 0; m < d; ++m) {
        int big = 0;
        for (int r = 1; r < d; ++r) {
            if (abs(V[r * d + m]) > abs(V[big * d + m])) {
                big = r;
            }
        }
        if (V[big * d + m] < real(0)) {
            for (int r = 0; r < d; ++r) {
                V[r * d + m] = -V[r * d + m];
            }
        }
    }
    return sweeps;
}

// Cholesky factorisation of A + diag(0, lambda, ..., lambda) with the RIDGE
// and SOLVE-FAIL rules (spec §0.5), in place.
// In:  A = the symmetric unregularised p x p normal matrix; only its upper
//      triangle and diagonal are read. lambda >= 0.
// Out: lower triangle + diagonal of A = the factor L (A + Lambda = L L^T);
//      the strict upper triangle still holds the input. lambda = the ridge
//      actually used.
// A pivot (before its square root) fails when it is <= EPS_PIVOT * max
// diag(A + Lambda) or not finite; then lambda <- max(10 lambda, 1e-8 * mean
// diag(A)) and the factorisation restarts, at most SOLVE_RETRIES times.
// Returns false if every attempt failed (the fit must output the centre
// input and set debug flag bit 0).
bool wls_factor(inout real A[MAX_P * MAX_P], int p, inout real lambda)
{
    real diag[MAX_P];
    real mean_diag = real(0);
    for (int j = 0; j < p; ++j) {
        diag[j] = A[j * p + j];
        mean_diag += diag[j];
    }
    mean_diag /= real(max(p, 1));

    for (int attempt = 0; attempt <= SOLVE_RETRIES; ++attempt) {
        if (attempt > 0) {
            lambda = max(real(10) * lambda, real(RIDGE_FLOOR) * mean_diag);
        }
        real max_diag = real(0);
        for (int j = 0; j < p; ++j) {
            max_diag = max(max_diag, diag[j] + (j == 0 ? real(0) : lambda));
        }
        real thresh = real(EPS_PIVOT) * max_diag;
        bool ok = true;
        for (int i = 0; i < p && ok; ++i) {
            for (int j = 0; j <= i; ++j) {
                real s = (i == j) ? diag[i] + (i == 0 ? real(0) : lambda) : A[j * p + i];
                for (int k = 0; k < j; ++k) {
                    s -= A[i * p + k] * A[j * p + k];
                }
                if (i == j) {
                    if (!(s > thresh) || isinf(s)) {
                        ok = false;
                        break;
                    }
                    A[i * p + i] = sqrt(s);
                } else {
                    A[i * p + j] = s / A[j * p + j];
                }
            }
        }
        if (ok) {
            return true;
        }
    }
    return false;
}

// Solves L L^T x = b in place (b <- x), with L the lower triangle of a matrix
// factored by wls_factor.
void wls_backsolve(real L[MAX_P * MAX_P], int p, inout real b[MAX_P])
{
    for (int i = 0; i < p; ++i) {
        real s = b[i];
        for (int k = 0; k < i; ++k) {
            s -= L[i * p + k] * b[k];
        }
        b[i] = s / L[i * p + i];
    }
    for (int i = p - 1; i >= 0; --i) {
        real s = b[i];
        for (int k = i + 1; k < p; ++k) {
            s -= L[k * p + i] * b[k];
        }
        b[i] = s / L[i * p + i];
    }
}

// b <- (A + Lambda)^{-1} b (spec §0.5): wls_factor then wls_backsolve. A is
// left factored (reuse it with wls_backsolve for more right-hand sides, e.g.
// one per colour channel). Returns false on SOLVE-FAIL, with b set to 0.
bool wls_solve(inout real A[MAX_P * MAX_P], int p, inout real lambda, inout real b[MAX_P])
{
    if (!wls_factor(A, p, lambda)) {
        for (int i = 0; i < MAX_P; ++i) {
            b[i] = real(0);
        }
        return false;
    }
    wls_backsolve(A, p, b);
    return true;
}

// u = (A + Lambda)^{-1} e_1, the first column of the inverse, which gives the
// equivalent kernel l_i = w_i u^T x_i of the fit at the centre (spec §0.5).
// Returns false on SOLVE-FAIL (u = 0).
bool wls_first_column(inout real A[MAX_P * MAX_P], int p, inout real lambda, out real u[MAX_P])
{
    for (int i = 0; i < MAX_P; ++i) {
        u[i] = real(0);
    }
    u[0] = real(1);
    return wls_solve(A, p, lambda, u);
}

// Gaussian map smoothing G_sigma (spec §0.5): radius ceil(3 sigma) ...
int gauss_radius(real sigma)
{
    return int(ceil(real(3) * sigma));
}

// ... and weight g(o) = exp(-|o|^2 / (2 sigma^2)); exp is evaluated in float
// (GLSL has no double exp), which is far below the test tolerance.
real gauss_weight(ivec2 o, real sigma)
{
    real r2 = real(o.x * o.x + o.y * o.y);
    return real(exp(float(-r2 / (real(2) * sigma * sigma))));
}

// GAUSS_SMOOTH(result, p, size, sigma, VALID, VALUE): result = G_sigma(m)(p),
// the g-weighted mean of VALUE(q) over the pixels q of the clipped window
// |q - p|_inf <= ceil(3 sigma) for which VALID(q) is true; 0 if there is none.
// VALID and VALUE name functions of an ivec2 (bool and real) that the kernel
// defines, typically reading a plane and the spp plane. p and size are ivec2.
#define GAUSS_SMOOTH(result, p, size, sigma, VALID, VALUE)                          \
    {                                                                               \
        int gs_r = gauss_radius(sigma);                                             \
        real gs_num = real(0);                                                      \
        real gs_den = real(0);                                                      \
        for (int gs_y = max((p).y - gs_r, 0); gs_y <= min((p).y + gs_r, (size).y - 1); ++gs_y) { \
            for (int gs_x = max((p).x - gs_r, 0); gs_x <= min((p).x + gs_r, (size).x - 1); ++gs_x) { \
                ivec2 gs_q = ivec2(gs_x, gs_y);                                     \
                if (VALID(gs_q)) {                                                  \
                    real gs_g = gauss_weight(gs_q - (p), sigma);                    \
                    gs_num += gs_g * VALUE(gs_q);                                   \
                    gs_den += gs_g;                                                 \
                }                                                                   \
            }                                                                       \
        }                                                                           \
        result = gs_den > real(0) ? gs_num / gs_den : real(0);                      \
    }

#endif // MC_LINALG_GLSL
