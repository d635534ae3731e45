//! Per-pixel routines of WLR (spec §2.3), shared by the twins
//! [`wlr_fit`](super::wlr_fit) and [`wlr_final`](super::wlr_final).
//! GPU twin: `spirv/lib/wlr.glsl`, function by function (same names without
//! the `wlr_` prefix), so a GPU/CPU mismatch can be bisected routine by
//! routine. Everything here is f64.
//!
//! One centre `c` goes through:
//! 1. [`local_space`]: the TSVD of §0.6 on the 9 WLR features (§2.1), then
//!    [`Projection`]: `Δz = V_kᵀ diag(1/ρ) (x_i − x_c)`, which equals
//!    `V_kᵀ (x'_i − x'_c)` of §0.6 step 7 (the window minimum cancels).
//! 2. [`outlier_weight`] (step 2) and [`accepted`] (step 3, WLR-CI).
//! 3. [`curvature`] (step 4): one weighted quadratic fit → `b_j`.
//! 4. [`fits`] (steps 5 and 9): local linear fits at one or more bandwidths.
//! 5. [`parametric`] and [`choose_h`] (steps 6–7), then [`mse_model`] (step 10).
//!
//! [`fit_pixel`] and [`final_pixel`] chain them as the two kernels do. No
//! per-neighbour state is stored between passes: every pass over the window
//! reloads the features and recomputes `Δz` (as the GPU does).

use super::linalg::{ridge_cholesky, EPS_PIVOT};
use super::spp_of;
use super::tsvd::{gather_window, LocalSpace};
pub use super::tsvd::{projection, Projection};
use crate::shared::{WLR_NONNEG, WLR_OUTLIER_CLAMPED, WLR_REJECT};

/// Feature dimension `D` of WLR (§2.1): `(px, py, nrm xyz, dep, albedo rgb)`.
pub const D: usize = 9;
/// WLR's feature arrays: [`D`] and the visibility (WLR-VIS, 10 features;
/// the tenth entry is 0 without it).
pub const DV: usize = 10;
/// WLR-VIS: the local coordinates hold at most the spec's 9 components (the
/// kernels' `TSVD_MAX_RANK`).
pub const MAX_RANK: usize = 9;
/// Trial bandwidths `h_s` (§2.3 step 5).
pub const TRIAL_H: [f64; 5] = [0.2, 0.4, 0.6, 0.8, 1.0];
/// Ridge of the curvature fit (step 4, release value).
pub const CURV_LAMBDA: f64 = 1e-3;
/// Ridge of the trial and final fits (step 5, release value).
pub const FIT_LAMBDA: f64 = 1e-4;
/// B-FLOOR: `b_j = (Hbar_j + BETA0)^{-1/2}`, so `b_j <= 1.25`.
pub const BETA0: f64 = 0.64;
/// WLR-CI: reject when `|grey_i − grey_c| > CI_SIGMAS·(sd_i + sd_c) + CI_MARGIN`.
pub const CI_SIGMAS: f64 = 3.0;
/// WLR-CI absolute margin.
pub const CI_MARGIN: f64 = 0.005;
/// NONNEG: floor of the positive-weight sum.
pub const NONNEG_FLOOR: f64 = 1e-3;
/// H-CASES: the formula's `h_opt` is clamped to `[H_MIN, H_MAX]`.
pub const H_MIN: f64 = 0.01;
/// H-CASES upper clamp (no extrapolation above the largest trial).
pub const H_MAX: f64 = 1.0;
/// H-CASES: `λ1²·n_c` below this → `h_opt = H_MAX`.
pub const LAMBDA_TINY: f64 = 1e-30;

/// Debug flag bits (§2.5). Bit 0: a Cholesky solve failed after its retries
/// (SOLVE-FAIL, §0.5).
pub const FLAG_SOLVE_FAIL: u32 = 1;
/// Bit 1: FEW in the final fit (at most one neighbour with positive weight).
pub const FLAG_FEW: u32 = 2;
/// Bit 2: `k = 0`, pass-through.
pub const FLAG_K0: u32 = 4;
/// Bit 3: `κ1 <= 0`, `h_opt = 0.2`.
pub const FLAG_KAPPA: u32 = 8;
/// Bit 4: `h_opt` clamped to `[0.01, 1]`.
pub const FLAG_CLAMPED: u32 = 16;
/// Bit 5 (wlr_final only): invalid pixel (`spp < 1`), filled with the mean of
/// its valid 3x3 neighbours (§0.2).
pub const FLAG_INVALID: u32 = 32;

