//! Per-centre routines of LP, linear predictions (spec §3), shared by the
//! twins [`lp_centres`](super::lp_centres) and [`lp_gather`](super::lp_gather).
//! GPU twin: `spirv/lib/lp.glsl`. Everything here is f64.
//!
//! One centre `c` goes through:
//! 1. the TSVD of §0.6 on the 9 WLR features (§2.1) of the 19×19 window, and
//!    its [`Projection`] `Δz = V_kᵀ diag(1/ρ)(x_i − x_c)` (§3.1);
//! 2. [`Rls`]: recursive least squares on `ζ_i = (1, Δz_i)`, ring by ring
//!    (§3.2–3.3), with the recursive error estimate of §3.4 ([`centre_fit`]);
//! 3. the prediction `f̂_c(i) = β_c[ch]ᵀ ζ_i`, stored in the collapsed form
//!    `f̂_c(i)[ch] = β_c[ch][0] + Σ_j u[ch][j] (x_ij − x_cj)` with
//!    `u[ch][j] = Σ_m β_c[ch][1+m] V_jm/ρ_j`, which is the same linear map
//!    (`ζ_i` of centre c built with its stored normalisation and `V_k`), in
//!    27 numbers instead of the 9 + 9 + 81 of `m`, `ρ` and `V_k`.
//!
//! The per-centre state of the GPU is 36 f32 values ([`StateLayout`]).

use super::spp_of;
use super::tsvd::{gather_window, LocalSpace};
use super::wlr::{projection, Projection, D};

/// Filtering window radius (19×19) in every pass (§3.1).
pub const RADIUS: usize = 9;
/// RLS prior: `P(0) = I/δ` (§3.3).
pub const DELTA: f64 = 0.001;
/// LOO-DEN: `1 − h_ii` is clamped to at least this (§3.4).
pub const LOO_DEN_MIN: f64 = 1e-4;
/// Granularities of the sparse-centre passes (§3.5): 19, 9, 4, 2, 1.
pub const GRANULARITIES: [u32; 5] = [19, 9, 4, 2, 1];
/// Largest regressor length `k + 1`.
pub const MAX_P: usize = D + 1;
/// Number of prediction sizes `r = 0..=RADIUS`.
pub const RINGS: usize = RADIUS + 1;

/// The per-centre state layout (shared with the kernels).
pub use crate::shared::LpStateLayout as StateLayout;

/// The planes both LP kernels read.
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
    /// Colour variances (of the mean) R, G, B.
    pub cvar: [&'a [f32]; 3],
    /// Sample count `n` per pixel (f32); valid when `spp_of(n) >= 1` (§0.2).
    pub spp: &'a [f32],
}

impl Planes<'_> {
    /// Raw features and variances of pixel `(px, py)` (§2.1); returns
    /// whether the pixel is valid. Mirrors `load_features` of the kernels.
    pub fn load_features(&self, px: usize, py: usize, x: &mut [f64], e2: &mut [f64]) -> bool {
        super::wlr::load_features(self.width, &self.feat, &self.var, px, py, x, e2);
        self.valid(py * self.width + px)
    }

    /// Raw features only.
    #[inline]
    pub fn features(&self, px: usize, py: usize) -> [f64; D] {
        super::wlr::features(self.width, &self.feat, px, py)
    }

    /// Colour `y` and its per-channel variance `v` of pixel index `q`.
    #[inline]
    pub fn colour(&self, q: usize) -> ([f64; 3], [f64; 3]) {
        (
            std::array::from_fn(|c| self.color[c][q] as f64),
            std::array::from_fn(|c| self.cvar[c][q] as f64),
        )
    }

    /// Whether pixel index `q` is valid: `spp_of(spp[q]) >= 1` (§0.2).
    #[inline]
    pub fn valid(&self, q: usize) -> bool {
        spp_of(self.spp[q]) >= 1.0
    }
}

/// The TSVD local space (§0.6) of `Ω_c(9)`.
pub fn local_space(p: &Planes, cx: usize, cy: usize) -> LocalSpace {
    let win = gather_window(p.width, p.height, cx, cy, RADIUS, D, |px, py, x, e2| {
        p.load_features(px, py, x, e2)
    });
    super::tsvd::local_space(&win.x, &win.e2, D)
}

