//! Shared linear algebra of the scalar twins (spec §0.5, §7), in f64.
//!
//! The GPU twin of every routine here is `spirv/lib/linalg.glsl`; both follow
//! the same algorithm step by step so that a kernel and its reference differ
//! only by precision (and, in f32, by the looser tolerances of §0.5).
//!
//! * [`jacobi_eigen`]: cyclic Jacobi eigen-decomposition of a small symmetric
//!   matrix (D ≤ 11), eigenvalues sorted decreasing, deterministic signs.
//! * [`ridge_cholesky`], [`wls_solve`], [`equivalent_kernel`]: weighted least
//!   squares with the RIDGE and SOLVE-FAIL rules.
//! * [`gaussian_smooth`]: the map smoothing `G_σ` over valid pixels.
//!
//! Matrices are dense, row-major, `Vec<f64>`/`&[f64]` of `d * d` values.

/// Relative stopping tolerance of [`jacobi_eigen`] in f64 (spec §0.5). The f32
/// kernels use `JACOBI_TOL` = 1e-6 from `spirv/lib/common.glsl`.
pub const JACOBI_TOL: f64 = 1e-12;

/// Maximum number of Jacobi sweeps in f64 (spec §0.5). The f32 kernels use
/// `JACOBI_SWEEPS` = 10 from `spirv/lib/common.glsl`.
pub const JACOBI_SWEEPS: usize = 30;

/// Relative pivot threshold of the Cholesky factorisation in f64 (SOLVE-FAIL,
/// spec §0.5); `EPS_PIVOT` = 1e-6 in the f32 kernels.
pub const EPS_PIVOT: f64 = 1e-12;

/// Number of ridge increases tried after a failed factorisation (SOLVE-FAIL).
pub const SOLVE_RETRIES: usize = 3;

/// Floor of a raised ridge, relative to the mean diagonal of the unregularised
/// normal matrix: `λ ← max(10λ, RIDGE_FLOOR · mean diag)` (SOLVE-FAIL).
pub const RIDGE_FLOOR: f64 = 1e-8;

/// Eigen-decomposition `A = V diag(values) Vᵀ` of a symmetric `d × d` matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Eigen {
    /// Matrix order.
    pub d: usize,
    /// Eigenvalues, sorted in decreasing order (signed: not clamped at 0).
    pub values: Vec<f64>,
    /// Eigenvectors, row-major `d × d`: column `m` (entries `vectors[j*d + m]`)
    /// is the unit eigenvector of `values[m]`. Orthonormal. Each column's
    /// largest-magnitude component (the first one on an exact tie) is positive.
    pub vectors: Vec<f64>,
    /// Number of full sweeps performed (0 if the input was already diagonal).
    pub sweeps: usize,
}

impl Eigen {
    /// Component `j` of eigenvector `m`.
    pub fn vector(&self, j: usize, m: usize) -> f64 {
        self.vectors[j * self.d + m]
    }
}

/// Cyclic Jacobi eigen-decomposition of the symmetric row-major `d × d`
/// matrix `a` (spec §0.5).
///
/// Each sweep rotates every pair `(p, q)`, `p < q`, in row order. Sweeps stop
/// when the off-diagonal Frobenius norm is `< tol · ‖A‖_F` (checked before each
/// sweep; an exactly diagonal matrix stops too) or after `max_sweeps` sweeps.
/// Then eigenvalues are sorted decreasing (stable selection, so equal values keep
/// their diagonal order) and each eigenvector's largest-magnitude component is
/// made positive. Use [`JACOBI_TOL`] / [`JACOBI_SWEEPS`] for the f64 rule, or
/// 1e-6 / 10 to mimic the f32 kernels. Only `a` symmetric is meaningful; the
/// whole matrix is read. Cost `O(sweeps · d³)`; intended for `d ≤ 11`.
pub fn jacobi_eigen(a: &[f64], d: usize, tol: f64, max_sweeps: usize) -> Eigen {
    assert_eq!(a.len(), d * d, "jacobi_eigen: matrix is not {d}x{d}");
    let mut m = a.to_vec();
    let mut v = vec![0.0; d * d];
    for j in 0..d {
        v[j * d + j] = 1.0;
    }
    let norm = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let mut sweeps = 0;
    while sweeps < max_sweeps {
        let mut off = 0.0;
        for p in 0..d {
            for q in 0..d {
                if p != q {
                    off += m[p * d + q] * m[p * d + q];
                }
            }
        }
        let off = off.sqrt();
        if off == 0.0 || off < tol * norm {
            break;
        }
        for p in 0..d {
            for q in p + 1..d {
                jacobi_rotate(&mut m, &mut v, d, p, q);
            }
        }
        sweeps += 1;
    }
    let mut values: Vec<f64> = (0..d).map(|j| m[j * d + j]).collect();
    sort_and_sign(&mut values, &mut v, d);
    Eigen {
        d,
        values,
        vectors: v,
        sweeps,
    }
}

