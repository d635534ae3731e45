//! Feature normalisation and TSVD local space (spec §0.6, `[WLR §4 Eq.5–6, §7]`),
//! shared by the WLR, LP and AOS twins. GPU twin: `spirv/lib/tsvd.glsl`.
//!
//! Given the `n` valid pixels of a window `Ω_c(R)` with raw features
//! `x_i ∈ R^D` and their variances `e2_i`, [`local_space`] computes the
//! per-window min-max normalisation, the singular values of the centred data,
//! the exact spectral norm of the noise matrix, the rank `k` and the retained
//! directions `V_k`; [`local_coords`] then projects a pixel to `Δz ∈ R^k`.
//! Everything is f64.
//!
//! Decision TSVD-ONE-PASS (ours): `G = ZᵀZ` is formed from the window's
//! sums `S1 = Σ y` and `S2 = Σ y yᵀ` of `y = x − x_ref` (the window's first
//! pixel here, the centre on the GPU), as
//! `G_jl = ((n S2_jl − S1_j S1_l)/n)/(ρ_j ρ_l)`, and `EᵀE` from
//! `Σ sqrt(e2_j e2_l)` scaled by `1/(ρ_j ρ_l)`: the same matrices as the
//! spec's normalise-centre-multiply, which lets the GPU visit a window once
//! instead of twice (its min/max/mean pass was a fifth of LP's centre
//! loads). For the pixel coordinates (integers) every sum and
//! `n S2 − S1 S1ᵀ` is exact, so equal spreads in x and y give exactly equal
//! entries here and on the GPU. A window whose range or feature variance
//! could overflow f32 raw sums takes a normalised second pass on the GPU
//! (`TSVD_WIDE_RANGE`, `TSVD_WIDE_E2` in `spirv/lib/tsvd.glsl`).

use super::linalg::{jacobi_eigen, JACOBI_SWEEPS, JACOBI_TOL};

/// A feature component whose window range `ρ_j` is `<= RANGE_EPS` (natural
/// units) is constant: normalised to 0 with variance 0 (spec §0.6 step 1).
pub const RANGE_EPS: f64 = 1e-6;

/// Decision NOISE-CONST (ours): after spec §0.6 step 1, a component whose
/// window range is at most `NOISE_RANGE_C` times its RMS noise,
/// `ρ_j <= 2·sqrt(mean_i e2_ij)`, is constant too. Its standard deviation
/// over the window is at most `ρ_j/2`, below its own noise, so step 6 could
/// never keep it; kept in `E`, its normalised noise `e2/ρ_j²` (huge for a
/// range of float rounding) would set `τ` for every other component. The
/// case is real: a constant albedo averaged in f32 over different sample
/// counts (adaptive sampling) spans a few rounding steps, and every window
/// along an edge fell to MINRANK's two pixel coordinates.
pub const NOISE_RANGE_C: f64 = 2.0;

/// Threshold factor `C` of `τ = C·‖E‖₂` (spec §0.6 step 5, `[WLR §4 Eq.5]`).
pub const TAU_C: f64 = 2.0;

/// Singular values `<= SIGMA_REL · σ_1` are numerically zero (step 6).
pub const SIGMA_REL: f64 = 1e-6;

/// MINRANK: at least `min(MIN_RANK, k_nz)` components are kept (step 6).
pub const MIN_RANK: usize = 2;