/// The pixels of ring `r` of centre `(cx, cy)` (`|i − c|_inf = r`), clipped
/// to the image, in raster order (RING-ORDER), valid or not.
pub fn ring(width: usize, height: usize, cx: usize, cy: usize, r: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let (cx, cy, r) = (cx as i64, cy as i64, r as i64);
    for py in (cy - r).max(0)..=(cy + r).min(height as i64 - 1) {
        if py == cy - r || py == cy + r {
            for px in (cx - r).max(0)..=(cx + r).min(width as i64 - 1) {
                out.push((px as usize, py as usize));
            }
        } else {
            for px in [cx - r, cx + r] {
                if px >= 0 && px < width as i64 {
                    out.push((px as usize, py as usize));
                }
            }
        }
    }
    out
}

/// Recursive least squares on regressors of length `p = k + 1` for the three
/// colour channels, with the shared inverse covariance `P` (LP-CHANNELS).
#[derive(Clone, Debug, PartialEq)]
pub struct Rls {
    /// Regressor length `p = k_c + 1` (intercept and the `k_c` local
    /// coordinates `Δz`), at most [`MAX_P`].
    pub p: usize,
    /// `P`, row-major `MAX_P × MAX_P` (only `p × p` used).
    pub pm: [[f64; MAX_P]; MAX_P],
    /// `β[ch]`.
    pub beta: [[f64; MAX_P]; 3],
}

impl Rls {
    /// `β(0) = (y_c, 0, …, 0)`, `P(0) = I/δ` (§3.3).
    pub fn new(p: usize, y_c: [f64; 3]) -> Rls {
        assert!((1..=MAX_P).contains(&p), "Rls::new: p = {p}");
        let mut pm = [[0.0; MAX_P]; MAX_P];
        for (j, row) in pm.iter_mut().enumerate().take(p) {
            row[j] = 1.0 / DELTA;
        }
        let mut beta = [[0.0; MAX_P]; 3];
        for ch in 0..3 {
            beta[ch][0] = y_c[ch];
        }
        Rls { p, pm, beta }
    }

    /// `β[ch]ᵀ ζ`.
    #[inline]
    pub fn predict(&self, zeta: &[f64; MAX_P]) -> [f64; 3] {
        std::array::from_fn(|ch| (0..self.p).map(|j| self.beta[ch][j] * zeta[j]).sum())
    }

    /// The leverage `ζᵀ P ζ`.
    pub fn leverage(&self, zeta: &[f64; MAX_P]) -> f64 {
        let q = self.p_zeta(zeta);
        (0..self.p).map(|j| zeta[j] * q[j]).sum()
    }

    fn p_zeta(&self, zeta: &[f64; MAX_P]) -> [f64; MAX_P] {
        let mut q = [0.0; MAX_P];
        for (j, qj) in q.iter_mut().enumerate().take(self.p) {
            *qj = (0..self.p).map(|l| self.pm[j][l] * zeta[l]).sum();
        }
        q
    }

    /// One update with regressor `ζ` and responses `y` (§3.3):
    /// `q = Pζ`, `G = q/(1 + ζᵀq)`, `P ← P − G qᵀ` (`qᵀ = ζᵀP` for the
    /// symmetric `P`), `β[ch] ← β[ch] + G (y[ch] − β[ch]ᵀζ)`.
    pub fn update(&mut self, zeta: &[f64; MAX_P], y: [f64; 3]) {
        self.update_weighted(zeta, y, 1.0);
    }

    /// [`Rls::update`] for a row of weight `1/c` (LP-OUTLIER-W):
    /// `G = q/(c + ζᵀq)`. After the rows, `β = (δI + XᵀWX)⁻¹(δβ(0) +
    /// XᵀWY)` and `P = (δI + XᵀWX)⁻¹` ([`batch_ridge_weighted`]).
    pub fn update_weighted(&mut self, zeta: &[f64; MAX_P], y: [f64; 3], c: f64) {
        let p = self.p;
        let q = self.p_zeta(zeta);
        let den = c + (0..p).map(|j| zeta[j] * q[j]).sum::<f64>();
        let g: [f64; MAX_P] = std::array::from_fn(|j| q[j] / den);
        let res = self.predict(zeta);
        for j in 0..p {
            for l in 0..p {
                self.pm[j][l] -= g[j] * q[l];
            }
        }
        for ch in 0..3 {
            let e = y[ch] - res[ch];
            for j in 0..p {
                self.beta[ch][j] += g[j] * e;
            }
        }
    }

