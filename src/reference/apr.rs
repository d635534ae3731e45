//! APR, adaptive polynomial rendering (spec §4), in f64 from the definitions:
//! the reference of the GPU kernels and the CPU path.
//!
//! Per channel and per block (centre `c` on the 14-pixel grid, 29×29 window):
//! the accepted set `A_c` (confidence-interval test), the design
//! `[1, scaled features, monomials of (dx, dy)/14 up to order K]`, Gaussian
//! weights (h = 14), ridge `λ = 1e-6·Σ K_h` on every column but the
//! intercept, and for each order K ∈ {0..3} the stage error
//! `ξ̂(K) = Σ K_h (bias² + var) / Σ K_h` with `bias = Hŷ − ŷ` and
//! `var = Σ_j H_ij² σ̂²_j = x_iᵀ C x_i`, `C = M⁻¹(Σ K_h² σ̂² x xᵀ)M⁻¹`. Two
//! stages (§4.3): stage 1 picks `K̂¹` from `(y, v)`, blends `H y` and
//! `H √v` into `ŷ₁`, `σ̂₁`; stage 2 picks `K̂²` from `(ŷ₁, σ̂₁²)`, and the
//! output is the blend of `H(K̂²) y`. Pixels no sparse block accepts get a
//! block of their own (COVER), which contributes only to themselves.
//!
//! The lower orders' designs are leading blocks of order 3's (columns in the
//! order [1, features, degree 1, 2, 3]), as the GPU kernels use them.

use super::linalg::ridge_cholesky;

/// Window radius and centre spacing (29×29 blocks every 14 pixels).
pub use crate::shared::APR_RADIUS as RADIUS;
/// Gaussian kernel bandwidth h (half the window).
pub const BANDWIDTH: f64 = 14.0;
/// Candidate orders K = 0..=MAX_ORDER.
pub const MAX_ORDER: usize = 3;
/// Polynomial columns per order: `(K+1)(K+2)/2 − 1`.
pub const POLY_COLS: [usize; 4] = [0, 2, 5, 9];
/// Confidence-interval rejection: `|y_i − y_c| <= 3·sqrt(v_i + v_c)`.
pub const REJECT_K: f64 = 3.0;

/// Decision APR-OUTLIER-W (ours): WLR's OUTLIER-W of spec §2.3 step 2
/// carried over to APR, per channel: a block's kernel is `K_h(i)·o_i` with
/// `o_i = 1/max(v_i, 1)` (option `apr.outlier_weight = clamped(default)|off`).
/// The confidence interval cannot reject a pixel dominated by one bright
/// sample: its standard error is about its own value, so `|y_i − y_c|` is
/// always within 3 of them. A small light seen through a glossy surface is
/// a *cluster* of such pixels, which the outlier stage leaves alone
/// (OUTLIER-ISOLATED); with `K_h` alone every block within 14 pixels
/// averaged it in, and APR came out worse than its input.
/// Pixels with `v_i <= 1` keep `K_h`. `H·1 = 1` still holds (the intercept
/// is unpenalised) and every formula of §4.2 reads `W = diag(K_h·o)`.
#[inline]
pub fn outlier_weight(v: f64, clamped: bool) -> f64 {
    if clamped {
        1.0 / v.max(1.0)
    } else {
        1.0
    }
}
/// Ridge factor: `λ = 1e-6·Σ K_h`.
pub const RIDGE: f64 = 1e-6;
/// Features whose spread over `A_c` is at most this are dropped.
pub const FEATURE_EPS: f64 = 1e-6;
/// The feature prefilter's window radius and bandwidth (§4.6).
pub const PREFILTER_RADIUS: usize = 2;
/// §4.6: `h = 2`.
pub const PREFILTER_BANDWIDTH: f64 = 2.0;
/// Number of stages T (`apr.stages`).
pub const STAGES: usize = 2;