/// The planes both WLR kernels read (bindings 0..18 of `wlr_fit`/`wlr_final`).
#[derive(Copy, Clone, Debug)]
pub struct Planes<'a> {
    /// Image width in pixels; every plane has `width * height` values.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// normal x, y, z, depth, albedo r, g, b.
    pub feat: [&'a [f32]; 7],
    /// Their variances (of the mean), same order.
    pub var: [&'a [f32]; 7],
    /// Colour R, G, B.
    pub color: [&'a [f32]; 3],
    /// `vbar = mean of the colour variances` (§0.1).
    pub vbar: &'a [f32],
    /// WLR-VIS: the prefiltered visibility and its variance, the tenth
    /// feature (bindings 18, 19 of `wlr_fit_vis`); `None`: the spec's 9.
    pub vis: Option<[&'a [f32]; 2]>,
    /// Sample count `n` per pixel (f32); valid when `spp_of(n) >= 1` (§0.2).
    pub spp: &'a [f32],
}

impl Planes<'_> {
    /// Raw features `x` and variances `e2` of pixel `(px, py)` (§2.1); returns
    /// whether the pixel is valid (`spp_of >= 1`). Mirrors `load_features`.
    pub fn load_features(&self, px: usize, py: usize, x: &mut [f64], e2: &mut [f64]) -> bool {
        load_features(self.width, &self.feat, &self.var, px, py, x, e2);
        if let Some([v, vv]) = self.vis {
            let q = py * self.width + px;
            x[D] = v[q] as f64;
            e2[D] = vv[q] as f64;
        }
        self.valid(py * self.width + px)
    }

    /// The feature count: [`D`], or [`DV`] with the visibility.
    #[inline]
    pub fn d(&self) -> usize {
        if self.vis.is_some() {
            DV
        } else {
            D
        }
    }

    /// Raw features only (the tenth 0 without the visibility).
    #[inline]
    pub fn features(&self, px: usize, py: usize) -> [f64; DV] {
        let mut x = [0.0; DV];
        x[..D].copy_from_slice(&features(self.width, &self.feat, px, py));
        if let Some([v, _]) = self.vis {
            x[D] = v[py * self.width + px] as f64;
        }
        x
    }

    /// Colour and `vbar` of pixel index `q`. Mirrors `load_colour`.
    #[inline]
    pub fn colour(&self, q: usize) -> ([f64; 3], f64) {
        (
            [
                self.color[0][q] as f64,
                self.color[1][q] as f64,
                self.color[2][q] as f64,
            ],
            self.vbar[q] as f64,
        )
    }

    /// Whether pixel index `q` is valid: `spp_of(spp[q]) >= 1` (§0.2).
    #[inline]
    pub fn valid(&self, q: usize) -> bool {
        spp_of(self.spp[q]) >= 1.0
    }
}

/// The 9 features of §2.1 `(px, py, nrm xyz, dep, albedo rgb)` of pixel
/// `(px, py)` and their variances `(0, 0, …)` from the 7 feature planes
/// (normal x, y, z, depth, albedo r, g, b) and their variance planes.
/// Mirrors the kernels' `load_features`; shared by WLR and LP.
pub fn load_features(
    width: usize,
    feat: &[&[f32]; 7],
    var: &[&[f32]; 7],
    px: usize,
    py: usize,
    x: &mut [f64],
    e2: &mut [f64],
) {
    let q = py * width + px;
    x[0] = px as f64;
    x[1] = py as f64;
    e2[0] = 0.0;
    e2[1] = 0.0;
    for j in 0..7 {
        x[2 + j] = feat[j][q] as f64;
        e2[2 + j] = var[j][q] as f64;
    }
}

/// The 9 raw features only (see [`load_features`]).
#[inline]
pub fn features(width: usize, feat: &[&[f32]; 7], px: usize, py: usize) -> [f64; D] {
    let q = py * width + px;
    let mut x = [0.0; D];
    x[0] = px as f64;
    x[1] = py as f64;
    for j in 0..7 {
        x[2 + j] = feat[j][q] as f64;
    }
    x
}

/// `grey = (R + G + B)/3` (§0.1 GREY).
#[inline]
pub fn grey(y: &[f64; 3]) -> f64 {
    (y[0] + y[1] + y[2]) / 3.0
}

/// What the fits need to know about the centre pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Centre {
    /// Centre column, in pixels.
    pub cx: usize,
    /// Centre row, in pixels.
    pub cy: usize,
    /// Raw features.
    pub x: [f64; DV],
    /// Colour `y_c`.
    pub y: [f64; 3],
    /// `vbar_c`, the mean of the colour variances (§0.1 GREY).
    pub vbar: f64,
    /// `grey_c = (R + G + B)/3` of `y_c` (§0.1 GREY), compared in WLR-CI.
    pub grey: f64,
    /// `sqrt(max(vbar_c, 0))`.
    pub sd: f64,
    /// `n_c = spp_of(spp_c)`.
    pub n: f64,
}

/// The centre's data. Mirrors `wlr_centre`.
pub fn centre(p: &Planes, cx: usize, cy: usize) -> Centre {
    let q = cy * p.width + cx;
    let (y, vbar) = p.colour(q);
    Centre {
        cx,
        cy,
        x: p.features(cx, cy),
        y,
        vbar,
        grey: grey(&y),
        sd: vbar.max(0.0).sqrt(),
        n: spp_of(p.spp[q]),
    }
}

/// Step 1: the TSVD local space (§0.6) of `Ω_c(R)` on the 9 WLR features
/// (10 with the visibility, the rank then at most [`MAX_RANK`]).
pub fn local_space(p: &Planes, cx: usize, cy: usize, radius: usize) -> LocalSpace {
    let d = p.d();
    let win = gather_window(p.width, p.height, cx, cy, radius, d, |px, py, x, e2| {
        p.load_features(px, py, x, e2)
    });
    let mut ls = super::tsvd::local_space(&win.x, &win.e2, d);
    ls.k = ls.k.min(MAX_RANK);
    ls
}

/// Step 2 (OUTLIER-W): `o_i = 1/max(vbar_i, 1)` with [`WLR_OUTLIER_CLAMPED`],
/// else 1.
#[inline]
pub fn outlier_weight(vbar: f64, options: u32) -> f64 {
    if options & WLR_OUTLIER_CLAMPED != 0 {
        1.0 / vbar.max(1.0)
    } else {
        1.0
    }
}

/// Step 3 (WLR-CI): whether neighbour `i` is accepted. Always true for the
/// centre and without [`WLR_REJECT`].
#[inline]
pub fn accepted(grey_i: f64, vbar_i: f64, c: &Centre, is_centre: bool, options: u32) -> bool {
    if options & WLR_REJECT == 0 || is_centre {
        return true;
    }
    let d = (grey_i - c.grey).abs();
    // A NaN difference is accepted, as in the kernel (`!(d > thr)`).
    d <= CI_SIGMAS * (vbar_i.max(0.0).sqrt() + c.sd) + CI_MARGIN || d.is_nan()
}

/// Epanechnikov kernel `K_E(t) = 0.75(1 − t²)` for `|t| < 1`, else 0.
#[inline]
pub fn epanechnikov(t: f64) -> f64 {
    (0.75 * (1.0 - t * t)).max(0.0)
}

/// `Π_{j<k} K_E(Δz_j · inv_bw_j)`, the product kernel. Mirrors `wlr_kernel`.
#[inline]
pub fn kernel_weight(dz: &[f64; DV], inv_bw: &[f64; DV], k: usize) -> f64 {
    let mut w = 1.0;
    for j in 0..k {
        w *= epanechnikov(dz[j] * inv_bw[j]);
    }
    w
}

/// Visits the valid pixels of `Ω_c(R)` in raster order: `f(q, px, py)`.
#[inline]
fn for_window(p: &Planes, c: &Centre, radius: usize, mut f: impl FnMut(usize, usize, usize)) {
    for py in c.cy.saturating_sub(radius)..(c.cy + radius + 1).min(p.height) {
        for px in c.cx.saturating_sub(radius)..(c.cx + radius + 1).min(p.width) {
            let q = py * p.width + px;
            if p.valid(q) {
                f(q, px, py);
            }
        }
    }
}

/// Result of the curvature fit (step 4).
#[derive(Clone, Debug, PartialEq)]
pub struct Curvature {
    /// `b_j` for `j < k`, 0 beyond (and all 0 if `failed`).
    pub b: [f64; DV],
    /// `Hbar_j = (1/3) Σ_ch |2 γ_j[ch]|`.
    pub hbar: [f64; DV],
    /// SOLVE-FAIL: the pixel passes through (flag bit 0).
    pub failed: bool,
}

/// Step 4: weighted quadratic fit `(1, Δz, Δz∘Δz)` (no cross terms, `p = 1+2k`)
/// with weights `o_i Π_j K_E(Δz_ij)`, ridge [`CURV_LAMBDA`], per channel; the
/// curvatures give `b_j = (Hbar_j + β0)^{-1/2}`. No rejection here.
/// Mirrors `wlr_curvature`.
pub fn curvature(
    p: &Planes,
    pr: &Projection<DV>,
    c: &Centre,
    radius: usize,
    options: u32,
) -> Curvature {
    let k = pr.k;
    let np = 1 + 2 * k;
    let mut a = [0.0; 19 * 19];
    let mut rhs = [[0.0; 19]; 3];
    let ones = [1.0; DV];
    for_window(p, c, radius, |q, px, py| {
        let x = p.features(px, py);
        let (y, vb) = p.colour(q);
        // Centred responses y − y_c: only the intercept changes (as on the GPU,
        // where this saves f32 precision).
        let y = [y[0] - c.y[0], y[1] - c.y[1], y[2] - c.y[2]];
        let dz = pr.dz(&x, &c.x);
        let w = outlier_weight(vb, options) * kernel_weight(&dz, &ones, k);
        if w > 0.0 {
            let mut xr = [0.0; 19];
            xr[0] = 1.0;
            for j in 0..k {
                xr[1 + j] = dz[j];
                xr[1 + k + j] = dz[j] * dz[j];
            }
            for r in 0..np {
                let wr = w * xr[r];
                for col in r..np {
                    a[r * np + col] += wr * xr[col];
                }
                for ch in 0..3 {
                    rhs[ch][r] += wr * y[ch];
                }
            }
        }
    });
    let chol = ridge_cholesky(&a[..np * np], np, CURV_LAMBDA, EPS_PIVOT);
    let mut out = Curvature {
        b: [0.0; DV],
        hbar: [0.0; DV],
        failed: chol.failed,
    };
    if chol.failed {
        return out;
    }
    for r in rhs.iter() {
        let beta = chol.solve(&r[..np]);
        for j in 0..k {
            out.hbar[j] += (2.0 * beta[1 + k + j]).abs() / 3.0;
        }
    }
    for j in 0..k {
        out.b[j] = 1.0 / (out.hbar[j] + BETA0).sqrt();
    }
    out
}

/// One local linear fit (step 5 / step 9).
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// `f̂[ch]` (NONNEG applied when on).
    pub f: [f64; 3],
    /// `bias_s = (1/3) Σ_ch (f̂[ch] − y_c[ch])`.
    pub bias: f64,
    /// `var_s = Σ_i l_i² vbar_i`.
    pub var: f64,
    /// [`FLAG_SOLVE_FAIL`] and/or [`FLAG_FEW`].
    pub flags: u32,
    /// Number of neighbours with `w_i > 0`.
    pub npos: usize,
    /// Whether NONNEG replaced the weights.
    pub nonneg: bool,
}