    /// `P ← (P + Pᵀ)/2`, after each ring (§3.3).
    pub fn symmetrise(&mut self) {
        for j in 0..self.p {
            for l in j + 1..self.p {
                let m = 0.5 * (self.pm[j][l] + self.pm[l][j]);
                self.pm[j][l] = m;
                self.pm[l][j] = m;
            }
        }
    }
}

/// The regressor `ζ = (1, Δz)` of raw features `x` for a centre with
/// projection `pr` and raw features `xc`.
pub fn regressor(pr: &Projection, x: &[f64; D], xc: &[f64; D]) -> [f64; MAX_P] {
    let dz = pr.dz(x, xc);
    let mut z = [0.0; MAX_P];
    z[0] = 1.0;
    z[1..=pr.k].copy_from_slice(&dz[..pr.k]);
    z
}

/// What one centre's optimisation gives.
#[derive(Clone, Debug, PartialEq)]
pub struct CentreFit {
    /// TSVD rank `k_c`.
    pub k: usize,
    /// The chosen prediction size.
    pub r_opt: usize,
    /// `β_c[ch] = β(k(r_opt))` (first `k + 1` entries).
    pub beta: [[f64; MAX_P]; 3],
    /// `ξ̂_ch(r)` for `r = 0..=9` (rings beyond the image repeat the last value).
    pub curve: [[f64; 3]; RINGS],
    /// `k(r)`, the number of valid pixels of `Ω^P_c(r)`.
    pub count: [usize; RINGS],
    /// The collapsed prediction map (module doc).
    pub u: [[f64; D]; 3],
}

impl CentreFit {
    /// `ξ̂_c,ch(r_opt)`.
    pub fn xi(&self) -> [f64; 3] {
        self.curve[self.r_opt]
    }

    /// The centre's 36-value state ([`StateLayout`]) for a centre made in
    /// pass `pass`.
    pub fn state(&self, pass: u32) -> [f32; StateLayout::LEN] {
        let mut s = [0.0f32; StateLayout::LEN];
        s[StateLayout::PASS] = (pass + 1) as f32;
        s[StateLayout::R_OPT] = self.r_opt as f32;
        s[StateLayout::K] = self.k as f32;
        let xi = self.xi();
        for ch in 0..3 {
            s[StateLayout::BETA0 + ch] = self.beta[ch][0] as f32;
            s[StateLayout::XI + ch] = xi[ch] as f32;
            for j in 0..D {
                s[StateLayout::U + 9 * ch + j] = self.u[ch][j] as f32;
            }
        }
        s
    }
}

/// LP-CENTRE-TEST's threshold: a squared miss at the centre above this many
/// times the centre's variance of the mean (3 standard errors).
pub const CENTRE_TEST_Z2: f64 = 9.0;

/// The error a window's model adds for missing its own centre, per channel.
///
/// Decision LP-CENTRE-TEST (ours): with option `lp.centre_test`,
/// `miss = β(k(r))ᵀζ_c − y_c` is the model's prediction at the centre minus
/// the centre's mean; where
/// `miss² > 9·v_c` the model is significantly wrong at the very pixel it
/// was fitted for, and `miss² − s·v_c` (the error against the truth, as in
/// the ring terms) is counted for every pixel of the window, i.e. added to
/// `ξ̂(r)`; otherwise 0.
pub fn centre_miss(miss: f64, v_c: f64, s: f64) -> f64 {
    let m2 = miss * miss;
    if m2 > CENTRE_TEST_Z2 * v_c {
        m2 - s * v_c
    } else {
        0.0
    }
}

/// LP-OUTLIER-W (ours, WLR's OUTLIER-W carried to LP's fits, measured in
/// the centre's own noise): the scale of a centre with colour variances
/// `vc`, `max(vbar_c, 1)` (`vbar_c` their mean, §0.1), or 0 with the option
/// off. Twin of `lp_weight_scale`.
#[inline]
pub fn weight_scale(vc: &[f64; 3], clamped: bool) -> f64 {
    if clamped {
        ((vc[0] + vc[1] + vc[2]) / 3.0).max(1.0)
    } else {
        0.0
    }
}

/// LP-OUTLIER-W: the inverse weight `max(vbar / scale, 1)` in the RLS of
/// a centre with [`weight_scale`] `scale` of a pixel with colour variances
/// `v`; 1 when `scale` is 0 (the option off). So a centre in a lamp's halo
/// weighs its equally noisy neighbours fully while a dark centre weighs a
/// one-sample pixel of variance V by 1/V, and a centre's own row always
/// weighs 1. Twin of `lp_inverse_weight`.
#[inline]
pub fn inverse_weight(v: &[f64; 3], scale: f64) -> f64 {
    if scale > 0.0 {
        ((v[0] + v[1] + v[2]) / 3.0 / scale).max(1.0)
    } else {
        1.0
    }
}