/// The image a block reads: one channel's values and variances, the feature
/// planes (possibly none), validity.
#[derive(Clone, Copy)]
pub struct Planes<'a> {
    /// Width in pixels.
    pub w: usize,
    /// Height in pixels.
    pub h: usize,
    /// The channel's (outlier-cleaned) values.
    pub y: &'a [f64],
    /// Their variances.
    pub v: &'a [f64],
    /// Feature planes (normal xyz, albedo rgb, depth, visibility).
    pub feats: &'a [Vec<f64>],
    /// Valid pixels (§0.2).
    pub valid: &'a [bool],
    /// APR-COUNT-CAP: per pixel the factor on its variance in the interval
    /// test ([`test_scales`]); `None`: the spec's test.
    pub test_scale: Option<&'a [f64]>,
}

impl Planes<'_> {
    /// The variance pixel `q` enters the interval test with.
    pub fn test_var(&self, q: usize) -> f64 {
        self.v[q] * self.test_scale.map_or(1.0, |s| s[q])
    }
}

/// APR-COUNT-CAP: the multiple of the image's mean count at which the
/// interval test's precision stops growing.
pub const COUNT_CAP_K: f32 = 2.0;

/// Decision APR-COUNT-CAP (ours): the factor on pixel `q`'s variance in
/// §4.2's interval test, `max(1, n_q / (K n̄))` with `K` = [`COUNT_CAP_K`]
/// and `n̄` the image's mean count over its valid pixels
/// ([`spp_total_mean`](super::spp_total::spp_total_mean)), in f32 as on the
/// GPU. The test runs on variances of the means, so under adaptive sampling
/// it tightens without bound where a map pours samples: a pixel with many
/// times the mean's samples rejects neighbours whose levels the polynomial
/// models, falls back to a block of its own (COVER), and keeps its noise.
/// Capped, a pixel is tested as if it had at most `K n̄` samples; on a
/// uniform render nothing changes.
pub fn test_scale(spp: f32, nbar: f32) -> f64 {
    if nbar > 0.0 {
        (super::spp_of(spp) as f32 / (COUNT_CAP_K * nbar)).max(1.0) as f64
    } else {
        1.0
    }
}

/// [`test_scale`] of every pixel of `spp` (all 1 when `on` is false).
pub fn test_scales(spp: &[f32], on: bool) -> Vec<f64> {
    let nbar = super::spp_total::spp_total_mean(super::spp_total::spp_total(spp));
    spp.iter()
        .map(|&s| if on { test_scale(s, nbar) } else { 1.0 })
        .collect()
}

/// Window and rejection of a kind of block.
#[derive(Clone, Copy, Debug)]
pub struct Shape {
    /// Window radius.
    pub radius: usize,
    /// Gaussian bandwidth.
    pub bandwidth: f64,
    /// Confidence-interval rejection (off in the prefilter, PF-NOREJECT).
    pub reject: bool,
    /// The kernel is `K_h·o_i` (APR-OUTLIER-W; off in the prefilter).
    pub clamped: bool,
}

/// The image blocks (§4.2).
pub const BLOCK: Shape = Shape {
    radius: RADIUS,
    bandwidth: BANDWIDTH,
    reject: true,
    clamped: true,
};

/// The image blocks with `apr.outlier_weight=off` (the paper's `K_h`).
pub const BLOCK_UNWEIGHTED: Shape = Shape {
    clamped: false,
    ..BLOCK
};

/// [`BLOCK`] with `apr.outlier_weight=clamped`, [`BLOCK_UNWEIGHTED`] with `off`.
pub fn block_shape(clamped: bool) -> Shape {
    if clamped {
        BLOCK
    } else {
        BLOCK_UNWEIGHTED
    }
}

/// The feature prefilter's blocks (§4.6).
pub const PREFILTER: Shape = Shape {
    radius: PREFILTER_RADIUS,
    bandwidth: PREFILTER_BANDWIDTH,
    reject: false,
    clamped: false,
};