/// [`jacobi_eigen`] with the f64 tolerances of spec §0.5.
pub fn symmetric_eigen(a: &[f64], d: usize) -> Eigen {
    jacobi_eigen(a, d, JACOBI_TOL, JACOBI_SWEEPS)
}

/// One Jacobi rotation zeroing `m[p][q]` (Golub & Van Loan §8.5, the form with
/// `a_pp ← a_pp - t·a_pq`); also accumulates it into `v`.
fn jacobi_rotate(m: &mut [f64], v: &mut [f64], d: usize, p: usize, q: usize) {
    let apq = m[p * d + q];
    if apq == 0.0 {
        return;
    }
    let app = m[p * d + p];
    let aqq = m[q * d + q];
    let theta = (aqq - app) / (2.0 * apq);
    // For huge θ, θ² overflows (in f32 at ~1e19): use t ≈ 1/(2θ) instead.
    // θ = ±0 takes t = +1, as in the GLSL twin.
    let t = if theta.abs() > 1e15 {
        0.5 / theta
    } else {
        let sign = if theta >= 0.0 { 1.0 } else { -1.0 };
        sign / (theta.abs() + (theta * theta + 1.0).sqrt())
    };
    let c = 1.0 / (t * t + 1.0).sqrt();
    let s = t * c;
    for k in 0..d {
        if k != p && k != q {
            let akp = m[k * d + p];
            let akq = m[k * d + q];
            let np = c * akp - s * akq;
            let nq = s * akp + c * akq;
            m[k * d + p] = np;
            m[p * d + k] = np;
            m[k * d + q] = nq;
            m[q * d + k] = nq;
        }
    }
    m[p * d + p] = app - t * apq;
    m[q * d + q] = aqq + t * apq;
    m[p * d + q] = 0.0;
    m[q * d + p] = 0.0;
    for k in 0..d {
        let vkp = v[k * d + p];
        let vkq = v[k * d + q];
        v[k * d + p] = c * vkp - s * vkq;
        v[k * d + q] = s * vkp + c * vkq;
    }
}

/// Sorts eigenpairs by decreasing value (selection sort, first maximum wins)
/// and applies the sign convention of §0.5.
fn sort_and_sign(w: &mut [f64], v: &mut [f64], d: usize) {
    for i in 0..d {
        let mut best = i;
        for j in i + 1..d {
            if w[j] > w[best] {
                best = j;
            }
        }
        if best != i {
            w.swap(i, best);
            for r in 0..d {
                v.swap(r * d + i, r * d + best);
            }
        }
    }
    for m in 0..d {
        let mut big = 0;
        for r in 1..d {
            if v[r * d + m].abs() > v[big * d + m].abs() {
                big = r;
            }
        }
        if v[big * d + m] < 0.0 {
            for r in 0..d {
                v[r * d + m] = -v[r * d + m];
            }
        }
    }
}