/// The options of [`centre_fit`].
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// The test-variance correction of LP-VARSUB: 1 (default) or the
    /// paper-literal 0.
    pub s: f64,
    /// LP-CENTRE-TEST: add [`centre_miss`] to every `ξ̂(r ≥ 1)`.
    pub centre_test: bool,
    /// LP-OUTLIER-W: weigh each pixel's row by `1/`[`inverse_weight`].
    pub outlier_weight: bool,
}

impl FitOptions {
    /// From [`LpPush::options`](crate::shared::LpPush::options) bits.
    pub fn from_bits(options: u32) -> FitOptions {
        use crate::shared::{LP_CENTRE_TEST, LP_OUTLIER_W, LP_VARSUB};
        FitOptions {
            s: if options & LP_VARSUB != 0 { 1.0 } else { 0.0 },
            centre_test: options & LP_CENTRE_TEST != 0,
            outlier_weight: options & LP_OUTLIER_W != 0,
        }
    }
}

/// Spec §3.3–3.4 for the valid centre `(cx, cy)`, with the options `o`.
/// With LP-OUTLIER-W the rows are weighted, the leave-one-out residual of
/// pixel i is `e_i/(1 − w_i ζᵢᵀPζᵢ)`, and the error terms are unweighted
/// (errors against the truth, as the spec's).
pub fn centre_fit(p: &Planes, cx: usize, cy: usize, o: FitOptions) -> CentreFit {
    let FitOptions {
        s,
        centre_test,
        outlier_weight,
    } = o;
    let ls = local_space(p, cx, cy);
    let pr = projection(&ls);
    let k = pr.k;
    let xc = p.features(cx, cy);
    let (yc, vc) = p.colour(cy * p.width + cx);
    let mut rls = Rls::new(k + 1, yc);
    let zeta_of = |px: usize, py: usize| regressor(&pr, &p.features(px, py), &xc);
    let scale = weight_scale(&vc, outlier_weight);
    let c_of = |v: &[f64; 3]| inverse_weight(v, scale);

    let mut curve = [[0.0; 3]; RINGS];
    let mut count = [0usize; RINGS];
    // r = 0: the centre (residual 0: β unchanged, P changes; its own row
    // weighs 1 under LP-OUTLIER-W); Ξ(0) = v_c.
    rls.update(&zeta_of(cx, cy), yc);
    rls.symmetrise();
    let mut n = 1usize;
    curve[0] = vc;
    count[0] = 1;
    let mut best = (0usize, vc.iter().sum::<f64>(), rls.beta);

    // r = 1: add ring 1, then the closed-form leave-one-out error over Ω^P(1).
    let ring1: Vec<(usize, usize)> = ring(p.width, p.height, cx, cy, 1)
        .into_iter()
        .filter(|&(px, py)| p.valid(py * p.width + px))
        .collect();
    for &(px, py) in &ring1 {
        let (y, v) = p.colour(py * p.width + px);
        rls.update_weighted(&zeta_of(px, py), y, c_of(&v));
        n += 1;
    }
    rls.symmetrise();
    let mut xi_acc = [0.0; 3];
    for py in cy.saturating_sub(1)..(cy + 2).min(p.height) {
        for px in cx.saturating_sub(1)..(cx + 2).min(p.width) {
            let q = py * p.width + px;
            if !p.valid(q) {
                continue;
            }
            let (y, v) = p.colour(q);
            let z = zeta_of(px, py);
            let den = (1.0 - rls.leverage(&z) / c_of(&v)).max(LOO_DEN_MIN);
            let f = rls.predict(&z);
            for ch in 0..3 {
                let e = (f[ch] - y[ch]) / den;
                xi_acc[ch] += e * e - s * v[ch];
            }
        }
    }
    let zeta_c = zeta_of(cx, cy);
    let mut consider = |r: usize, xi_acc: &[f64; 3], n: usize, rls: &Rls| {
        let at_centre = centre_test.then(|| rls.predict(&zeta_c));
        let xi: [f64; 3] = std::array::from_fn(|ch| {
            let miss = at_centre.map_or(0.0, |f| centre_miss(f[ch] - yc[ch], vc[ch], s));
            xi_acc[ch] / n as f64 + miss
        });
        curve[r] = xi;
        count[r] = n;
        let total: f64 = xi.iter().sum();
        if total < best.1 {
            best = (r, total, rls.beta);
        }
    };
    consider(1, &xi_acc, n, &rls);

    // r >= 2: score the previous model on ring r, then add the ring.
    for r in 2..RINGS {
        let ring_r: Vec<(usize, usize)> = ring(p.width, p.height, cx, cy, r)
            .into_iter()
            .filter(|&(px, py)| p.valid(py * p.width + px))
            .collect();
        for &(px, py) in &ring_r {
            let (y, v) = p.colour(py * p.width + px);
            let f = rls.predict(&zeta_of(px, py));
            for ch in 0..3 {
                let e = f[ch] - y[ch];
                xi_acc[ch] += e * e - s * v[ch];
            }
        }
        n += ring_r.len();
        for &(px, py) in &ring_r {
            let (y, v) = p.colour(py * p.width + px);
            rls.update_weighted(&zeta_of(px, py), y, c_of(&v));
        }
        rls.symmetrise();
        consider(r, &xi_acc, n, &rls);
    }
    let (r_opt, _, beta) = best;
    let mut u = [[0.0; D]; 3];
    for ch in 0..3 {
        for (j, uj) in u[ch].iter_mut().enumerate() {
            *uj = (0..k).map(|m| beta[ch][1 + m] * pr.p[m][j]).sum();
        }
    }
    CentreFit {
        k,
        r_opt,
        beta,
        curve,
        count,
        u,
    }
}