/// One block's design: accepted pixels, rows, weights, and the feature
/// scaling (so rows can be formed again for any pixel).
#[derive(Clone, Debug)]
pub struct Design {
    /// Centre pixel.
    pub centre: usize,
    /// Accepted pixels `A_c` in raster order.
    pub idx: Vec<usize>,
    /// Kernel weights `K_h(i)·o_i` of the accepted pixels (APR-OUTLIER-W;
    /// `K_h(i)` without it).
    pub kh: Vec<f64>,
    /// Rows at the largest order (`idx.len() × p3`, row-major).
    pub rows: Vec<f64>,
    /// Columns at each order: `p_K = 1 + kept features + POLY_COLS[K]`.
    pub p: [usize; 4],
    /// Per feature plane: `s_j`, or 0 when dropped.
    pub scale: Vec<f64>,
    /// Ridge λ: `1e-6·Σ K_h`, raised by SOLVE-FAIL retries of the largest
    /// order's factorisation (APR-RIDGE-BLOCK), so every order of the block
    /// uses the same λ.
    pub lambda: f64,
    /// The largest order's factorisation failed after every retry: the block
    /// outputs its centre value (SOLVE-FAIL), like a block of one pixel.
    pub failed: bool,
    radius: usize,
    bandwidth: f64,
}

impl Design {
    /// The design row of pixel `i` at the largest order (any pixel of the
    /// window, accepted or not).
    pub fn row(&self, pl: &Planes, i: usize) -> Vec<f64> {
        let (w, c) = (pl.w, self.centre);
        let u = ((i % w) as f64 - (c % w) as f64) / self.radius as f64;
        let v = ((i / w) as f64 - (c / w) as f64) / self.radius as f64;
        let mut r = vec![1.0];
        for (j, f) in pl.feats.iter().enumerate() {
            if self.scale[j] > 0.0 {
                r.push((f[i] - f[c]) / self.scale[j]);
            }
        }
        r.extend([
            u,
            v,
            u * u,
            u * v,
            v * v,
            u * u * u,
            u * u * v,
            u * v * v,
            v * v * v,
        ]);
        r
    }

    /// Kernel weight of pixel `i`.
    pub fn weight(&self, w: usize, i: usize) -> f64 {
        let c = self.centre;
        let dx = (i % w) as f64 - (c % w) as f64;
        let dy = (i / w) as f64 - (c / w) as f64;
        (-(dx * dx + dy * dy) / (2.0 * self.bandwidth * self.bandwidth)).exp()
    }

    fn p3(&self) -> usize {
        self.p[MAX_ORDER]
    }

    /// `M_K = X_Kᵀ W X_K` (unregularised) over `A_c`.
    fn normal(&self, k: usize) -> Vec<f64> {
        let (p, p3) = (self.p[k], self.p3());
        let mut m = vec![0.0; p * p];
        for (r, &kh) in self.kh.iter().enumerate() {
            let x = &self.rows[r * p3..r * p3 + p];
            for a in 0..p {
                for b in 0..p {
                    m[a * p + b] += kh * x[a] * x[b];
                }
            }
        }
        m
    }
}

