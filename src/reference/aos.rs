//! AOS, adaptive-order polynomial fitting in feature space (spec §5), in f64
//! from the definitions: the reference of the CPU path (and of GPU kernels
//! to come).
//!
//! Per pixel `c`: the TSVD local space (§0.6) of the window's features
//! `(px, py, depth, albedo rgb, normal xyz[, visibility])`, the local
//! coordinates `Δz ∈ R^k`, a spatial Gaussian kernel (`h = R`), and the
//! *partial* polynomial design of element-wise powers
//! `[1, Δz, Δz², …, Δz⁵]` (columns ordered by power, so order `l`'s design
//! is a leading block). One order-5 fit on grey gives the bias image of each
//! candidate order `l ∈ {1, 3}` (its next two powers, AOS-ONEFIT) and `σ*²`;
//! the order of least `var_l + bias_l²` filters each channel.
//!
//! [`nlmeans`] is the feature prefilter of §5.2.

use super::linalg::{ridge_cholesky, RidgeCholesky, EPS_PIVOT};
use super::tsvd::{local_coords, local_space};

/// Window radius of the final pass (19×19).
pub const RADIUS_FINAL: usize = 9;
/// Window radius of the intermediate passes (11×11).
pub const RADIUS_INTERMEDIATE: usize = 5;
/// Candidate orders `l` (Alg. 1: `l = 1, 1 + a, …, p_max`).
pub const ORDERS: [usize; 2] = [1, 3];
/// Increment `a`: order `l`'s bias comes from powers `l+1 ..= l+a`.
pub const INCREMENT: usize = 2;
/// The high order `P* = p_max + a` fitted once (AOS-ONEFIT).
pub use crate::shared::AOS_P_STAR as P_STAR;
/// Ridge factor: `λ = 1e-5·Σ K_i` (§5.3 step 3).
pub const RIDGE: f64 = 1e-5;
/// AOS-SCALE: a column whose weighted RMS is below this is dropped.
pub const RMS_EPS: f64 = 1e-12;
/// `ε` of the sampling formula for AOS (§5.3 step 8).
pub const EPSILON: f64 = 1e-4;
/// NL-means search radius (11×11, NLM-PARAMS).
pub const NLM_SEARCH: usize = 5;
/// NL-means patch radius (7×7, NLM-PARAMS).
pub const NLM_PATCH: usize = 3;
/// NL-means `k` (NLM-K).
pub const NLM_K: f64 = 1.0;

/// The variance estimate of §5.3 step 5 (`aos.variance`).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Variance {
    /// `[A_l⁻¹ B_l A_l⁻¹]_00 · σ*²` (the paper as written, default).
    #[default]
    Paper,
    /// `Σ_i (l^{(l)}_i)² vbar_i`, the exact variance of the order-l estimate.
    Sandwich,
}

/// The image AOS reads: colour and its variance, the feature planes in §5.1's
/// order after the prefilter, their variances, validity.
#[derive(Clone, Copy)]
pub struct Planes<'a> {
    /// Width in pixels.
    pub w: usize,
    /// Height in pixels.
    pub h: usize,
    /// Colour R, G, B.
    pub color: [&'a [f64]; 3],
    /// `vbar`: the mean of the three colour variances (§0.1).
    pub vbar: &'a [f64],
    /// Feature planes: depth, albedo r g b, normal x y z[, visibility]
    /// (pixel coordinates are added by [`Planes::features`]).
    pub feats: &'a [Vec<f64>],
    /// Their variances (of the mean).
    pub fvar: &'a [Vec<f64>],
    /// Valid pixels (§0.2).
    pub valid: &'a [bool],
    /// Sample counts (AOS-RESIDUAL's threshold).
    pub spp: &'a [f64],
}

impl Planes<'_> {
    /// Feature dimension `D`: 2 coordinates + the planes (10, or 9 without
    /// visibility).
    pub fn d(&self) -> usize {
        2 + self.feats.len()
    }

    /// Raw features and variances of pixel `q` (§5.1): `(px, py, …)` with
    /// variance 0 for the coordinates.
    pub fn features(&self, q: usize, x: &mut [f64], e2: &mut [f64]) {
        x[0] = (q % self.w) as f64;
        x[1] = (q / self.w) as f64;
        e2[0] = 0.0;
        e2[1] = 0.0;
        for (j, (f, v)) in self.feats.iter().zip(self.fvar).enumerate() {
            x[2 + j] = f[q];
            e2[2 + j] = v[q];
        }
    }

    /// [`all_black`] at pixel `q`.
    pub fn all_black(&self, q: usize) -> bool {
        all_black(self.vbar[q], [0, 1, 2].map(|ch| self.color[ch][q]))
    }

    /// `grey = (R + G + B)/3` of pixel `q` (§0.1).
    pub fn grey(&self, q: usize) -> f64 {
        (self.color[0][q] + self.color[1][q] + self.color[2][q]) / 3.0
    }
}