/// The TSVD local space of one window (spec §0.6), plus what is needed to
/// re-project other pixels into it (the per-centre state LP stores).
#[derive(Clone, Debug, PartialEq)]
pub struct LocalSpace {
    /// Feature dimension D.
    pub d: usize,
    /// Number of window pixels `n` the space was built from.
    pub n: usize,
    /// Rank `k` after MINRANK: `k = max(#{σ_m > τ, σ_m > 1e-6 σ_1}, min(2, k_nz))`.
    /// 0 only when every component is constant (e.g. `n = 1`).
    pub k: usize,
    /// `k_nz = #{m : σ_m > 1e-6 σ_1}`, the numerical rank of the centred data.
    pub k_nz: usize,
    /// Threshold `τ = 2‖E‖₂`.
    pub tau: f64,
    /// Spectral norm `‖E‖₂ = sqrt(λ_max(EᵀE))` of the normalised noise matrix
    /// (SPECNORM: exact, by the Jacobi routine).
    pub specnorm: f64,
    /// Singular values `σ_1 >= … >= σ_D` of the centred normalised data `Z`.
    pub sigma: Vec<f64>,
    /// Right singular vectors, row-major `D × D`: column `m` (entries
    /// `v[j*D + m]`) is `v_m`, sign-normalised as in `linalg::jacobi_eigen`.
    /// `V_k` is the first `k` columns.
    pub v: Vec<f64>,
    /// Per-component window minimum `m_j` (raw units).
    pub min: Vec<f64>,
    /// Per-component window range `ρ_j = M_j − m_j` (raw units; the component
    /// is treated as constant when `<= RANGE_EPS`).
    pub range: Vec<f64>,
}

impl LocalSpace {
    /// Component `j` of singular vector `m`.
    pub fn vector(&self, j: usize, m: usize) -> f64 {
        self.v[j * self.d + m]
    }

    /// `∂Δz_m/∂x_j` of raw features: `V_jm / ρ_j`, or 0 for a constant
    /// component (the entries of [`Projection::p`]).
    pub fn projection_entry(&self, m: usize, j: usize) -> f64 {
        let inv = if self.range[j] > RANGE_EPS {
            1.0 / self.range[j]
        } else {
            0.0
        };
        self.vector(j, m) * inv
    }