/// Steps 5/9: one local linear fit `(1, Δz)` (`p = k+1`, ridge `lambda`) per
/// bandwidth in `h`, with weights `w_i = acc_i o_i Π_j K_E(Δz_ij/(h b_j))`,
/// FEW, SOLVE-FAIL (→ `y_c`, bias 0, var `vbar_c`), NONNEG. Two passes over the
/// window: normal matrices, then the equivalent kernels `l_i`. `b` must be
/// positive for `j < k`. Mirrors `wlr_fits`.
pub fn fits(
    p: &Planes,
    pr: &Projection<DV>,
    c: &Centre,
    b: &[f64; DV],
    h: &[f64],
    radius: usize,
    options: u32,
    lambda: f64,
) -> Vec<Fit> {
    let k = pr.k;
    let np = k + 1;
    let nh = h.len();
    let inv_bw: Vec<[f64; DV]> = h
        .iter()
        .map(|&hs| {
            let mut inv = [0.0; DV];
            for j in 0..k {
                inv[j] = 1.0 / (hs * b[j]);
            }
            inv
        })
        .collect();
    let cidx = c.cy * p.width + c.cx;
    // The base weight acc_i·o_i and Δz of a neighbour.
    let neighbour = |q: usize, px: usize, py: usize| {
        let x = p.features(px, py);
        let (y, vb) = p.colour(q);
        let acc = accepted(grey(&y), vb, c, q == cidx, options);
        let base = if acc {
            outlier_weight(vb, options)
        } else {
            0.0
        };
        // centred responses: Σ l_i (y_i − y_c) = f̂ − y_c because Σ l_i = 1
        let yc = [y[0] - c.y[0], y[1] - c.y[1], y[2] - c.y[2]];
        (pr.dz(&x, &c.x), yc, vb, base)
    };

    // Pass A: normal matrices (upper triangles) and positive-weight counts.
    let mut a = vec![[0.0; 100]; nh];
    let mut npos = vec![0usize; nh];
    for_window(p, c, radius, |q, px, py| {
        let (dz, _, _, base) = neighbour(q, px, py);
        if base <= 0.0 {
            return;
        }
        let mut xr = [0.0; 10];
        xr[0] = 1.0;
        xr[1..=k].copy_from_slice(&dz[..k]);
        for s in 0..nh {
            let w = base * kernel_weight(&dz, &inv_bw[s], k);
            if w > 0.0 {
                npos[s] += 1;
                for r in 0..np {
                    let wr = w * xr[r];
                    for col in r..np {
                        a[s][r * np + col] += wr * xr[col];
                    }
                }
            }
        }
    });

    // Solves: u_s = (A_s + Λ)^{-1} e_1.
    let mut out = Vec::with_capacity(nh);
    let mut u = vec![[0.0; 10]; nh];
    let mut solved = vec![false; nh];
    for s in 0..nh {
        let mut fit = Fit {
            f: c.y,
            bias: 0.0,
            var: c.vbar,
            flags: 0,
            npos: npos[s],
            nonneg: false,
        };
        if npos[s] <= 1 {
            fit.flags |= FLAG_FEW;
        } else {
            let chol = ridge_cholesky(&a[s][..np * np], np, lambda, EPS_PIVOT);
            if chol.failed {
                fit.flags |= FLAG_SOLVE_FAIL;
            } else {
                let mut e1 = [0.0; 10];
                e1[0] = 1.0;
                u[s][..np].copy_from_slice(&chol.solve(&e1[..np]));
                solved[s] = true;
            }
        }
        out.push(fit);
    }
    if !solved.iter().any(|&x| x) {
        return out;
    }

    // Pass B: l_i = w_i uᵀ x_i → Σ l (y − y_c), Σ l² vbar and the positive parts.
    let mut sy = vec![[0.0; 3]; nh];
    let mut sl2v = vec![0.0; nh];
    let mut sp = vec![0.0; nh];
    let mut spy = vec![[0.0; 3]; nh];
    let mut sp2v = vec![0.0; nh];
    for_window(p, c, radius, |q, px, py| {
        let (dz, y, vb, base) = neighbour(q, px, py);
        if base <= 0.0 {
            return;
        }
        for s in 0..nh {
            let w = base * kernel_weight(&dz, &inv_bw[s], k);
            if w > 0.0 {
                let mut ux = u[s][0];
                for j in 0..k {
                    ux += u[s][1 + j] * dz[j];
                }
                let l = w * ux;
                let lp = l.max(0.0);
                for ch in 0..3 {
                    sy[s][ch] += l * y[ch];
                    spy[s][ch] += lp * y[ch];
                }
                sl2v[s] += l * l * vb;
                sp[s] += lp;
                sp2v[s] += lp * lp * vb;
            }
        }
    });
    for s in 0..nh {
        if !solved[s] {
            continue;
        }
        let fit = &mut out[s];
        // delta = f̂ − y_c = Σ l_i (y_i − y_c)
        let mut delta = sy[s];
        fit.var = sl2v[s];
        if options & WLR_NONNEG != 0 && (0..3).any(|ch| c.y[ch] + delta[ch] < 0.0) {
            // NONNEG: l ← max(l, 0)/max(Σ max(l, 0), 1e-3), then clamp f̂ >= 0.
            let den = sp[s].max(NONNEG_FLOOR);
            for ch in 0..3 {
                delta[ch] = if sp[s] >= NONNEG_FLOOR {
                    spy[s][ch] / sp[s]
                } else {
                    (spy[s][ch] + c.y[ch] * sp[s]) / den - c.y[ch]
                };
                delta[ch] = delta[ch].max(-c.y[ch]);
            }
            fit.var = sp2v[s] / (den * den);
            fit.nonneg = true;
        }
        for ch in 0..3 {
            fit.f[ch] = c.y[ch] + delta[ch];
        }
        fit.bias = (delta[0] + delta[1] + delta[2]) / 3.0;
    }
    out
}