/// The design of one pixel's window at order [`P_STAR`]: accepted (valid)
/// pixels, kernel weights, scaled columns.
#[derive(Clone, Debug)]
pub struct Design {
    /// The centre pixel.
    pub centre: usize,
    /// The window's valid pixels in raster order.
    pub idx: Vec<usize>,
    /// `K_i = exp(−|i−c|²/(2h²))`, `h = R` (AOS-H).
    pub kh: Vec<f64>,
    /// The TSVD rank `k` (§0.6), the local dimension `d` of the sample map.
    pub rank: usize,
    /// Columns kept, as `(power v, component j)`; column 0 (`(0, 0)`) is the
    /// intercept. Ordered by power, then component.
    pub cols: Vec<(usize, usize)>,
    /// Rows, `idx.len() × cols.len()` row-major, scaled (AOS-SCALE).
    pub rows: Vec<f64>,
    /// `Σ_i K_i x_i x_iᵀ` over all columns (unregularised), formed once:
    /// every order's normal matrix is a leading block of it.
    pub normal: Vec<f64>,
    /// Each column's AOS-SCALE factor.
    pub scale: Vec<f64>,
    /// `∂Δz_m/∂x_j` = the projection `P[m][j]` (`rank × d` row-major):
    /// AOS-FEATNOISE's chain rule.
    pub grad: Vec<f64>,
    /// The centre's feature standard deviations (of the mean), `d` values.
    pub centre_sd: Vec<f64>,
}

impl Design {
    /// Number of columns of order ≤ `l` (the leading block).
    pub fn p(&self, l: usize) -> usize {
        self.cols.iter().filter(|c| c.0 <= l).count()
    }

    /// `Σ_i w_i x_i x_iᵀ` over the leading `p` columns with weights `w`.
    fn gram(&self, p: usize, w: impl Fn(usize) -> f64) -> Vec<f64> {
        let pc = self.cols.len();
        let mut a = vec![0.0; p * p];
        for r in 0..self.idx.len() {
            let x = &self.rows[r * pc..r * pc + p];
            let wr = w(r);
            for i in 0..p {
                for j in 0..p {
                    a[i * p + j] += wr * x[i] * x[j];
                }
            }
        }
        a
    }

    /// Row `r`'s leading `p` entries.
    pub fn row(&self, r: usize, p: usize) -> &[f64] {
        let pc = self.cols.len();
        &self.rows[r * pc..r * pc + p]
    }
}

/// Builds the design of pixel `c` with window radius `radius` (§5.3 steps
/// 1–3, the columns up to order [`P_STAR`]).
pub fn design(pl: &Planes, c: usize, radius: usize) -> Design {
    design_with(pl, c, radius, false)
}

/// Decision AOS-OUTLIER-W (ours): with option `aos.outlier_weight`, the
/// kernel is `K_i·o_i` with `o_i = 1/max(vbar_i, 1)`, WLR's OUTLIER-W (spec
/// §2.3 step 2) and APR's APR-OUTLIER-W applied to AOS. Every sum of §5.3
/// reads it (the normal matrix, the right-hand sides, the kernels `l_i`, the
/// variances); the equivalent kernels still sum to 1.
///
/// Why: AOS has no rejection. Next to a light seen directly, the window of
/// a dark pixel holds the light's edge pixels (bright, variance in the
/// hundreds), and the low-order fit follows them; their bias estimate is
/// too noisy for AOS-BIAS-TEST to count it. Pixels with variances below 1,
/// almost all of a typical render's, keep `K_i`.
pub fn outlier_weight(vbar: f64) -> f64 {
    1.0 / vbar.max(1.0)
}