/// Value `s` of the state of pixel index `q` in the vec4 `planes`.
#[inline]
pub fn state_value(planes: &[Vec<f32>], q: usize, s: usize) -> f32 {
    planes[s / 4][4 * q + s % 4]
}

/// Whether pixel `(px, py)` is covered by a centre (`|i − c|_inf <=
/// r_opt(c)`, §3.5), from the [`lp_reach`](super::lp_reach) plane: some row
/// `y'` within 9 has `reach(px, y') >= |py − y'|`.
pub fn covered(reach: &[f32], width: usize, height: usize, px: usize, py: usize) -> bool {
    (py.saturating_sub(RADIUS)..(py + RADIUS + 1).min(height))
        .any(|qy| reach[qy * width + px] >= qy.abs_diff(py) as f32)
}

/// The spec's invariant reference: `(δI + XᵀX)⁻¹ (δβ(0) + XᵀY)` and
/// `(δI + XᵀX)⁻¹` by Gauss–Jordan elimination, for `rows` regressors of
/// length `p` and responses `y` (3 channels).
pub fn batch_ridge(
    rows: &[[f64; MAX_P]],
    y: &[[f64; 3]],
    p: usize,
    beta0: &[[f64; MAX_P]; 3],
) -> ([[f64; MAX_P]; 3], [[f64; MAX_P]; MAX_P]) {
    batch_ridge_weighted(rows, y, &vec![1.0; rows.len()], p, beta0)
}