/// `(intercept, slope)` of the least-squares line through `(t_s, u_s)`
/// (closed form of step 6). Mirrors `wlr_simple_regression` (f64 on the GPU
/// too).
pub fn simple_regression(t: &[f64], u: &[f64]) -> (f64, f64) {
    let n = t.len() as f64;
    let tm = t.iter().sum::<f64>() / n;
    let um = u.iter().sum::<f64>() / n;
    let mut stu = 0.0;
    let mut stt = 0.0;
    for (ti, ui) in t.iter().zip(u) {
        stu += (ti - tm) * (ui - um);
        stt += (ti - tm) * (ti - tm);
    }
    let slope = stu / stt;
    (um - slope * tm, slope)
}

/// The parametric models of step 6.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Parametric {
    /// `bias(h) ≈ λ0 + λ1 h²`.
    pub lambda0: f64,
    /// `λ1`: slope of the bias on `h²`.
    pub lambda1: f64,
    /// `n_c·var(h) ≈ κ0 + κ1 h^{-k}`.
    pub kappa0: f64,
    /// `κ1`: slope of `n_c·var` on `h^{-k}`.
    pub kappa1: f64,
}

/// `h^{-k}` by repeated multiplication (as the GPU computes it).
pub fn inv_pow(h: f64, k: usize) -> f64 {
    let mut hk = 1.0;
    for _ in 0..k {
        hk *= h;
    }
    1.0 / hk
}