/// [`design`] with the kernel `K_i·o_i` of AOS-OUTLIER-W when
/// `outlier_weight`.
pub fn design_with(pl: &Planes, c: usize, radius: usize, outlier_weight_on: bool) -> Design {
    let (w, h) = (pl.w, pl.h);
    let (cx, cy) = (c % w, c / w);
    let d = pl.d();
    let mut idx = Vec::new();
    let mut x = Vec::new();
    let mut e2 = Vec::new();
    let (mut xi, mut ei) = (vec![0.0; d], vec![0.0; d]);
    for qy in cy.saturating_sub(radius)..(cy + radius + 1).min(h) {
        for qx in cx.saturating_sub(radius)..(cx + radius + 1).min(w) {
            let q = qy * w + qx;
            if !pl.valid[q] {
                continue;
            }
            pl.features(q, &mut xi, &mut ei);
            idx.push(q);
            x.extend_from_slice(&xi);
            e2.extend_from_slice(&ei);
        }
    }
    let ls = local_space(&x, &e2, d);
    let mut xc = vec![0.0; d];
    pl.features(c, &mut xc, &mut ei);
    let centre_sd: Vec<f64> = ei.iter().map(|v| v.max(0.0).sqrt()).collect();
    let grad: Vec<f64> = (0..ls.k)
        .flat_map(|m| (0..d).map(move |j| (m, j)))
        .map(|(m, j)| ls.projection_entry(m, j))
        .collect();
    let k = ls.k;
    let dz: Vec<Vec<f64>> = (0..idx.len())
        .map(|r| local_coords(&ls, &x[r * d..(r + 1) * d], &xc))
        .collect();
    let bw = radius.max(1) as f64;
    let kh: Vec<f64> = idx
        .iter()
        .map(|&q| {
            let dx = (q % w) as f64 - cx as f64;
            let dy = (q / w) as f64 - cy as f64;
            let o = if outlier_weight_on {
                outlier_weight(pl.vbar[q])
            } else {
                1.0
            };
            (-(dx * dx + dy * dy) / (2.0 * bw * bw)).exp() * o
        })
        .collect();
    let ksum: f64 = kh.iter().sum();
    // Columns by power, then component; AOS-SCALE divides each by its
    // weighted RMS and drops the ones below RMS_EPS.
    let mut cols = vec![(0, 0)];
    let mut scale = vec![1.0];
    for v in 1..=P_STAR {
        for j in 0..k {
            let ms = dz
                .iter()
                .zip(&kh)
                .map(|(z, &kw)| kw * z[j].powi(v as i32).powi(2))
                .sum::<f64>()
                / ksum;
            let rms = ms.sqrt();
            if rms >= RMS_EPS {
                cols.push((v, j));
                scale.push(1.0 / rms);
            }
        }
    }
    let rows: Vec<f64> = dz
        .iter()
        .flat_map(|z| {
            cols.iter()
                .zip(&scale)
                .map(|(&(v, j), &s)| if v == 0 { 1.0 } else { z[j].powi(v as i32) * s })
                .collect::<Vec<_>>()
        })
        .collect();
    let mut d = Design {
        centre: c,
        idx,
        kh,
        rank: k,
        cols,
        rows,
        normal: Vec::new(),
        scale,
        grad,
        centre_sd,
    };
    d.normal = d.gram(d.cols.len(), |r| d.kh[r]);
    d
}

/// One order's weighted least-squares system: the factor of
/// `A = XᵀWX + Λ` over the leading `p` columns and `u = A⁻¹ e_1`.
#[derive(Clone, Debug)]
pub struct Fit {
    /// Columns used.
    pub p: usize,
    /// The ridge Cholesky factor (SOLVE-FAIL retries included).
    pub chol: RidgeCholesky,
    /// `u = A⁻¹ e_1`: the equivalent kernel is `l_i = K_i uᵀ x_i` (§0.5).
    pub u: Vec<f64>,
}

impl Fit {
    /// `β = A⁻¹ Xᵀ W z` over the design's pixels (`z` of a pixel index).
    pub fn beta(&self, d: &Design, z: impl Fn(usize) -> f64) -> Vec<f64> {
        let mut rhs = vec![0.0; self.p];
        for (r, (&q, &kw)) in d.idx.iter().zip(&d.kh).enumerate() {
            let zq = z(q);
            for (a, x) in rhs.iter_mut().zip(d.row(r, self.p)) {
                *a += kw * x * zq;
            }
        }
        self.chol.solve(&rhs)
    }

    /// The equivalent kernel `l_i = K_i uᵀ x_i` at the centre (§0.5).
    pub fn kernel(&self, d: &Design) -> Vec<f64> {
        (0..d.idx.len())
            .map(|r| {
                d.kh[r]
                    * d.row(r, self.p)
                        .iter()
                        .zip(&self.u)
                        .map(|(x, u)| x * u)
                        .sum::<f64>()
            })
            .collect()
    }

    /// `[A⁻¹ B A⁻¹]_00 = uᵀ B u` with `B = Xᵀ W² X` (§5.3 step 5).
    pub fn sandwich00(&self, d: &Design) -> f64 {
        let b = d.gram(self.p, |r| d.kh[r] * d.kh[r]);
        let p = self.p;
        let mut s = 0.0;
        for i in 0..p {
            for j in 0..p {
                s += self.u[i] * b[i * p + j] * self.u[j];
            }
        }
        s
    }
}