/// Builds the design of the block centred at `c` (steps 1–3 of §4.2).
pub fn design(pl: &Planes, shape: Shape, c: usize) -> Design {
    let (w, h) = (pl.w, pl.h);
    let (cx, cy) = (c % w, c / w);
    let r = shape.radius;
    let mut idx = Vec::new();
    for qy in cy.saturating_sub(r)..(cy + r + 1).min(h) {
        for qx in cx.saturating_sub(r)..(cx + r + 1).min(w) {
            let q = qy * w + qx;
            if !pl.valid[q] {
                continue;
            }
            if shape.reject
                && q != c
                && (pl.y[q] - pl.y[c]).abs()
                    > REJECT_K * (pl.test_var(q) + pl.test_var(c)).max(0.0).sqrt()
            {
                continue;
            }
            idx.push(q);
        }
    }
    let scale: Vec<f64> = pl
        .feats
        .iter()
        .map(|f| {
            let s = idx.iter().map(|&q| (f[q] - f[c]).abs()).fold(0.0, f64::max);
            if s <= FEATURE_EPS {
                0.0
            } else {
                s
            }
        })
        .collect();
    let kept = scale.iter().filter(|&&s| s > 0.0).count();
    let p = std::array::from_fn(|k| 1 + kept + POLY_COLS[k]);
    let mut d = Design {
        centre: c,
        idx,
        kh: Vec::new(),
        rows: Vec::new(),
        p,
        scale,
        lambda: 0.0,
        failed: false,
        radius: r,
        bandwidth: shape.bandwidth,
    };
    d.kh = d
        .idx
        .iter()
        .map(|&q| d.weight(w, q) * outlier_weight(pl.v[q], shape.clamped))
        .collect();
    d.rows = d.idx.iter().flat_map(|&q| d.row(pl, q)).collect();
    d.lambda = RIDGE * d.kh.iter().sum::<f64>();
    // Decision APR-RIDGE-BLOCK (ours): SOLVE-FAIL's retries run once per
    // block, on the largest order's matrix; the lower orders' matrices are
    // its leading blocks, whose pivots are its first pivots, so they factor
    // with the same λ. The GPU kernel factors once and reads every order
    // from that factor.
    let f = ridge_cholesky(
        &d.normal(MAX_ORDER),
        d.p3(),
        d.lambda,
        super::linalg::EPS_PIVOT,
    );
    d.lambda = f.lambda;
    d.failed = f.failed;
    d
}

impl Design {
    /// A block that fits nothing: one accepted pixel (ALONE) or a failed
    /// factorisation (SOLVE-FAIL). It outputs its centre value.
    pub fn degenerate(&self) -> bool {
        self.idx.len() <= 1 || self.failed
    }
}

/// One order's solved block: `β` of the responses asked for, the stage
/// error, `tr H`.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The order K.
    pub order: usize,
    /// `ξ̂(K)` of the stage.
    pub xi: f64,
    /// `tr H(K)`.
    pub trace: f64,
}

/// Solves `M_K β = X_Kᵀ W z` over the accepted pixels. A degenerate block
/// gives `[z_c]`: its output is the centre value wherever it is evaluated.
pub fn beta(d: &Design, k: usize, z: &[f64]) -> Vec<f64> {
    if d.degenerate() {
        return vec![z[d.centre]];
    }
    let (p, p3) = (d.p[k], d.p3());
    let m = d.normal(k);
    let mut rhs = vec![0.0; p];
    for (r, (&q, &kh)) in d.idx.iter().zip(&d.kh).enumerate() {
        for a in 0..p {
            rhs[a] += kh * d.rows[r * p3 + a] * z[q];
        }
    }
    ridge_cholesky(&m, p, d.lambda, super::linalg::EPS_PIVOT).solve(&rhs)
}

/// `x_Kᵀ β` for a full-order row `x`.
pub fn eval(x: &[f64], beta: &[f64]) -> f64 {
    beta.iter().zip(x).map(|(b, x)| b * x).sum()
}