/// Step 6 (f64): bias on `h²`, `n_c·var` on `h^{-k}` over the trial
/// bandwidths [`TRIAL_H`]. Needs `k >= 1`. Mirrors `wlr_parametric`.
pub fn parametric(bias: &[f64; 5], var: &[f64; 5], k: usize, n: f64) -> Parametric {
    let t2: Vec<f64> = TRIAL_H.iter().map(|h| h * h).collect();
    let tk: Vec<f64> = TRIAL_H.iter().map(|&h| inv_pow(h, k)).collect();
    let nv: Vec<f64> = var.iter().map(|v| n * v).collect();
    let (lambda0, lambda1) = simple_regression(&t2, bias);
    let (kappa0, kappa1) = simple_regression(&tk, &nv);
    Parametric {
        lambda0,
        lambda1,
        kappa0,
        kappa1,
    }
}

/// The bandwidth choice of step 7 and the MSE model stored for step 10.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct HChoice {
    /// Bandwidth `h_opt` (step 7), a factor on the `b_j`: the formula's
    /// value clamped to `[H_MIN, H_MAX]`, `H_MAX` when `λ1²·n_c` is tiny,
    /// 0.2 when `κ1 <= 0`.
    pub h_opt: f64,
    /// The stored model: `MSE(h) = (λ1 h²)² + (κ0 + κ1 h^{-k})/n_c`. In the
    /// `κ1 <= 0` case `λ1 = κ1 = 0` and `κ0 = n_c·(bias_1² + var_1)`.
    pub lambda1: f64,
    /// `κ0` of the stored model.
    pub kappa0: f64,
    /// `κ1` of the stored model.
    pub kappa1: f64,
    /// [`FLAG_KAPPA`] or [`FLAG_CLAMPED`].
    pub flags: u32,
}