impl Fit {
    /// Order `l`'s system as the leading block of this (order-5) fit: the
    /// Cholesky factor of a leading block of `A + Λ` is the leading block of
    /// the factor, at the same ridge (decision AOS-ONE-RIDGE, see [`pixel`]).
    pub fn leading(&self, d: &Design, l: usize) -> Fit {
        let (p, pc) = (d.p(l), self.p);
        let l_lead: Vec<f64> = (0..p)
            .flat_map(|i| self.chol.l[i * pc..i * pc + p].iter().copied())
            .collect();
        let chol = RidgeCholesky {
            p,
            l: l_lead,
            ..self.chol.clone()
        };
        let mut e1 = vec![0.0; p];
        e1[0] = 1.0;
        let u = chol.solve(&e1);
        Fit { p, chol, u }
    }
}

/// Factors order `l`'s system (all columns of power ≤ `l`) with ridge
/// `lambda`; `None` on SOLVE-FAIL.
pub fn fit(d: &Design, l: usize, lambda: f64) -> Option<Fit> {
    let (p, pc) = (d.p(l), d.cols.len());
    let a: Vec<f64> = (0..p)
        .flat_map(|i| d.normal[i * pc..i * pc + p].iter().copied())
        .collect();
    let chol = ridge_cholesky(&a, p, lambda, EPS_PIVOT);
    if chol.failed {
        return None;
    }
    let mut e1 = vec![0.0; p];
    e1[0] = 1.0;
    let u = chol.solve(&e1);
    Some(Fit { p, chol, u })
}

/// Decision AOS-BIAS-TEST (ours): with option `aos.bias_test`, an order's
/// estimated bias counts in its MSE only when it is significant,
/// `|bias_l| > BIAS_Z · sd(bias_l)`. The bias estimate is a linear function
/// of the data, `Σ_j g_j grey_j`, so its variance `Σ_j g_j² vbar_j` is known.
/// Without the test the noise of the estimate decides the order: order 1's
/// bias comes from the order-2 and order-3 coefficients of the order-5 fit
/// (AOS-ONEFIT), which are as noisy as that fit and noisier than order 1
/// itself, at any noise level (`tests/aos.rs`).
pub const BIAS_Z: f64 = 2.0;

/// Decision AOS-FEATNOISE (ours): with option `aos.feature_noise`, the
/// variance the chosen order's output inherits from the centre's own noisy
/// features, added to the exported error estimate. Neither the order choice
/// nor the sample map (`E_i = MSE_l̂`, §5.3 step 8) sees it: in the choice
/// the input won where low-spp features are noisy, and in the map it made
/// adaptive AOS worse, since its noise falls as `1/n`, not at the rate the
/// map assumes.
///
/// Every `Δz_i = P (x_i − x_c)` moves with the centre's features, so the
/// fitted value moves by `−∇f·P δx_c`; at `Δz = 0` only the power-1
/// columns have a gradient. With `g_j = Σ_m β_(1,m) s_(1,m) P[m][j]`
/// (`β` the order's coefficients on grey, `s` the AOS-SCALE factors) the
/// term is `(Σ_j |g_j| σ_j)²`, the features' noise taken as fully
/// correlated (they are means over the same samples), as LP-FEATNOISE does
/// for LP.
///
/// Why: at the edge of a light, a pixel's albedo, normal and
/// visibility carry the same coverage noise as its colour, so the fit
/// follows them and reproduces the noisy input with a residual of 0 and an
/// estimated MSE far below its squared error.
pub fn feature_noise(d: &Design, beta: &[f64]) -> f64 {
    let dim = d.centre_sd.len();
    let mut g = vec![0.0; dim];
    for (i, &(v, m)) in d.cols.iter().enumerate().take(beta.len()) {
        if v == 1 {
            let c = beta[i] * d.scale[i];
            for (gj, p) in g.iter_mut().zip(&d.grad[m * dim..(m + 1) * dim]) {
                *gj += c * p;
            }
        }
    }
    let s: f64 = g.iter().zip(&d.centre_sd).map(|(g, sd)| g.abs() * sd).sum();
    s * s
}

/// AOS-RESIDUAL: `vbar` below this counts as this in the window's geometric
/// mean (a zero variance has no logarithm).
pub const RESIDUAL_VBAR_FLOOR: f64 = 1e-20;