/// Cholesky factor `L Lᵀ = A + Λ` of a ridge-regularised normal matrix, with
/// `Λ = diag(0, λ, …, λ)` (RIDGE, spec §0.5).
#[derive(Clone, Debug, PartialEq)]
pub struct RidgeCholesky {
    /// Matrix order `p`.
    pub p: usize,
    /// Lower-triangular factor, row-major `p × p` (upper part zero). All zero
    /// if the factorisation failed.
    pub l: Vec<f64>,
    /// The ridge `λ` actually used (raised by SOLVE-FAIL retries).
    pub lambda: f64,
    /// Number of ridge increases performed (0..=[`SOLVE_RETRIES`]).
    pub retries: usize,
    /// `true` if every attempt hit a pivot `<= eps_pivot · max diag`: the fit
    /// must fall back to the centre input (debug flag bit 0).
    pub failed: bool,
}

impl RidgeCholesky {
    /// Solves `(A + Λ) x = b` by forward and back substitution. Returns zeros
    /// if the factorisation failed.
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        let p = self.p;
        assert_eq!(b.len(), p, "RidgeCholesky::solve: rhs length");
        if self.failed {
            return vec![0.0; p];
        }
        let l = &self.l;
        let mut x = b.to_vec();
        for i in 0..p {
            let mut s = x[i];
            for k in 0..i {
                s -= l[i * p + k] * x[k];
            }
            x[i] = s / l[i * p + i];
        }
        for i in (0..p).rev() {
            let mut s = x[i];
            for k in i + 1..p {
                s -= l[k * p + i] * x[k];
            }
            x[i] = s / l[i * p + i];
        }
        x
    }
}

/// Factors `A + diag(0, λ, …, λ)` with the SOLVE-FAIL rule of spec §0.5.
///
/// `a` is the symmetric unregularised normal matrix (row-major `p × p`; only
/// its upper triangle and diagonal are read). A pivot (the Schur complement
/// before its square root) fails when it is `<= eps_pivot · max diag(A + Λ)`
/// or not finite. On failure `λ ← max(10λ, RIDGE_FLOOR · mean diag(A))` and
/// the factorisation restarts, at most [`SOLVE_RETRIES`] times. `eps_pivot`
/// is [`EPS_PIVOT`] in f64 (1e-6 mimics the f32 kernels). `λ >= 0`.
///
/// Note: starting from `λ = 0`, the raised ridge reaches at most
/// `1e-6 · mean diag`, so an exactly singular system is rescued in f64 but
/// usually still fails with the f32 threshold (GPU f32 variant); with the
/// `λ > 0` of the methods both precisions succeed.
pub fn ridge_cholesky(a: &[f64], p: usize, lambda: f64, eps_pivot: f64) -> RidgeCholesky {
    assert_eq!(a.len(), p * p, "ridge_cholesky: matrix is not {p}x{p}");
    let mean_diag = if p == 0 {
        0.0
    } else {
        (0..p).map(|j| a[j * p + j]).sum::<f64>() / p as f64
    };
    let mut lambda = lambda;
    let mut l = vec![0.0; p * p];
    for attempt in 0..=SOLVE_RETRIES {
        if attempt > 0 {
            lambda = (10.0 * lambda).max(RIDGE_FLOOR * mean_diag);
        }
        if cholesky_attempt(a, p, lambda, eps_pivot, &mut l) {
            return RidgeCholesky {
                p,
                l,
                lambda,
                retries: attempt,
                failed: false,
            };
        }
    }
    RidgeCholesky {
        p,
        l: vec![0.0; p * p],
        lambda,
        retries: SOLVE_RETRIES,
        failed: true,
    }
}

/// One factorisation attempt (row by row); `false` on a failed pivot.
fn cholesky_attempt(a: &[f64], p: usize, lambda: f64, eps_pivot: f64, l: &mut [f64]) -> bool {
    let ridge = |j: usize| if j == 0 { 0.0 } else { lambda };
    let mut max_diag = 0.0f64;
    for j in 0..p {
        max_diag = max_diag.max(a[j * p + j] + ridge(j));
    }
    let thresh = eps_pivot * max_diag;
    l.fill(0.0);
    for i in 0..p {
        for j in 0..=i {
            // a(j, i) from the upper triangle.
            let mut s = a[j * p + i] + if i == j { ridge(i) } else { 0.0 };
            for k in 0..j {
                s -= l[i * p + k] * l[j * p + k];
            }
            if i == j {
                // `s > thresh` is false for NaN too.
                let pivot_ok = s > thresh && s.is_finite();
                if !pivot_ok {
                    return false;
                }
                l[i * p + i] = s.sqrt();
            } else {
                l[i * p + j] = s / l[j * p + j];
            }
        }
    }
    true
}