/// The stage error `ξ̂(K)` of a block with `yprev = ŷ_{t−1}` and
/// `s2prev = σ̂²_{t−1}` (step 5), and `tr H(K)` (step 4).
pub fn stage_error(d: &Design, k: usize, yprev: &[f64], s2prev: &[f64]) -> Fit {
    let (p, p3, n) = (d.p[k], d.p3(), d.idx.len());
    let m = d.normal(k);
    let chol = ridge_cholesky(&m, p, d.lambda, super::linalg::EPS_PIVOT);
    let b = beta(d, k, yprev);
    // C = M⁻¹ V M⁻¹ with V = Σ K² σ̂² x xᵀ.
    let mut v = vec![0.0; p * p];
    for r in 0..n {
        let x = &d.rows[r * p3..r * p3 + p];
        let s = d.kh[r] * d.kh[r] * s2prev[d.idx[r]];
        for a in 0..p {
            for bb in 0..p {
                v[a * p + bb] += s * x[a] * x[bb];
            }
        }
    }
    let mut minv = vec![0.0; p * p];
    for j in 0..p {
        let mut e = vec![0.0; p];
        e[j] = 1.0;
        let col = chol.solve(&e);
        for i in 0..p {
            minv[i * p + j] = col[i];
        }
    }
    let mul = |a: &[f64], b: &[f64]| -> Vec<f64> {
        let mut o = vec![0.0; p * p];
        for i in 0..p {
            for j in 0..p {
                o[i * p + j] = (0..p).map(|l| a[i * p + l] * b[l * p + j]).sum();
            }
        }
        o
    };
    let c = mul(&mul(&minv, &v), &minv);
    let (mut num, mut den) = (0.0, 0.0);
    for r in 0..n {
        let x = &d.rows[r * p3..r * p3 + p];
        let bias = eval(x, &b) - yprev[d.idx[r]];
        let mut var = 0.0;
        for a in 0..p {
            for bb in 0..p {
                var += x[a] * c[a * p + bb] * x[bb];
            }
        }
        num += d.kh[r] * (bias * bias + var);
        den += d.kh[r];
    }
    let trace = p as f64 - d.lambda * (1..p).map(|j| minv[j * p + j]).sum::<f64>();
    Fit {
        order: k,
        xi: num / den,
        trace,
    }
}

/// The order of least stage error (ties to the smaller K); ALONE when
/// `|A_c| = 1` (and SOLVE-FAIL): order 0 with `ξ̂ = v_c` and `tr H = 1`.
pub fn choose(d: &Design, pl: &Planes, yprev: &[f64], s2prev: &[f64]) -> Fit {
    if d.degenerate() {
        return Fit {
            order: 0,
            xi: pl.v[d.centre],
            trace: 1.0,
        };
    }
    let mut best = stage_error(d, 0, yprev, s2prev);
    for k in 1..=MAX_ORDER {
        let f = stage_error(d, k, yprev, s2prev);
        if f.xi < best.xi {
            best = f;
        }
    }
    best
}

/// A block's output `(H(K) z)_i` at a pixel `i` it accepted (`z_c` for a
/// degenerate block, whose `β` is `[z_c]`).
fn output(d: &Design, pl: &Planes, k: usize, beta: &[f64], i: usize) -> f64 {
    let p = d.p[k].min(beta.len());
    eval(&d.row(pl, i)[..p], beta)
}

/// What one channel's reconstruction returns.
#[derive(Clone, Debug)]
pub struct ChannelResult {
    /// The final `ŷ`.
    pub color: Vec<f64>,
    /// The blended per-pixel error `ξ̂_i`.
    pub error: Vec<f64>,
    /// The blended `tr H(K̂²)`.
    pub dim: Vec<f64>,
    /// `K̂²` at the sparse centres (+1; 0 elsewhere).
    pub centre_order: Vec<f64>,
    /// 1 where the pixel became an extra centre (COVER).
    pub extra: Vec<f64>,
}

/// The sparse centres: valid pixels with `x, y ≡ 0 (mod 14)`.
pub fn centres(w: usize, h: usize, valid: &[bool]) -> Vec<usize> {
    (0..w * h)
        .filter(|&i| (i % w) % RADIUS == 0 && (i / w) % RADIUS == 0 && valid[i])
        .collect()
}

/// The sparse centres whose window holds pixel `i` (`|i − c|_inf <= 14`), in
/// raster order.
pub fn covering(w: usize, h: usize, i: usize, valid: &[bool]) -> Vec<usize> {
    let (x, y) = (i % w, i / w);
    let mut v = Vec::new();
    let lo = |a: usize| a.saturating_sub(RADIUS).div_ceil(RADIUS) * RADIUS;
    let mut cy = lo(y);
    while cy <= (y + RADIUS).min(h - 1) {
        let mut cx = lo(x);
        while cx <= (x + RADIUS).min(w - 1) {
            let c = cy * w + cx;
            if valid[c] {
                v.push(c);
            }
            cx += RADIUS;
        }
        cy += RADIUS;
    }
    v
}