/// AOS-RESIDUAL's variance of the pixel itself: `max(vbar_c, s_geo / n_c)`
/// with `s_geo = exp(Σ K_i (ln max(vbar_i, floor) + ln n_i) / Σ K_i)` (the
/// terms of [`residual_ln_term`]), the window's
/// kernel-weighted geometric mean of the *per-sample* variances
/// (`lnsum = Σ K_i ln …`, `ksum = Σ K_i`), over the centre's sample count
/// `n_c`. Under uniform sampling that is the geometric mean of `vbar`; under
/// adaptive sampling a centre with more samples than its window is not
/// given its neighbours' larger variances of the mean. Both sums skip the
/// [`all_black`] pixels: with no pixel left (`ksum = 0`) the result is
/// `vbar_c`.
pub fn residual_centre_var(vbar_c: f64, lnsum: f64, ksum: f64, n_c: f64) -> f64 {
    if ksum > 0.0 {
        vbar_c.max((lnsum / ksum).exp() / n_c.max(1.0))
    } else {
        vbar_c
    }
}

/// The term of [`residual_centre_var`]'s `lnsum` for a window pixel with
/// variance of the mean `vbar` over `n ≥ 1` samples: `ln max(vbar, floor) +
/// ln n` (a sum of logarithms, so that the f32 GPU kernel never forms the
/// product, which could overflow).
pub fn residual_ln_term(vbar: f64, n: f64) -> f64 {
    vbar.max(RESIDUAL_VBAR_FLOOR).ln() + n.max(1.0).ln()
}

/// Decision ALL-BLACK (ours): a pixel whose samples all came out black
/// (`vbar` 0 and colour 0 in every channel) says nothing of the noise
/// around it, so AOS-RESIDUAL's window mean and AOS-IDENTITY-FLOOR's median
/// leave it out. Where light arrives by rare paths, most pixels of a
/// region can miss them all; their zero variances pulled both statistics
/// to 0, and a black pixel kept its black input. A pixel of one steady
/// non-zero colour (a lamp, the sky) is still counted: its variance 0 is
/// real.
pub fn all_black(vbar: f64, rgb: [f64; 3]) -> bool {
    vbar <= 0.0 && rgb.iter().all(|&c| c <= 0.0)
}

/// AOS-RESIDUAL: the bias² an order's residual at the centre shows, or 0.
/// `res = ŷ_l − grey_c`; `res_var = Σ_i (l_i − δ_ic)² v_i` with the
/// centre's `v` from [`residual_centre_var`]; `n` the centre's samples.
pub fn residual_bias2(res: f64, res_var: f64, n: f64) -> f64 {
    let z = super::t_threshold3(n);
    if res * res > z * z * res_var {
        res * res - res_var
    } else {
        0.0
    }
}

/// The choices of §5.3 that are options.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Settings {
    /// `aos.variance` (AOS-VAR).
    pub variance: Variance,
    /// `aos.bias_test` (AOS-BIAS-TEST).
    pub bias_test: bool,
    /// `aos.identity` (AOS-IDENTITY, see [`pixel`]).
    pub identity: bool,
    /// `aos.identity_floor` (AOS-IDENTITY-FLOOR, see [`identity_mse`]).
    pub identity_floor: bool,
    /// `aos.outlier_weight` (AOS-OUTLIER-W, see [`outlier_weight`]).
    pub outlier_weight: bool,
    /// `aos.residual` (AOS-RESIDUAL, see [`pixel`]).
    pub residual: bool,
    /// `aos.feature_noise` (AOS-FEATNOISE, see [`feature_noise`]).
    pub feature_noise: bool,
}

impl Settings {
    /// The `aos_fit` kernel's [`crate::shared::AosPush::flags`] for these
    /// settings.
    pub fn flags(&self) -> u32 {
        use crate::shared::{
            AOS_BIAS_TEST, AOS_FEATNOISE, AOS_IDENTITY, AOS_IDENTITY_FLOOR, AOS_OUTLIER_W,
            AOS_RESIDUAL, AOS_SANDWICH,
        };
        let bit = |on: bool, b: u32| if on { b } else { 0 };
        bit(self.variance == Variance::Sandwich, AOS_SANDWICH)
            | bit(self.bias_test, AOS_BIAS_TEST)
            | bit(self.identity, AOS_IDENTITY)
            | bit(self.identity_floor, AOS_IDENTITY_FLOOR)
            | bit(self.outlier_weight, AOS_OUTLIER_W)
            | bit(self.residual, AOS_RESIDUAL)
            | bit(self.feature_noise, AOS_FEATNOISE)
    }

    /// The spec's AOS as written: none of our decisions.
    pub const SPEC: Settings = Settings {
        variance: Variance::Paper,
        bias_test: false,
        identity: false,
        identity_floor: false,
        outlier_weight: false,
        residual: false,
        feature_noise: false,
    };
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            variance: Variance::Paper,
            bias_test: true,
            identity: true,
            identity_floor: true,
            outlier_weight: true,
            residual: true,
            feature_noise: true,
        }
    }
}