/// Result of [`wls_solve`].
#[derive(Clone, Debug, PartialEq)]
pub struct WlsSolve {
    /// `(A + Λ)^{-1} rhs`; zeros if `failed`.
    pub x: Vec<f64>,
    /// The ridge actually used.
    pub lambda: f64,
    /// SOLVE-FAIL: the caller outputs the centre input and sets flag bit 0.
    pub failed: bool,
}

/// Solves `(A + Λ) x = rhs` with the RIDGE and SOLVE-FAIL rules (spec §0.5), in
/// f64 ([`EPS_PIVOT`]). With `rhs = Σ w_i x_i y_i` this gives the coefficients
/// `β`; with `rhs = e_1` the first column `u` of the inverse (see
/// [`equivalent_kernel`]). `a` is `p × p` row-major (upper triangle read).
pub fn wls_solve(a: &[f64], rhs: &[f64], p: usize, lambda: f64) -> WlsSolve {
    let ch = ridge_cholesky(a, p, lambda, EPS_PIVOT);
    WlsSolve {
        x: ch.solve(rhs),
        lambda: ch.lambda,
        failed: ch.failed,
    }
}

/// Normal matrix `A = Σ_i w_i x_i x_iᵀ` (row-major `p × p`) of the design rows
/// `rows` (`n × p` row-major, `x_i[0] = 1` by convention) and weights `w` (n).
pub fn normal_matrix(rows: &[f64], p: usize, w: &[f64]) -> Vec<f64> {
    assert_eq!(
        rows.len(),
        w.len() * p,
        "normal_matrix: rows are not n x {p}"
    );
    let mut a = vec![0.0; p * p];
    for (x, &wi) in rows.chunks_exact(p).zip(w) {
        for r in 0..p {
            for c in 0..p {
                a[r * p + c] += wi * x[r] * x[c];
            }
        }
    }
    a
}

/// Right-hand side `Σ_i w_i x_i y_i` of the normal equations.
pub fn normal_rhs(rows: &[f64], p: usize, w: &[f64], y: &[f64]) -> Vec<f64> {
    assert_eq!(rows.len(), w.len() * p, "normal_rhs: rows are not n x {p}");
    assert_eq!(y.len(), w.len(), "normal_rhs: responses");
    let mut b = vec![0.0; p];
    for ((x, &wi), &yi) in rows.chunks_exact(p).zip(w).zip(y) {
        for r in 0..p {
            b[r] += wi * x[r] * yi;
        }
    }
    b
}

/// The equivalent kernel of a WLS fit at the centre (spec §0.5).
#[derive(Clone, Debug, PartialEq)]
pub struct WlsKernel {
    /// `u = (A + Λ)^{-1} e_1`, the first column of the inverse (p).
    pub u: Vec<f64>,
    /// `l_i = w_i uᵀ x_i` (n): `f̂ = Σ_i l_i y_i`. Sums to 1 when the fit
    /// succeeded (the intercept is never penalised). Zeros if `failed`.
    pub l: Vec<f64>,
    /// The ridge actually used.
    pub lambda: f64,
    /// SOLVE-FAIL after all retries.
    pub failed: bool,
}

/// Equivalent kernel `l_i = w_i uᵀ x_i` of the weighted fit with design rows
/// `rows` (`n × p`, intercept first), weights `w` and ridge `λ` (spec §0.5).
pub fn equivalent_kernel(rows: &[f64], p: usize, w: &[f64], lambda: f64) -> WlsKernel {
    let a = normal_matrix(rows, p, w);
    let mut e1 = vec![0.0; p];
    if p > 0 {
        e1[0] = 1.0;
    }
    let s = wls_solve(&a, &e1, p, lambda);
    let l = rows
        .chunks_exact(p.max(1))
        .zip(w)
        .map(|(x, &wi)| {
            if s.failed {
                0.0
            } else {
                wi * x.iter().zip(&s.x).map(|(a, b)| a * b).sum::<f64>()
            }
        })
        .collect();
    WlsKernel {
        u: s.x,
        l,
        lambda: s.lambda,
        failed: s.failed,
    }
}