/// APR on one channel (§4.2–4.3): `pl.y`, `pl.v` are the channel, features
/// already prefiltered; `block` is [`BLOCK`] or [`BLOCK_UNWEIGHTED`].
/// `pixel_test`: the sample counts for APR-PIXEL-TEST, `None` for §4.3 as
/// written.
///
/// Decision APR-PIXEL-TEST (ours): with option `apr.pixel_test`, after
/// LP-PIXEL-TEST, a block whose squared miss `(x_iᵀβ_y − y_i)²` at the valid pixel `i`
/// exceeds [`pixel_test_limit`](super::pixel_test_limit) of the channel's
/// `v` does not predict i; a pixel whose accepting blocks all do keeps its
/// input (`y_i`, error `v_i`, dimension 0). It keeps APR's blocks from
/// painting a firefly cluster's level over dark pixels (built-in mix).
pub fn channel(
    pl: &Planes,
    stages: usize,
    block: Shape,
    pixel_test: Option<&[f32]>,
) -> ChannelResult {
    let (w, h) = (pl.w, pl.h);
    let n = w * h;
    let s: Vec<f64> = pl.v.iter().map(|v| v.max(0.0).sqrt()).collect();
    let cs = centres(w, h, pl.valid);
    let designs: Vec<Design> = cs.iter().map(|&c| design(pl, block, c)).collect();
    let pos = |c: usize| cs.binary_search(&c).unwrap();
    // Extra centres: valid pixels no sparse block accepted.
    let accepted_by = |i: usize| -> Vec<usize> {
        covering(w, h, i, pl.valid)
            .into_iter()
            .map(pos)
            .filter(|&b| designs[b].idx.binary_search(&i).is_ok())
            .collect()
    };
    let cover: Vec<Vec<usize>> = (0..n).map(accepted_by).collect();
    let extra: Vec<Option<Design>> = (0..n)
        .map(|i| (pl.valid[i] && cover[i].is_empty()).then(|| design(pl, block, i)))
        .collect();
    let (mut yprev, mut s2prev) = (pl.y.to_vec(), pl.v.to_vec());
    let mut result = ChannelResult {
        color: pl.y.to_vec(),
        error: pl.v.to_vec(),
        dim: vec![1.0; n],
        centre_order: vec![0.0; n],
        extra: extra.iter().map(|e| e.is_some() as u8 as f64).collect(),
    };
    for stage in 1..=stages.max(1) {
        let last = stage == stages.max(1);
        let fits: Vec<Fit> = designs
            .iter()
            .map(|d| choose(d, pl, &yprev, &s2prev))
            .collect();
        let by: Vec<Vec<f64>> = designs
            .iter()
            .zip(&fits)
            .map(|(d, f)| beta(d, f.order, pl.y))
            .collect();
        let bs: Vec<Vec<f64>> = if last {
            Vec::new()
        } else {
            designs
                .iter()
                .zip(&fits)
                .map(|(d, f)| beta(d, f.order, &s))
                .collect()
        };
        let mut ny = pl.y.to_vec();
        let mut ns = s.clone();
        let mut err = pl.v.to_vec();
        let mut dim = vec![1.0; n];
        for i in 0..n {
            if !pl.valid[i] {
                continue;
            }
            if let Some(d) = &extra[i] {
                let f = choose(d, pl, &yprev, &s2prev);
                ny[i] = output(d, pl, f.order, &beta(d, f.order, pl.y), i);
                if !last {
                    ns[i] = output(d, pl, f.order, &beta(d, f.order, &s), i);
                }
                err[i] = f.xi;
                dim[i] = f.trace;
                continue;
            }
            let limit = pixel_test.map(|spp| {
                super::pixel_test_limit(
                    w,
                    h,
                    |q| pl.v[q],
                    |q| (pl.y[q] - pl.y[i]).powi(2),
                    |q| pl.valid[q],
                    spp,
                    i,
                )
            });
            let (mut wsum, mut acc_y, mut acc_s, mut acc_e, mut acc_d) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for &b in &cover[i] {
                let d = &designs[b];
                let kw = d.weight(w, i);
                let k = fits[b].order;
                let fy = output(d, pl, k, &by[b], i);
                if limit.is_some_and(|l| (fy - pl.y[i]).powi(2) > l) {
                    continue;
                }
                wsum += kw;
                acc_y += kw * fy;
                if !last {
                    acc_s += kw * output(d, pl, k, &bs[b], i);
                }
                acc_e += kw * fits[b].xi;
                acc_d += kw * fits[b].trace;
            }
            if wsum > 0.0 {
                ny[i] = acc_y / wsum;
                ns[i] = acc_s / wsum;
                err[i] = acc_e / wsum;
                dim[i] = acc_d / wsum;
            } else {
                // APR-PIXEL-TEST left out every accepting block: the input.
                ny[i] = pl.y[i];
                ns[i] = s[i];
                err[i] = pl.v[i];
                dim[i] = 0.0;
            }
        }
        if last {
            for (b, &c) in cs.iter().enumerate() {
                result.centre_order[c] = fits[b].order as f64 + 1.0;
            }
            result.color = ny;
            result.error = err;
            result.dim = dim;
        } else {
            yprev = ny;
            s2prev = ns.iter().map(|s| s * s).collect();
        }
    }
    result
}