/// What one pixel's reconstruction returns (§5.3 steps 6–8 and §5.5's debug
/// outputs).
#[derive(Clone, Debug, PartialEq)]
pub struct Pixel {
    /// The output colour.
    pub color: [f64; 3],
    /// `MSE_c = MSE_l̂`, shared by the channels (`vbar_c` for the input):
    /// the sample map's `E_i` (§5.3 step 8).
    pub mse: f64,
    /// AOS-FEATNOISE's term for the chosen order ([`feature_noise`]; 0 for
    /// the input or with the option off). The exported error estimate is
    /// `mse + feat_var`.
    pub feat_var: f64,
    /// The chosen order `l̂`; 0: the pixel's input (AOS-IDENTITY or
    /// AOS-FALLBACK).
    pub order: usize,
    /// TSVD rank `k` (the local dimension `d`).
    pub rank: usize,
    /// `bias_l` for l = 1, 3 (0 where not computed).
    pub bias: [f64; 2],
    /// The standard error of each `bias_l` estimate.
    pub bias_sd: [f64; 2],
    /// `var_l` for l = 1, 3.
    pub var: [f64; 2],
    /// `σ*²` of the order-5 fit.
    pub sigma2: f64,
}

/// AOS at pixel `c` (§5.3). `lambda_factor` is [`RIDGE`] (tests use 0).
///
/// Decision AOS-FALLBACK (ours): after §0.5 SOLVE-FAIL, a pixel whose rank
/// is 0 (a window of one pixel), or whose order-5 system fails, outputs its
/// input with error `vbar_c`.
///
/// Decision AOS-RESIDUAL (ours): with option `aos.residual`, an order's own
/// residual at the centre bounds its bias from below. `res = ŷ_l − grey_c`
/// has `E[res²] = bias_l² + Σ_i (l_i − δ_ic)² v_i`. Where `res²` exceeds
/// that variance [`t_threshold3`](super::t_threshold3)`(n_c)²` times, `res² − res_var`
/// replaces `bias_l²` if larger. The order-5 fit only sees the bias that
/// powers 2–5 of the same features explain; a fit that is off because the
/// features do not explain the colour (a defocused edge, the ceiling next
/// to a light) kept an error estimate orders of magnitude below its error,
/// so the sample map starved those pixels. The centre's `v_c` is
/// [`residual_centre_var`]: a pixel that missed the rare bright paths of
/// its neighbours has a variance estimate far below its true variance, and
/// with `vbar_c` alone the test fired on indirect light.
///
/// Decision AOS-ONE-RIDGE (ours): after §0.5 SOLVE-FAIL, the orders share
/// the order-5 system's factorisation, so they share its ridge. Each order's
/// factor is the leading block of the order-5 factor (§5.4), and when the
/// order-5 system needs a raised ridge, orders 1 and 3 use it too. The GPU
/// factors once per pixel.
///
/// Decision AOS-IDENTITY (ours): with option `aos.identity`, the pixel's
/// own input is a third candidate, with bias 0 and MSE `vbar_c`. It is the
/// same idea as APR's PF-IDENTITY. AOS has a fixed spatial bandwidth and no
/// rejection, so a sharp, nearly noise-free highlight with the same
/// features as its surroundings is spread over 19×19 pixels by every
/// order, and AOS as specified scored worse than its input there.
pub fn pixel(pl: &Planes, c: usize, radius: usize, set: Settings, lambda_factor: f64) -> Pixel {
    let fallback = |rank: usize| Pixel {
        color: [pl.color[0][c], pl.color[1][c], pl.color[2][c]],
        mse: pl.vbar[c],
        feat_var: 0.0,
        order: 0,
        rank,
        bias: [0.0; 2],
        bias_sd: [0.0; 2],
        var: [0.0; 2],
        sigma2: 0.0,
    };
    let d = design_with(pl, c, radius, set.outlier_weight);
    if d.rank == 0 {
        return fallback(0);
    }
    let lambda = lambda_factor * d.kh.iter().sum::<f64>();
    let Some(star) = fit(&d, P_STAR, lambda) else {
        return fallback(d.rank);
    };
    let pc = d.cols.len();
    let beta_star = star.beta(&d, |q| pl.grey(q));
    let lstar = star.kernel(&d);
    let sigma2: f64 = lstar
        .iter()
        .zip(&d.idx)
        .map(|(l, &q)| l * l * pl.vbar[q])
        .sum();
    let mut best: Option<(usize, f64, Vec<f64>)> = None;
    let mut best_fit: Option<Fit> = None;
    // AOS-RESIDUAL's variance of the centre, from the window's geometric
    // mean of per-sample variances (all-black pixels left out).
    let v_c = set.residual.then(|| {
        let (mut lnsum, mut ksum) = (0.0, 0.0);
        for (k, &q) in d.kh.iter().zip(&d.idx) {
            if !pl.all_black(q) {
                lnsum += k * residual_ln_term(pl.vbar[q], pl.spp[q]);
                ksum += k;
            }
        }
        residual_centre_var(pl.vbar[c], lnsum, ksum, pl.spp[c])
    });
    let mut out = Pixel {
        rank: d.rank,
        sigma2,
        ..fallback(d.rank)
    };
    for (o, &l) in ORDERS.iter().enumerate() {
        let f = star.leading(&d, l);
        let high = |col: &(usize, usize)| col.0 > l && col.0 <= l + INCREMENT;
        // Bias image ξ_i: the order-5 fit's terms of powers l+1 ..= l+a.
        let xi: Vec<f64> = (0..d.idx.len())
            .map(|r| {
                d.cols
                    .iter()
                    .zip(d.row(r, pc))
                    .zip(&beta_star)
                    .filter(|((col, _), _)| high(col))
                    .map(|((_, x), b)| x * b)
                    .sum()
            })
            .collect();
        let kern = f.kernel(&d);
        let bias: f64 = kern.iter().zip(&xi).map(|(k, x)| k * x).sum();
        // bias = Σ_j g_j grey_j with g_j = K_j x*_jᵀ A*⁻¹ P_l Σ_i l_i x*_i.
        let mut t = vec![0.0; pc];
        for (r, &k) in kern.iter().enumerate() {
            for (tv, x) in t.iter_mut().zip(d.row(r, pc)) {
                *tv += k * x;
            }
        }
        for (tv, col) in t.iter_mut().zip(&d.cols) {
            if !high(col) {
                *tv = 0.0;
            }
        }
        let qv = star.chol.solve(&t);
        let bias_var: f64 = (0..d.idx.len())
            .map(|r| {
                let g = d.kh[r]
                    * d.row(r, pc)
                        .iter()
                        .zip(&qv)
                        .map(|(x, q)| x * q)
                        .sum::<f64>();
                g * g * pl.vbar[d.idx[r]]
            })
            .sum();
        let var = match set.variance {
            Variance::Paper => f.sandwich00(&d) * sigma2,
            Variance::Sandwich => kern
                .iter()
                .zip(&d.idx)
                .map(|(k, &q)| k * k * pl.vbar[q])
                .sum(),
        };
        let counted = if !set.bias_test || bias * bias > BIAS_Z * BIAS_Z * bias_var {
            bias
        } else {
            0.0
        };
        let mut bias2 = counted * counted;
        if let Some(v_c) = v_c {
            let (mut res, mut res_var) = (-pl.grey(c), 0.0);
            for (&k, &q) in kern.iter().zip(&d.idx) {
                res += k * pl.grey(q);
                res_var += if q == c {
                    (k - 1.0) * (k - 1.0) * v_c
                } else {
                    k * k * pl.vbar[q]
                };
            }
            bias2 = bias2.max(residual_bias2(res, res_var, pl.spp[c]));
        }
        let mse = var + bias2;
        out.bias[o] = bias;
        out.bias_sd[o] = bias_var.sqrt();
        out.var[o] = var;
        if best.as_ref().map_or(true, |b| mse < b.1) {
            best = Some((l, mse, kern));
            best_fit = Some(f);
        }
    }
    let (Some((l, mse, kern)), Some(f)) = (best, best_fit) else {
        return out;
    };
    if set.identity {
        let v = identity_mse(pl, c, set.identity_floor);
        if v < mse {
            out.mse = v;
            return out;
        }
    }
    for ch in 0..3 {
        out.color[ch] = kern
            .iter()
            .zip(&d.idx)
            .map(|(k, &q)| k * pl.color[ch][q])
            .sum();
    }
    out.order = l;
    out.mse = mse;
    if set.feature_noise {
        out.feat_var = feature_noise(&d, &f.beta(&d, |q| pl.grey(q)));
    }
    out
}