    /// Min-max normalised features `x'` of a raw feature vector (step 1):
    /// `(x_j − m_j)/ρ_j`, or 0 for a constant component.
    pub fn normalise(&self, x: &[f64]) -> Vec<f64> {
        assert_eq!(x.len(), self.d, "LocalSpace::normalise: feature length");
        (0..self.d)
            .map(|j| {
                if self.range[j] > RANGE_EPS {
                    (x[j] - self.min[j]) / self.range[j]
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// Builds the TSVD local space of a window with the f64 Jacobi tolerances.
///
/// `x` holds the `n` raw feature vectors of the window's valid pixels
/// (`n × d`, row-major, any order), `e2` their per-component variances of the
/// mean (same shape; 0 for pixel coordinates; negative values count as 0).
/// `n = 0` gives an all-zero space with `V = I`.
pub fn local_space(x: &[f64], e2: &[f64], d: usize) -> LocalSpace {
    local_space_with(x, e2, d, JACOBI_TOL, JACOBI_SWEEPS)
}

/// [`local_space`] with explicit Jacobi tolerance and sweep limit (1e-6 / 10
/// mimics the f32 kernels).
pub fn local_space_with(x: &[f64], e2: &[f64], d: usize, tol: f64, sweeps: usize) -> LocalSpace {
    assert!(d > 0, "local_space: D = 0");
    assert_eq!(x.len() % d, 0, "local_space: x is not n x {d}");
    assert_eq!(x.len(), e2.len(), "local_space: e2 shape differs from x");
    let n = x.len() / d;

    // 1. min-max normalisation per window
    let mut min = vec![0.0; d];
    let mut range = vec![0.0; d];
    for j in 0..d {
        if n > 0 {
            let (lo, hi) = x
                .iter()
                .skip(j)
                .step_by(d)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            min[j] = lo;
            range[j] = hi - lo;
            // NOISE-CONST
            let esum: f64 = e2.iter().skip(j).step_by(d).map(|&v| v.max(0.0)).sum();
            if range[j] <= NOISE_RANGE_C * (esum / n as f64).sqrt() {
                range[j] = 0.0;
            }
        }
    }
    // 2. centred data matrix Z; 3. G = ZᵀZ; 4. (EᵀE)_jl = Σ_i sqrt(e2'_ij e2'_il).
    // Decision TSVD-ONE-PASS (ours): from the sums S1 = Σ y, S2 = Σ y yᵀ of
    // y = x − x_0 (the first pixel), G_jl = ((n S2_jl − S1_j S1_l) / n) /
    // (ρ_j ρ_l), as the GPU computes it in one pass over the window: for
    // pixel coordinates (integers) every sum and n S2 − S1 S1ᵀ is exact, so
    // equal spreads in x and y give exactly equal entries on both sides
    // (the order of equal singular values is then the index order), where
    // normalising first rounds the two differently.
    let inv: Vec<f64> = range
        .iter()
        .map(|&r| if r > RANGE_EPS { 1.0 / r } else { 0.0 })
        .collect();
    let mut s1 = vec![0.0; d];
    let mut s2 = vec![0.0; d * d];
    let mut ete = vec![0.0; d * d];
    for i in 0..n {
        for j in 0..d {
            let yj = x[i * d + j] - x[j];
            s1[j] += yj;
            for l in 0..d {
                s2[j * d + l] += yj * (x[i * d + l] - x[l]);
                ete[j * d + l] += (e2[i * d + j].max(0.0) * e2[i * d + l].max(0.0)).sqrt();
            }
        }
    }
    let nf = n.max(1) as f64;
    let mut g = vec![0.0; d * d];
    for j in 0..d {
        for l in 0..d {
            g[j * d + l] = (nf * s2[j * d + l] - s1[j] * s1[l]) / nf * inv[j] * inv[l];
            ete[j * d + l] *= inv[j] * inv[l];
        }
    }
    let eg = jacobi_eigen(&g, d, tol, sweeps);
    let sigma: Vec<f64> = eg.values.iter().map(|&l| l.max(0.0).sqrt()).collect();

    // 4. SPECNORM: exact ‖E‖₂; 5. τ
    let ee = jacobi_eigen(&ete, d, tol, sweeps);
    let specnorm = ee.values[0].max(0.0).sqrt();
    let tau = TAU_C * specnorm;

    // 6. rank with MINRANK
    let floor = SIGMA_REL * sigma[0];
    let k_nz = sigma.iter().filter(|&&s| s > floor).count();
    let k_tau = sigma.iter().filter(|&&s| s > tau && s > floor).count();
    let k = k_tau.max(MIN_RANK.min(k_nz));

    LocalSpace {
        d,
        n,
        k,
        k_nz,
        tau,
        specnorm,
        sigma,
        v: eg.vectors,
        min,
        range,
    }
}

/// Local coordinates `Δz_i = V_kᵀ (x'_i − x'_c) ∈ R^k` of a pixel with raw
/// features `x_i` relative to the centre's raw features `x_c` (step 7,
/// `[WLR §4 Eq.6]`). Either pixel may lie outside the window the space was
/// built from (LP re-projection); its normalised values then leave [0, 1].
pub fn local_coords(ls: &LocalSpace, x_i: &[f64], x_c: &[f64]) -> Vec<f64> {
    let xi = ls.normalise(x_i);
    let xc = ls.normalise(x_c);
    (0..ls.k)
        .map(|m| (0..ls.d).map(|j| ls.vector(j, m) * (xi[j] - xc[j])).sum())
        .collect()
}

/// The valid pixels of a window `Ω_c(R)` in raster order, with their raw
/// features (spec §0.2: clipped to the image, never padded).
#[derive(Clone, Debug, PartialEq)]
pub struct Window {
    /// Pixel coordinates `(x, y)` of the gathered pixels, raster order.
    pub pixels: Vec<(usize, usize)>,
    /// Raw features, `pixels.len() × d` row-major.
    pub x: Vec<f64>,
    /// Their variances, same shape.
    pub e2: Vec<f64>,
}

/// Gathers the window of radius `radius` around `(cx, cy)` in a
/// `width × height` image. `load(px, py, x, e2)` fills the `d` raw features
/// and variances of a pixel and returns whether the pixel is valid; invalid
/// pixels are skipped. This mirrors the `load_features` hook of
/// `spirv/lib/tsvd.glsl`.
pub fn gather_window(
    width: usize,
    height: usize,
    cx: usize,
    cy: usize,
    radius: usize,
    d: usize,
    mut load: impl FnMut(usize, usize, &mut [f64], &mut [f64]) -> bool,
) -> Window {
    let mut w = Window {
        pixels: Vec::new(),
        x: Vec::new(),
        e2: Vec::new(),
    };
    let mut x = vec![0.0; d];
    let mut e2 = vec![0.0; d];
    for py in cy.saturating_sub(radius)..(cy + radius + 1).min(height) {
        for px in cx.saturating_sub(radius)..(cx + radius + 1).min(width) {
            if load(px, py, &mut x, &mut e2) {
                w.pixels.push((px, py));
                w.x.extend_from_slice(&x);
                w.e2.extend_from_slice(&e2);
            }
        }
    }
    w
}

/// Feature count of WLR's and LP's [`Projection`] (the 9 features of §2.1),
/// its default.
const D9: usize = 9;

/// The linear map from raw feature differences to local coordinates:
/// `Δz_m = Σ_j p[m][j] (x_j − x_c,j)` with `p[m][j] = V_jm / ρ_j` for `m < k`
/// and non-constant `j` (0 otherwise). Equal to §0.6 step 7.
/// For `D` features: 9 for WLR and LP (§2.1, mirrors `TsvdProj` /
/// `tsvd_projection` of `spirv/lib/tsvd.glsl`), 10 for AOS (§5.1, stored
/// per pixel by `aos_space`).
#[derive(Clone, Debug, PartialEq)]
pub struct Projection<const D: usize = D9> {
    /// Rank `k` of the local space (§0.6 step 6): rows `0..k` of `p` are used.
    pub k: usize,
    /// `p[m][j] = V_jm / ρ_j` for `m < k` and non-constant feature `j`, else 0.
    pub p: [[f64; D]; D],
}

/// Builds the [`Projection`] of a local space of at most `D` features (the
/// entries of the features beyond the space's stay 0: WLR's arrays hold 10
/// entries, 9 of them features without the visibility).
pub fn projection<const D: usize>(ls: &LocalSpace) -> Projection<D> {
    assert!(ls.d <= D, "tsvd::projection: D");
    let mut p = [[0.0; D]; D];
    for (m, row) in p.iter_mut().enumerate().take(ls.k) {
        for (j, v) in row.iter_mut().enumerate().take(ls.d) {
            *v = ls.projection_entry(m, j);
        }
    }
    Projection { k: ls.k, p }
}

impl<const D: usize> Projection<D> {
    /// `Δz` of raw features `x` relative to the centre's `xc`; 0 beyond `k`.
    /// Mirrors `tsvd_dz`.
    #[inline]
    pub fn dz(&self, x: &[f64; D], xc: &[f64; D]) -> [f64; D] {
        let mut dx = [0.0; D];
        for j in 0..D {
            dx[j] = x[j] - xc[j];
        }
        let mut dz = [0.0; D];
        for m in 0..self.k {
            let row = &self.p[m];
            let mut s = 0.0;
            for j in 0..D {
                s += row[j] * dx[j];
            }
            dz[m] = s;
        }
        dz
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    const D: usize = 9;

    /// A full (2R+1)² window of D = 9 features: pixel coordinates, then 7
    /// smooth-plus-random features, with per-component noise variance `var`.
    fn window(rng: &mut Rng, r: usize, var: f64) -> (Vec<f64>, Vec<f64>) {
        let s = 2 * r + 1;
        let mut x = Vec::new();
        let mut e2 = Vec::new();
        for py in 0..s {
            for px in 0..s {
                let (fx, fy) = (px as f64 + 20.0, py as f64 + 30.0);
                x.extend_from_slice(&[fx, fy]);
                e2.extend_from_slice(&[0.0, 0.0]);
                for j in 0..7 {
                    let smooth = (0.1 * (j + 1) as f64 * fx).sin() + 0.05 * fy * j as f64;
                    x.push(smooth + rng.next());
                    e2.push(var * (1.0 + rng.next()));
                }
            }
        }
        (x, e2)
    }

    /// TSVD-ONE-PASS against the spec's words: σ² equal the eigenvalues of
    /// `ZᵀZ` built explicitly (min-max normalise, centre on the mean,
    /// multiply), and ‖E‖₂ that of `EᵀE` from the normalised variances, on
    /// windows whose features sit far from 0 (depth-like offsets of 1e3)
    /// and whose centre is an outlier.
    #[test]
    fn one_pass_sums_give_the_spec_matrices() {
        let mut rng = Rng(17);
        for (offset, outlier) in [(0.0, false), (1e3, false), (1e3, true)] {
            let (mut x, e2) = window(&mut rng, 4, 1e-3);
            let n = x.len() / D;
            for i in 0..n {
                x[i * D + 5] += offset;
            }
            if outlier {
                x[(n / 2) * D + 6] += 5.0;
            }
            let ls = local_space(&x, &e2, D);
            let (min, max) = (0..D)
                .map(|j| {
                    let col = (0..n).map(|i| x[i * D + j]);
                    (
                        col.clone().fold(f64::INFINITY, f64::min),
                        col.fold(f64::NEG_INFINITY, f64::max),
                    )
                })
                .unzip::<_, _, Vec<f64>, Vec<f64>>();
            let xn = |i: usize, j: usize| (x[i * D + j] - min[j]) / (max[j] - min[j]);
            let mean: Vec<f64> = (0..D)
                .map(|j| (0..n).map(|i| xn(i, j)).sum::<f64>() / n as f64)
                .collect();
            let mut g = vec![0.0; D * D];
            let mut ete = vec![0.0; D * D];
            for i in 0..n {
                for j in 0..D {
                    for l in 0..D {
                        g[j * D + l] += (xn(i, j) - mean[j]) * (xn(i, l) - mean[l]);
                        let r2 = |j: usize| e2[i * D + j] / (max[j] - min[j]).powi(2);
                        ete[j * D + l] += (r2(j) * r2(l)).sqrt();
                    }
                }
            }
            let eg = jacobi_eigen(&g, D, JACOBI_TOL, JACOBI_SWEEPS);
            for m in 0..D {
                let want = eg.values[m].max(0.0).sqrt();
                assert!(
                    (ls.sigma[m] - want).abs() <= 1e-9 * (want + eg.values[0].sqrt()),
                    "offset {offset}, outlier {outlier}: σ_{m} {} against {want}",
                    ls.sigma[m]
                );
            }
            let spec = jacobi_eigen(&ete, D, JACOBI_TOL, JACOBI_SWEEPS).values[0].sqrt();
            assert!(
                (ls.specnorm - spec).abs() <= 1e-9 * spec,
                "‖E‖₂ {} against {spec}",
                ls.specnorm
            );
        }
    }

    fn check_orthonormal_vk(ls: &LocalSpace) {
        for a in 0..ls.k {
            for b in 0..ls.k {
                let dot: f64 = (0..ls.d).map(|j| ls.vector(j, a) * ls.vector(j, b)).sum();
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-12, "V_kᵀV_k[{a},{b}] = {dot}");
            }
        }
    }

    #[test]
    fn zero_noise_general_position_keeps_numerical_rank() {
        let mut rng = Rng(1234);
        let (x, _) = window(&mut rng, 5, 0.0);
        let e2 = vec![0.0; x.len()];
        let ls = local_space(&x, &e2, D);
        assert_eq!(ls.n, 121);
        assert_eq!(ls.specnorm, 0.0);
        assert_eq!(ls.tau, 0.0);
        assert_eq!(ls.k_nz, D);
        assert_eq!(ls.k, ls.k_nz);
        check_orthonormal_vk(&ls);
        assert!(ls.sigma.windows(2).all(|w| w[0] >= w[1]));
        // pixel coordinates of a full window: min = corner, range = 2R
        assert_eq!((ls.min[0], ls.range[0]), (20.0, 10.0));
        assert_eq!((ls.min[1], ls.range[1]), (30.0, 10.0));
    }

    #[test]
    fn minrank_keeps_two_components_under_heavy_noise() {
        // Noise above every σ, but within NOISE-CONST's bound nowhere: all
        // nine components stay, τ drops them all, MINRANK keeps two.
        let mut rng = Rng(99);
        let (x, e2) = window(&mut rng, 4, 0.3);
        let ls = local_space(&x, &e2, D);
        assert!(ls.range.iter().all(|&r| r > 0.0), "ranges {:?}", ls.range);
        assert!(
            ls.tau > ls.sigma[0],
            "noise should dominate: τ {} σ {:?}",
            ls.tau,
            ls.sigma
        );
        assert_eq!(ls.k, 2);
        assert!(ls.k >= MIN_RANK.min(ls.k_nz));
        check_orthonormal_vk(&ls);

        // Noise far above the features' ranges: NOISE-CONST makes the seven
        // noisy components constant; the pixel coordinates remain.
        let (x, e2) = window(&mut rng, 4, 1e4);
        let ls = local_space(&x, &e2, D);
        assert!(ls.range[2..].iter().all(|&r| r == 0.0));
        assert_eq!((ls.k_nz, ls.k), (2, 2));
        check_orthonormal_vk(&ls);

        // Only one non-constant component: k_nz = 1, so k = 1.
        let n = 10;
        let mut x1 = vec![0.0; n * 3];
        for i in 0..n {
            x1[i * 3] = i as f64;
            x1[i * 3 + 1] = 5.0;
            x1[i * 3 + 2] = -2.0 + 1e-9 * i as f64; // range 9e-9 <= RANGE_EPS
        }
        let ls1 = local_space(&x1, &vec![0.0; n * 3], 3);
        assert_eq!((ls1.k_nz, ls1.k), (1, 1));
        assert_eq!(ls1.normalise(&[4.5, 5.0, 3.0]), vec![0.5, 0.0, 0.0]);

        // A single pixel, and an empty window: everything constant, k = 0.
        let one = local_space(&[1.0, 2.0], &[0.5, 0.5], 2);
        assert_eq!((one.n, one.k, one.k_nz), (1, 0, 0));
        let none = local_space(&[], &[], 2);
        assert_eq!((none.n, none.k), (0, 0));
        assert_eq!(none.v, vec![1.0, 0.0, 0.0, 1.0]);
    }

    /// NOISE-CONST: a component spanning only float rounding (an albedo of
    /// 0.73 averaged in f32 over different sample counts) with a rounding
    /// variance does not set τ for the others: a depth edge keeps its
    /// component. Without the decision ‖E‖₂ ≈ 900 and k = MINRANK = 2.
    #[test]
    fn a_rounding_range_is_constant_and_does_not_set_tau() {
        let mut rng = Rng(42);
        let (r, d) = (9usize, 4usize);
        let mut x = Vec::new();
        let mut e2 = Vec::new();
        for py in 0..2 * r + 1 {
            for px in 0..2 * r + 1 {
                let depth = if py < r { 4.7 } else { 5.0 } + 1e-3 * rng.next();
                let albedo = 0.73 + 2e-6 * rng.next();
                x.extend_from_slice(&[px as f64, py as f64, depth, albedo]);
                e2.extend_from_slice(&[0.0, 0.0, 1e-6, 1e-8]);
            }
        }
        let ls = local_space(&x, &e2, d);
        assert_eq!(ls.range[3], 0.0, "the albedo is constant");
        assert!(ls.range[2] > 0.29, "the depth is not");
        assert!(ls.specnorm < 1.0, "‖E‖₂ = {}", ls.specnorm);
        assert_eq!(ls.k, 3, "σ = {:?}, τ = {}", ls.sigma, ls.tau);
        // The albedo's range is 2e-6, above RANGE_EPS: step 1 alone keeps it.
        assert!(x.iter().skip(3).step_by(d).fold(0.0f64, |m, &v| m.max(v)) - 0.73 > RANGE_EPS);
    }

    #[test]
    fn rank_follows_the_threshold() {
        // Moderate noise: k between MINRANK and D, every kept σ above τ, and
        // every dropped one below it.
        let mut rng = Rng(5);
        let (x, e2) = window(&mut rng, 5, 0.02);
        let ls = local_space(&x, &e2, D);
        assert!(ls.k >= 2 && ls.k <= D);
        for m in 0..D {
            if m < ls.k && m >= 2 {
                assert!(ls.sigma[m] > ls.tau);
            }
            if m >= ls.k {
                assert!(ls.sigma[m] <= ls.tau);
            }
        }
        check_orthonormal_vk(&ls);
    }

    #[test]
    fn affine_change_of_a_raw_feature_changes_nothing() {
        let mut rng = Rng(77);
        let (x, e2) = window(&mut rng, 5, 0.01);
        let ls = local_space(&x, &e2, D);
        let (j, scale, offset) = (5, 37.5, 1000.0);
        let mut x2 = x.clone();
        let mut e22 = e2.clone();
        for i in 0..x.len() / D {
            x2[i * D + j] = x[i * D + j] * scale + offset;
            e22[i * D + j] = e2[i * D + j] * scale * scale;
        }
        let ls2 = local_space(&x2, &e22, D);
        assert_eq!(ls.k, ls2.k);
        assert!((ls.tau - ls2.tau).abs() < 1e-9 * ls.tau);
        let c = 60; // the window centre
        for i in 0..x.len() / D {
            let a = local_coords(&ls, &x[i * D..(i + 1) * D], &x[c * D..(c + 1) * D]);
            let b = local_coords(&ls2, &x2[i * D..(i + 1) * D], &x2[c * D..(c + 1) * D]);
            assert_eq!(a.len(), ls.k);
            for (p, q) in a.iter().zip(&b) {
                assert!((p - q).abs() < 1e-8, "Δz changed: {p} vs {q}");
            }
        }
    }

    #[test]
    fn local_coords_match_the_definition() {
        let mut rng = Rng(8);
        let (x, e2) = window(&mut rng, 3, 0.001);
        let ls = local_space(&x, &e2, D);
        let xi = &x[3 * D..4 * D];
        let xc = &x[24 * D..25 * D];
        let dz = local_coords(&ls, xi, xc);
        // The centre maps to the origin; norms are preserved when k = D.
        assert!(local_coords(&ls, xc, xc).iter().all(|&v| v == 0.0));
        let full = LocalSpace { k: D, ..ls.clone() };
        let dz_full = local_coords(&full, xi, xc);
        let diff: f64 = ls
            .normalise(xi)
            .iter()
            .zip(ls.normalise(xc))
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        let norm: f64 = dz_full.iter().map(|v| v * v).sum();
        assert!((diff - norm).abs() < 1e-12);
        assert_eq!(&dz_full[..ls.k], &dz[..]);
    }

    #[test]
    fn specnorm_matches_power_iteration() {
        let mut rng = Rng(31);
        let (x, e2) = window(&mut rng, 4, 0.05);
        let ls = local_space(&x, &e2, D);
        let n = ls.n;
        // E explicitly, then power iteration on EᵀE.
        let e: Vec<f64> = (0..n * D)
            .map(|t| {
                let j = t % D;
                if ls.range[j] > RANGE_EPS {
                    e2[t].sqrt() / ls.range[j]
                } else {
                    0.0
                }
            })
            .collect();
        let mut v = vec![1.0; D];
        let mut lambda = 0.0;
        for _ in 0..500 {
            let ev: Vec<f64> = (0..n)
                .map(|i| (0..D).map(|j| e[i * D + j] * v[j]).sum())
                .collect();
            let w: Vec<f64> = (0..D)
                .map(|j| (0..n).map(|i| e[i * D + j] * ev[i]).sum())
                .collect();
            let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            lambda = norm / v.iter().map(|x| x * x).sum::<f64>().sqrt();
            v = w.iter().map(|x| x / norm).collect();
        }
        assert!(
            (ls.specnorm - lambda.sqrt()).abs() < 1e-9 * ls.specnorm,
            "{} vs {}",
            ls.specnorm,
            lambda.sqrt()
        );
        assert_eq!(ls.tau, 2.0 * ls.specnorm);
    }

    #[test]
    fn gather_window_clips_and_skips_invalid() {
        let (w, h) = (6, 4);
        let win = gather_window(w, h, 0, 3, 2, 2, |px, py, x, e2| {
            x[0] = px as f64;
            x[1] = py as f64;
            e2.fill(0.0);
            !(px == 1 && py == 2)
        });
        // x in 0..=2, y in 1..=3, minus (1, 2)
        assert_eq!(win.pixels.len(), 8);
        assert_eq!(win.pixels[0], (0, 1));
        assert_eq!(win.x[..2], [0.0, 1.0]);
        assert!(!win.pixels.contains(&(1, 2)));
    }
}