/// The 5×5 polynomial feature prefilter (§4.6) of one feature plane with its
/// variance: every pixel a centre, no rejection, point-wise output, two
/// stages.
///
/// Decision PF-IDENTITY (ours): the unfiltered value is a fifth candidate,
/// with bias 0 and error `Σ K_h σ̂² / Σ K_h` (the window's mean variance); it
/// wins ties. Without it a noise-free feature edge (the rim of a light, an
/// albedo step) is always blurred, since every order 0–3 has bias there, and
/// the blurred features let the blocks mix a light with the wall next to
/// it.
pub fn prefilter_plane(w: usize, h: usize, f: &[f64], var: &[f64], valid: &[bool]) -> Vec<f64> {
    let pl = Planes {
        w,
        h,
        y: f,
        v: var,
        feats: &[],
        valid,
        test_scale: None,
    };
    let n = w * h;
    let s: Vec<f64> = var.iter().map(|v| v.max(0.0).sqrt()).collect();
    let designs: Vec<Option<Design>> = (0..n)
        .map(|i| valid[i].then(|| design(&pl, PREFILTER, i)))
        .collect();
    let (mut yprev, mut s2prev) = (f.to_vec(), var.to_vec());
    let mut out = f.to_vec();
    for stage in 1..=STAGES {
        let last = stage == STAGES;
        let mut ny = f.to_vec();
        let mut ns = s.clone();
        for i in 0..n {
            let Some(d) = &designs[i] else { continue };
            let fit = choose(d, &pl, &yprev, &s2prev);
            // PF-IDENTITY: the unfiltered value competes as one more
            // candidate, with no bias and the window's mean variance.
            let wsum: f64 = d.kh.iter().sum();
            let xi_id = d
                .idx
                .iter()
                .zip(&d.kh)
                .map(|(&q, &k)| k * s2prev[q])
                .sum::<f64>()
                / wsum;
            if xi_id <= fit.xi {
                continue;
            }
            ny[i] = output(d, &pl, fit.order, &beta(d, fit.order, f), i);
            if !last {
                ns[i] = output(d, &pl, fit.order, &beta(d, fit.order, &s), i);
            }
        }
        if last {
            out = ny;
        } else {
            yprev = ny;
            s2prev = ns.iter().map(|s| s * s).collect();
        }
    }
    out
}

/// §0.2: an invalid pixel's output, the plain mean of the valid pixels of its
/// 3×3 neighbourhood in `y` (0 if none).
pub fn invalid_fill(w: usize, h: usize, y: &[f64], valid: &[bool], i: usize) -> f64 {
    super::valid_mean_3x3(w, h, i, |q| valid[q], |q| y[q])
}