/// The identity candidate's MSE (AOS-IDENTITY): `vbar_c`, and with
/// `floor` (decision AOS-IDENTITY-FLOOR, ours) at least `m / n_c`, with
/// `m` the median (the upper one of an even count) of the per-sample
/// variances `n_q·vbar_q` over the valid pixels of c's 3×3, in f32 as on
/// the GPU. A pixel whose few samples missed the rare paths its neighbours
/// caught has a variance far below its true one, and its noisy input then
/// beat every fit; the median ignores a lone firefly beside it. The
/// [`all_black`] pixels are not counted.
pub fn identity_mse(pl: &Planes, c: usize, floor: bool) -> f64 {
    if !floor {
        return pl.vbar[c];
    }
    identity_floor(
        (pl.w, pl.h),
        c,
        pl.vbar[c],
        pl.spp[c],
        |q| pl.valid[q] && !pl.all_black(q),
        |q| pl.vbar[q] as f32 * pl.spp[q] as f32,
    )
}

/// [`identity_mse`] with the floor, on any planes: `v_c` and `n_c` the
/// centre's variance and count; `counted` (valid and not [`all_black`])
/// and `per_sample` (`n_q·vbar_q` in f32) of any pixel of the `size`
/// image. Also `aos_fit`'s twin.
pub fn identity_floor(
    size: (usize, usize),
    c: usize,
    v_c: f64,
    n_c: f64,
    counted: impl Fn(usize) -> bool,
    per_sample: impl Fn(usize) -> f32,
) -> f64 {
    let (w, h) = size;
    let mut vv: Vec<f32> = super::neighbourhood_3x3(w, h, c)
        .filter(|&q| counted(q))
        .map(per_sample)
        .collect();
    if vv.is_empty() {
        return v_c;
    }
    vv.sort_by(f32::total_cmp);
    v_c.max(vv[vv.len() / 2] as f64 / n_c.max(1.0))
}