/// Step 7 (f64) with H-CASES for `k >= 1`; `bias1`, `var1` are the trial at
/// `h = 0.2`. Mirrors `wlr_choose_h`.
pub fn choose_h(par: &Parametric, k: usize, n: f64, bias1: f64, var1: f64) -> HChoice {
    // κ1 <= 0 (or NaN, as in the kernel's `!(κ1 > 0)`)
    if par.kappa1 <= 0.0 || par.kappa1.is_nan() {
        return HChoice {
            h_opt: TRIAL_H[0],
            lambda1: 0.0,
            kappa0: n * (bias1 * bias1 + var1),
            kappa1: 0.0,
            flags: FLAG_KAPPA,
        };
    }
    let mut c = HChoice {
        h_opt: H_MAX,
        lambda1: par.lambda1,
        kappa0: par.kappa0,
        kappa1: par.kappa1,
        flags: 0,
    };
    let l2n = par.lambda1 * par.lambda1 * n;
    if l2n < LAMBDA_TINY {
        return c;
    }
    let a = k as f64 * par.kappa1 / (4.0 * l2n);
    let h = a.powf(1.0 / (k as f64 + 4.0));
    c.h_opt = h.clamp(H_MIN, H_MAX);
    if !(H_MIN..=H_MAX).contains(&h) {
        c.flags |= FLAG_CLAMPED;
    }
    c
}

/// Step 10: `(λ1 h²)² + (κ0 + κ1 h^{-k})/n_c`, clamped `>= 0`.
pub fn mse_model(lambda1: f64, kappa0: f64, kappa1: f64, k: usize, n: f64, h: f64) -> f64 {
    let b = lambda1 * h * h;
    (b * b + (kappa0 + kappa1 * inv_pow(h, k)) / n).max(0.0)
}

/// Everything `wlr_fit` writes for one pixel.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FitPixel {
    /// Bandwidth `h_opt` (step 7), in `[0.01, 1]`; 0.2 in the pass-through cases.
    pub h_opt: f64,
    /// `λ1` of the stored MSE model (see [`HChoice::lambda1`]).
    pub lambda1: f64,
    /// `κ0` of the stored MSE model.
    pub kappa0: f64,
    /// `κ1` of the stored MSE model.
    pub kappa1: f64,
    /// TSVD rank `k` of the window (§0.6; `0..=D`, at most [`MAX_RANK`]).
    pub k: usize,
    /// Debug flag bits of §2.5 set by steps 1–7: [`FLAG_SOLVE_FAIL`],
    /// [`FLAG_K0`], [`FLAG_KAPPA`], [`FLAG_CLAMPED`].
    pub flags: u32,
    /// `b_1..b_3` (0 for `j >= k`).
    pub b: [f64; 3],
}

impl FitPixel {
    /// The `kflags` encoding: `k + 16·flags`.
    pub fn kflags(&self) -> f64 {
        (self.k as u32 + 16 * self.flags) as f64
    }
}