/// Radius `ceil(3σ)` of the [`gaussian_smooth`] window.
pub use crate::shared::gaussian_radius;

/// `G_σ(m)(x, y)`: the Gaussian-weighted mean of `m` over the valid pixels `q`
/// with `|q - p|_inf <= ceil(3σ)` (clipped to the image), weights
/// `exp(-|q-p|²/(2σ²))` (spec §0.5; not edge-aware). Returns 0 when no valid
/// pixel lies in the window. `m` and `valid` are `width × height` planes.
pub fn gaussian_smooth_at<T: Copy + Into<f64>>(
    m: &[T],
    valid: &[bool],
    width: usize,
    height: usize,
    sigma: f64,
    x: usize,
    y: usize,
) -> f64 {
    let r = gaussian_radius(sigma);
    let (mut num, mut den) = (0.0, 0.0);
    for qy in y.saturating_sub(r)..(y + r + 1).min(height) {
        for qx in x.saturating_sub(r)..(x + r + 1).min(width) {
            let q = qy * width + qx;
            if !valid[q] {
                continue;
            }
            let dx = qx as f64 - x as f64;
            let dy = qy as f64 - y as f64;
            let g = (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp();
            num += g * m[q].into();
            den += g;
        }
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// [`gaussian_smooth_at`] for every pixel of a `width × height` plane
/// (invalid pixels included: they receive the mean of their valid neighbours).
pub fn gaussian_smooth<T: Copy + Into<f64>>(
    m: &[T],
    valid: &[bool],
    width: usize,
    height: usize,
    sigma: f64,
) -> Vec<f64> {
    assert_eq!(m.len(), width * height, "gaussian_smooth: plane size");
    assert_eq!(valid.len(), width * height, "gaussian_smooth: mask size");
    let mut out = vec![0.0; width * height];
    for y in 0..height {
        for x in 0..width {
            out[y * width + x] = gaussian_smooth_at(m, valid, width, height, sigma, x, y);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64* in [0, 1).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn sym(&mut self) -> f64 {
            2.0 * self.next() - 1.0
        }
    }

    fn random_symmetric(rng: &mut Rng, d: usize) -> Vec<f64> {
        let mut a = vec![0.0; d * d];
        for i in 0..d {
            for j in i..d {
                let x = rng.sym() * 10.0;
                a[i * d + j] = x;
                a[j * d + i] = x;
            }
        }
        a
    }

    fn check_eigen(a: &[f64], e: &Eigen, tol: f64) {
        let d = e.d;
        let scale = a.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
        for m in 0..d {
            if m + 1 < d {
                assert!(e.values[m] >= e.values[m + 1], "not sorted: {:?}", e.values);
            }
            // A v_m = λ_m v_m
            for r in 0..d {
                let av: f64 = (0..d).map(|c| a[r * d + c] * e.vector(c, m)).sum();
                assert!(
                    (av - e.values[m] * e.vector(r, m)).abs() <= tol * scale,
                    "A v != λ v at ({r},{m})"
                );
            }
            // sign convention
            let big =
                (0..d)
                    .map(|j| e.vector(j, m))
                    .fold(0.0f64, |b, x| if x.abs() > b.abs() { x } else { b });
            assert!(big > 0.0);
            // orthonormality
            for m2 in 0..d {
                let dot: f64 = (0..d).map(|j| e.vector(j, m) * e.vector(j, m2)).sum();
                let want = if m == m2 { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-12, "VᵀV[{m},{m2}] = {dot}");
            }
        }
    }

    #[test]
    fn jacobi_random_symmetric() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for d in 1..=11 {
            for _ in 0..20 {
                let a = random_symmetric(&mut rng, d);
                let e = symmetric_eigen(&a, d);
                check_eigen(&a, &e, 1e-11);
                assert!(e.sweeps < JACOBI_SWEEPS, "did not converge: d={d}");
                let trace: f64 = (0..d).map(|j| a[j * d + j]).sum();
                let sum: f64 = e.values.iter().sum();
                assert!((trace - sum).abs() < 1e-10 * (1.0 + trace.abs()));
            }
        }
    }

    #[test]
    fn jacobi_rank_deficient_and_degenerate() {
        // G = Zᵀ Z with 3 columns, one repeated: eigenvalue 0, and a diagonal
        // matrix with repeated values (no rotation at all).
        let z = [1.0, 2.0, 1.0, 0.5, -1.0, 0.5, -1.5, -1.0, -1.5];
        let d = 3;
        let mut g = vec![0.0; 9];
        for i in 0..3 {
            for r in 0..d {
                for c in 0..d {
                    g[r * d + c] += z[i * d + r] * z[i * d + c];
                }
            }
        }
        let e = symmetric_eigen(&g, d);
        check_eigen(&g, &e, 1e-12);
        assert!(e.values[2].abs() < 1e-12);
        let diag = [2.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 2.0];
        let e = symmetric_eigen(&diag, 3);
        assert_eq!(e.values, vec![5.0, 2.0, 2.0]);
        assert_eq!(e.sweeps, 0);
        assert_eq!(e.vectors, vec![0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        let zero = symmetric_eigen(&[0.0; 4], 2);
        assert_eq!(zero.values, vec![0.0, 0.0]);
    }

    #[test]
    fn jacobi_f32_tolerances_are_close() {
        let mut rng = Rng(7);
        let a = random_symmetric(&mut rng, 9);
        let e = jacobi_eigen(&a, 9, 1e-6, 10);
        check_eigen(&a, &e, 1e-5);
    }

    fn design(rng: &mut Rng, n: usize, p: usize) -> (Vec<f64>, Vec<f64>) {
        let mut rows = Vec::with_capacity(n * p);
        let mut w = Vec::with_capacity(n);
        for _ in 0..n {
            rows.push(1.0);
            for _ in 1..p {
                rows.push(rng.sym());
            }
            w.push(rng.next());
        }
        (rows, w)
    }

    #[test]
    fn wls_kernel_sums_to_one_and_reproduces_constants() {
        let mut rng = Rng(42);
        for &(n, p, lambda) in &[(50, 3, 1e-3), (30, 7, 1e-4), (10, 19, 1e-3), (5, 9, 1e-3)] {
            let (rows, w) = design(&mut rng, n, p);
            let k = equivalent_kernel(&rows, p, &w, lambda);
            assert!(!k.failed);
            let sum: f64 = k.l.iter().sum();
            assert!((sum - 1.0).abs() < 1e-10, "Σ l = {sum} (n={n}, p={p})");
            // f̂ of a constant image is the constant, also through β.
            let y = vec![3.25; n];
            let fh: f64 = k.l.iter().zip(&y).map(|(l, y)| l * y).sum();
            assert!((fh - 3.25).abs() < 1e-10);
            let a = normal_matrix(&rows, p, &w);
            let beta = wls_solve(&a, &normal_rhs(&rows, p, &w, &y), p, lambda);
            assert!((beta.x[0] - 3.25).abs() < 1e-10);
            assert!(beta.x[1..].iter().all(|b| b.abs() < 1e-10));
        }
    }

    #[test]
    fn wls_unpenalised_fit_is_exact_on_affine_data() {
        let mut rng = Rng(3);
        let (n, p) = (40, 4);
        let (rows, w) = design(&mut rng, n, p);
        let coef = [0.5, -2.0, 1.0, 3.0];
        let y: Vec<f64> = rows
            .chunks_exact(p)
            .map(|x| x.iter().zip(&coef).map(|(a, b)| a * b).sum())
            .collect();
        let a = normal_matrix(&rows, p, &w);
        let s = wls_solve(&a, &normal_rhs(&rows, p, &w, &y), p, 0.0);
        assert!(!s.failed);
        for (b, c) in s.x.iter().zip(&coef) {
            assert!((b - c).abs() < 1e-10);
        }
        // the inverse's first column satisfies (A+Λ) u = e_1
        let k = equivalent_kernel(&rows, p, &w, 0.0);
        for r in 0..p {
            let au: f64 = (0..p).map(|c| a[r * p + c] * k.u[c]).sum();
            assert!((au - if r == 0 { 1.0 } else { 0.0 }).abs() < 1e-10);
        }
    }

    #[test]
    fn wls_singular_system_is_rescued_by_ridge_retry() {
        // Two identical columns and λ = 0: the first attempt fails, the raised
        // ridge (1e-8 · mean diag) succeeds and Σ l is still 1.
        let n = 20;
        let p = 3;
        let mut rng = Rng(11);
        let mut rows = Vec::new();
        for _ in 0..n {
            let t = rng.sym();
            rows.extend_from_slice(&[1.0, t, t]);
        }
        let w = vec![1.0; n];
        let a = normal_matrix(&rows, p, &w);
        let ch = ridge_cholesky(&a, p, 0.0, EPS_PIVOT);
        assert!(!ch.failed);
        assert_eq!(ch.retries, 1);
        let mean_diag = (a[0] + a[4] + a[8]) / 3.0;
        assert!((ch.lambda - RIDGE_FLOOR * mean_diag).abs() < 1e-20);
        let k = equivalent_kernel(&rows, p, &w, 0.0);
        assert!((k.l.iter().sum::<f64>() - 1.0).abs() < 1e-8);
    }

    #[test]
    fn wls_solve_fail_path() {
        // All weights zero: A = 0, the intercept pivot is 0 on every attempt.
        let (rows, _) = design(&mut Rng(5), 8, 3);
        let w = vec![0.0; 8];
        let k = equivalent_kernel(&rows, 3, &w, 1e-3);
        assert!(k.failed);
        assert!(k.l.iter().all(|&l| l == 0.0));
        let a = normal_matrix(&rows, 3, &w);
        let s = wls_solve(&a, &[1.0, 0.0, 0.0], 3, 1e-3);
        assert!(s.failed);
        assert_eq!(s.x, vec![0.0; 3]);
        // λ went 1e-3 → 1e-2 → 1e-1 → 1.
        assert!((s.lambda - 1.0).abs() < 1e-12);
        // A non-finite matrix fails too instead of producing NaN.
        let bad = [f64::NAN, 0.0, 0.0, 1.0];
        assert!(ridge_cholesky(&bad, 2, 0.0, EPS_PIVOT).failed);
    }

    #[test]
    fn gaussian_smoothing_rules() {
        let (w, h) = (7, 5);
        let valid: Vec<bool> = (0..w * h).map(|i| i != 17).collect();
        // constant map stays constant over valid pixels, whatever the mask
        let m = vec![2.5f32; w * h];
        let s = gaussian_smooth(&m, &valid, w, h, 1.0);
        assert!(s.iter().all(|v| (v - 2.5).abs() < 1e-12));
        // an invalid pixel's value never leaks
        let mut m2 = vec![1.0f64; w * h];
        m2[17] = 1e9;
        let s2 = gaussian_smooth(&m2, &valid, w, h, 1.5);
        assert!(s2.iter().all(|v| (v - 1.0).abs() < 1e-12));
        // an impulse spreads with the normalised Gaussian profile
        let mut imp = vec![0.0f64; w * h];
        imp[2 * w + 3] = 1.0;
        let all = vec![true; w * h];
        let s3 = gaussian_smooth(&imp, &all, w, h, 1.0);
        let den_at_centre: f64 = (-2i64..=2)
            .flat_map(|dy| (-3i64..=3).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| (-((dx * dx + dy * dy) as f64) / 2.0).exp())
            .sum();
        assert!((s3[2 * w + 3] - 1.0 / den_at_centre).abs() < 1e-12);
        assert!(s3[2 * w + 4] > 0.0 && s3[2 * w + 4] < s3[2 * w + 3]);
        // no valid pixel in the window → 0
        let none = vec![false; w * h];
        assert!(gaussian_smooth(&m, &none, w, h, 1.0)
            .iter()
            .all(|&v| v == 0.0));
        assert_eq!(gaussian_radius(1.0), 3);
        assert_eq!(gaussian_radius(1.5), 5);
    }
}