/// AOS over the image: every valid pixel (invalid ones are left to the
/// caller, §0.2), on all cores ([`super::par_map`]).
pub fn run(pl: &Planes, radius: usize, set: Settings) -> Vec<Option<Pixel>> {
    super::par_map(pl.w * pl.h, |c| {
        pl.valid[c].then(|| pixel(pl, c, radius, set, RIDGE))
    })
}

/// The NL-means weight `w_pq = exp(−max(0, Dist_pq))` of §5.2 for a buffer
/// of `g.len()` channels with variances `vg`.
pub fn nlm_weight(
    w: usize,
    h: usize,
    g: &[&[f64]],
    vg: &[&[f64]],
    valid: &[bool],
    p: usize,
    q: usize,
) -> f64 {
    let (px, py) = ((p % w) as i64, (p / w) as i64);
    let (qx, qy) = ((q % w) as i64, (q / w) as i64);
    let r = NLM_PATCH as i64;
    let (mut sum, mut count) = (0.0, 0usize);
    for oy in -r..=r {
        for ox in -r..=r {
            let (ax, ay, bx, by) = (px + ox, py + oy, qx + ox, qy + oy);
            let inside = |x: i64, y: i64| x >= 0 && y >= 0 && x < w as i64 && y < h as i64;
            if !inside(ax, ay) || !inside(bx, by) {
                continue;
            }
            let (a, b) = ((ay * w as i64 + ax) as usize, (by * w as i64 + bx) as usize);
            if !valid[a] || !valid[b] {
                continue;
            }
            count += 1;
            for (gc, vc) in g.iter().zip(vg) {
                let (va, vb) = (vc[a].max(0.0), vc[b].max(0.0));
                let diff = gc[a] - gc[b];
                sum += (diff * diff - (va + va.min(vb))) / (1e-10 + NLM_K * NLM_K * (va + vb));
            }
        }
    }
    if count == 0 {
        return 1.0;
    }
    let dist = sum / (g.len() * count) as f64;
    (-dist.max(0.0)).exp()
}

/// The variance-aware NL-means prefilter of one buffer (§5.2): filtered
/// channels and their propagated variances. Invalid pixels keep their input.
pub fn nlmeans(
    w: usize,
    h: usize,
    g: &[&[f64]],
    vg: &[&[f64]],
    valid: &[bool],
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut out: Vec<Vec<f64>> = g.iter().map(|c| c.to_vec()).collect();
    let mut var: Vec<Vec<f64>> = vg.iter().map(|c| c.to_vec()).collect();
    let r = NLM_SEARCH;
    for p in 0..w * h {
        if !valid[p] {
            continue;
        }
        let (px, py) = (p % w, p / w);
        let mut ws = Vec::new();
        for qy in py.saturating_sub(r)..(py + r + 1).min(h) {
            for qx in px.saturating_sub(r)..(px + r + 1).min(w) {
                let q = qy * w + qx;
                if valid[q] {
                    ws.push((q, nlm_weight(w, h, g, vg, valid, p, q)));
                }
            }
        }
        let total: f64 = ws.iter().map(|x| x.1).sum();
        for ch in 0..g.len() {
            out[ch][p] = ws.iter().map(|&(q, wq)| wq * g[ch][q]).sum::<f64>() / total;
            var[ch][p] = ws
                .iter()
                .map(|&(q, wq)| (wq / total).powi(2) * vg[ch][q].max(0.0))
                .sum();
        }
    }
    (out, var)
}