/// `wlr_fit` at a valid centre: steps 1–7 (spec §2.3). Pass-through cases
/// (`k = 0`, SOLVE-FAIL of the curvature fit) give `h_opt = 0.2`,
/// `λ1 = κ1 = 0`, `κ0 = n_c·vbar_c`.
pub fn fit_pixel(p: &Planes, cx: usize, cy: usize, radius: usize, options: u32) -> FitPixel {
    let ls = local_space(p, cx, cy, radius);
    let c = centre(p, cx, cy);
    let mut out = FitPixel {
        h_opt: TRIAL_H[0],
        lambda1: 0.0,
        kappa0: c.n * c.vbar,
        kappa1: 0.0,
        k: ls.k,
        flags: 0,
        b: [0.0; 3],
    };
    if ls.k == 0 {
        out.flags |= FLAG_K0;
        return out;
    }
    let pr = projection(&ls);
    let curv = curvature(p, &pr, &c, radius, options);
    if curv.failed {
        out.flags |= FLAG_SOLVE_FAIL;
        return out;
    }
    out.b.copy_from_slice(&curv.b[..3]);
    let trials = fits(p, &pr, &c, &curv.b, &TRIAL_H, radius, options, FIT_LAMBDA);
    let mut bias = [0.0; 5];
    let mut var = [0.0; 5];
    for s in 0..5 {
        out.flags |= trials[s].flags & FLAG_SOLVE_FAIL;
        bias[s] = trials[s].bias;
        var[s] = trials[s].var;
    }
    let par = parametric(&bias, &var, ls.k, c.n);
    let ch = choose_h(&par, ls.k, c.n, bias[0], var[0]);
    out.h_opt = ch.h_opt;
    out.lambda1 = ch.lambda1;
    out.kappa0 = ch.kappa0;
    out.kappa1 = ch.kappa1;
    out.flags |= ch.flags;
    out
}

/// Everything `wlr_final` writes for one pixel.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FinalPixel {
    /// Output colour, clamped `>= 0`.
    pub rgb: [f64; 3],
    /// `MSE_c` of step 10 (`>= 0`), shared by R, G, B; `vbar_c` when a fit failed.
    pub mse: f64,
    /// Debug flag bits of §2.5: the stored `wlr_fit` flags plus [`FLAG_K0`],
    /// [`FLAG_SOLVE_FAIL`] and [`FLAG_FEW`] of this pass.
    pub flags: u32,
}

/// The stored values `wlr_final` reads from `wlr_fit` for one pixel.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Stored {
    /// `hbar = G_1(h_opt)` (step 8).
    pub hbar: f64,
    /// `λ1` of the MSE model `wlr_fit` stored.
    pub lambda1: f64,
    /// `κ0` of the MSE model `wlr_fit` stored.
    pub kappa0: f64,
    /// `κ1` of the MSE model `wlr_fit` stored.
    pub kappa1: f64,
    /// `k + 16·flags` as written by `wlr_fit`.
    pub kflags: f64,
}

impl Stored {
    /// `(k, flags)` decoded from `kflags`.
    pub fn k_flags(&self) -> (usize, u32) {
        let v = self.kflags.max(0.0).round() as u32;
        ((v % 16) as usize, v / 16)
    }
}

/// `wlr_final` at a valid centre: the TSVD and `b_j` recomputed exactly as in
/// [`fit_pixel`], step 9 at `h = clamp(hbar, 0.01, 1)` (a no-op for a
/// Gaussian mean of `h_opt` values) and step 10 with the stored model and the
/// stored `k` (the `k` its `κ`s were fitted with). A pass-through (`k = 0`,
/// SOLVE-FAIL of the curvature or the final fit) outputs `y_c`; a failed fit
/// reports `MSE = vbar_c` (§0.5).
pub fn final_pixel(
    p: &Planes,
    cx: usize,
    cy: usize,
    radius: usize,
    options: u32,
    st: &Stored,
) -> FinalPixel {
    let ls = local_space(p, cx, cy, radius);
    let c = centre(p, cx, cy);
    let (k_st, flags_st) = st.k_flags();
    let mut flags = flags_st;
    let mut f = c.y;
    let mut failed = false;
    if ls.k == 0 {
        flags |= FLAG_K0;
    } else {
        let pr = projection(&ls);
        let curv = curvature(p, &pr, &c, radius, options);
        if curv.failed {
            flags |= FLAG_SOLVE_FAIL;
            failed = true;
        } else {
            let h = [st.hbar.clamp(H_MIN, H_MAX)];
            let fit = &fits(p, &pr, &c, &curv.b, &h, radius, options, FIT_LAMBDA)[0];
            f = fit.f;
            flags |= fit.flags;
            failed = fit.flags & FLAG_SOLVE_FAIL != 0;
        }
    }
    let mse = if failed {
        c.vbar.max(0.0)
    } else {
        mse_model(
            st.lambda1,
            st.kappa0,
            st.kappa1,
            k_st,
            c.n,
            st.hbar.clamp(H_MIN, H_MAX),
        )
    };
    FinalPixel {
        rgb: [f[0].max(0.0), f[1].max(0.0), f[2].max(0.0)],
        mse,
        flags,
    }
}