/// [`batch_ridge`] with row weights `w`: `(δI + XᵀWX)⁻¹ (δβ(0) + XᵀWY)`
/// and `(δI + XᵀWX)⁻¹` (LP-OUTLIER-W's invariant).
pub fn batch_ridge_weighted(
    rows: &[[f64; MAX_P]],
    y: &[[f64; 3]],
    w: &[f64],
    p: usize,
    beta0: &[[f64; MAX_P]; 3],
) -> ([[f64; MAX_P]; 3], [[f64; MAX_P]; MAX_P]) {
    assert_eq!(rows.len(), w.len(), "batch_ridge_weighted: weights");
    let mut a = vec![vec![0.0; 2 * p]; p];
    for j in 0..p {
        a[j][j] = DELTA;
        a[j][p + j] = 1.0;
        for (r, wr) in rows.iter().zip(w) {
            for l in 0..p {
                a[j][l] += wr * r[j] * r[l];
            }
        }
    }
    for col in 0..p {
        let piv = (col..p)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap();
        a.swap(col, piv);
        let d = a[col][col];
        for v in a[col].iter_mut() {
            *v /= d;
        }
        for i in 0..p {
            if i != col {
                let f = a[i][col];
                if f != 0.0 {
                    for l in 0..2 * p {
                        a[i][l] -= f * a[col][l];
                    }
                }
            }
        }
    }
    let mut inv = [[0.0; MAX_P]; MAX_P];
    for j in 0..p {
        for l in 0..p {
            inv[j][l] = a[j][p + l];
        }
    }
    let mut beta = [[0.0; MAX_P]; 3];
    for ch in 0..3 {
        let mut rhs = [0.0; MAX_P];
        for j in 0..p {
            rhs[j] = DELTA * beta0[ch][j];
            for ((r, yy), wr) in rows.iter().zip(y).zip(w) {
                rhs[j] += wr * r[j] * yy[ch];
            }
        }
        for j in 0..p {
            beta[ch][j] = (0..p).map(|l| inv[j][l] * rhs[l]).sum();
        }
    }
    (beta, inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rings_partition_the_window() {
        for (w, h, cx, cy) in [(30, 30, 12, 15), (5, 4, 0, 3), (1, 1, 0, 0), (20, 3, 19, 1)] {
            let mut seen = vec![0; w * h];
            for r in 0..RINGS {
                let ring = ring(w, h, cx, cy, r);
                let mut sorted = ring.clone();
                sorted.sort_by_key(|&(x, y)| (y, x));
                assert_eq!(ring, sorted, "raster order");
                for (x, y) in ring {
                    assert_eq!(x.abs_diff(cx).max(y.abs_diff(cy)), r);
                    seen[y * w + x] += 1;
                }
            }
            for y in 0..h {
                for x in 0..w {
                    let inside = x.abs_diff(cx) <= RADIUS && y.abs_diff(cy) <= RADIUS;
                    assert_eq!(seen[y * w + x], inside as i32, "({x},{y})");
                }
            }
        }
    }

    #[test]
    fn inverse_weight_is_the_noise_over_the_centres() {
        let v = |x: f64| [x, x, x];
        let w = |x: [f64; 3], c: [f64; 3], on: bool| inverse_weight(&x, weight_scale(&c, on));
        assert_eq!(w(v(100.0), v(0.5), true), 100.0);
        assert_eq!(w(v(100.0), v(4.0), true), 25.0);
        assert_eq!(w(v(2.0), v(4.0), true), 1.0);
        assert_eq!(w(v(0.3), v(0.0), true), 1.0);
        assert_eq!(w([30.0, 60.0, 90.0], v(0.0), true), 60.0);
        assert_eq!(w(v(100.0), v(0.5), false), 1.0);
        // A centre's own row.
        assert_eq!(w(v(867.0), v(867.0), true), 1.0);
    }

    #[test]
    fn rls_equals_batch_ridge() {
        let mut s = 12345u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        // p = 3 and 10 twice: unit weights, then LP-OUTLIER-W's (every
        // fifth row at 1/40).
        for (p, weighted) in [(1, false), (3, false), (10, false), (3, true), (10, true)] {
            let y0 = [0.3, -1.0, 2.0];
            let mut rls = Rls::new(p, y0);
            let prior = rls.beta;
            let mut rows = Vec::new();
            let mut ys = Vec::new();
            let mut ws = Vec::new();
            for n in 1..=40 {
                let mut z = [0.0; MAX_P];
                z[0] = 1.0;
                for v in z.iter_mut().take(p).skip(1) {
                    *v = rnd();
                }
                let y = [rnd(), rnd() + 1.0, 3.0 * rnd()];
                let c = if weighted && n % 5 == 0 { 40.0 } else { 1.0 };
                rls.update_weighted(&z, y, c);
                rows.push(z);
                ys.push(y);
                ws.push(1.0 / c);
                if n % 7 == 0 {
                    rls.symmetrise();
                }
                let (beta, inv) = if weighted {
                    batch_ridge_weighted(&rows, &ys, &ws, p, &prior)
                } else {
                    batch_ridge(&rows, &ys, p, &prior)
                };
                for ch in 0..3 {
                    for j in 0..p {
                        let (a, b) = (rls.beta[ch][j], beta[ch][j]);
                        assert!(
                            (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                            "p{p} n{n} β: {a} vs {b}"
                        );
                    }
                }
                for j in 0..p {
                    for l in 0..p {
                        let (a, b) = (rls.pm[j][l], inv[j][l]);
                        assert!(
                            (a - b).abs() <= 1e-9 * b.abs().max(1e-3),
                            "p{p} n{n} P: {a} vs {b}"
                        );
                    }
                }
            }
        }
    }
}