/// §0.2: the output of an invalid pixel, the plain mean colour of the valid
/// pixels of its 3x3 neighbourhood (0 if none), clamped `>= 0` like every
/// final colour output (§0.4 step 5).
pub fn invalid_fill(p: &Planes, cx: usize, cy: usize) -> [f64; 3] {
    let i = cy * p.width + cx;
    [0, 1, 2].map(|ch| {
        super::valid_mean_3x3(p.width, p.height, i, |q| p.valid(q), |q| p.colour(q).0[ch]).max(0.0)
    })
}

/// Runs `f(x, y)` for every pixel of a `width × height` grid on all cores
/// (rows through [`super::par_map`]; the result does not depend on the
/// thread count) and scatters the `N` values per pixel into
/// `out[0..N]` (full planes).
pub fn par_pixels<const N: usize>(
    width: usize,
    height: usize,
    out: &mut [Vec<f32>],
    f: impl Fn(usize, usize) -> [f32; N] + Sync,
) {
    assert!(out.len() >= N, "par_pixels: output planes");
    for o in out.iter().take(N) {
        assert!(o.len() >= width * height, "par_pixels: plane size");
    }
    let rows: Vec<Vec<[f32; N]>> =
        super::par_map(height, |y| (0..width).map(|x| f(x, y)).collect());
    for (y, row) in rows.into_iter().enumerate() {
        for (x, v) in row.into_iter().enumerate() {
            for (j, &val) in v.iter().enumerate() {
                out[j][y * width + x] = val;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::tsvd::local_coords;

    #[test]
    fn projection_equals_local_coords() {
        let (w, h) = (9, 9);
        let f: Vec<Vec<f32>> = (0..7)
            .map(|j| {
                (0..w * h)
                    .map(|i| ((i * (j + 3)) % 11) as f32 * 0.1 + (i % w) as f32 * 0.01)
                    .collect()
            })
            .collect();
        let z = vec![0.0f32; w * h];
        let one = vec![1.0f32; w * h];
        let planes = Planes {
            width: w,
            height: h,
            feat: std::array::from_fn(|j| f[j].as_slice()),
            var: [&z; 7],
            color: [&one; 3],
            vbar: &z,
            spp: &one,
            vis: None,
        };
        let ls = local_space(&planes, 4, 4, 3);
        assert!(ls.k >= 2);
        let pr = projection(&ls);
        let xc = planes.features(4, 4);
        for (px, py) in [(1, 1), (7, 5), (4, 4), (2, 6)] {
            let x = planes.features(px, py);
            let a = pr.dz(&x, &xc);
            let b = local_coords(&ls, &x[..ls.d], &xc[..ls.d]);
            for m in 0..ls.k {
                assert!((a[m] - b[m]).abs() < 1e-12, "{m}: {} vs {}", a[m], b[m]);
            }
            assert!(a[ls.k..].iter().all(|&v| v == 0.0));
        }
    }

    #[test]
    fn h_choice_cases() {
        let par = Parametric {
            lambda0: 0.0,
            lambda1: 0.1,
            kappa0: 0.0,
            kappa1: -1.0,
        };
        let c = choose_h(&par, 3, 4.0, 0.5, 0.25);
        assert_eq!(
            (c.h_opt, c.flags, c.lambda1, c.kappa1),
            (0.2, FLAG_KAPPA, 0.0, 0.0)
        );
        assert!((mse_model(0.0, c.kappa0, 0.0, 3, 4.0, 0.7) - 0.5).abs() < 1e-15);
        let flat = Parametric {
            lambda1: 0.0,
            kappa1: 1.0,
            ..par
        };
        assert_eq!(choose_h(&flat, 3, 4.0, 0.0, 0.0).h_opt, 1.0);
        let big = Parametric {
            lambda1: 1e-6,
            kappa1: 1.0,
            ..par
        };
        let c = choose_h(&big, 3, 4.0, 0.0, 0.0);
        assert_eq!((c.h_opt, c.flags), (1.0, FLAG_CLAMPED));
        let small = Parametric {
            lambda1: 1e6,
            kappa1: 1e-9,
            ..par
        };
        let c = choose_h(&small, 3, 4.0, 0.0, 0.0);
        assert_eq!((c.h_opt, c.flags), (0.01, FLAG_CLAMPED));
    }
}
