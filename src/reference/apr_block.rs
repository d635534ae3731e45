//! Scalar twin of `spirv/apr_block.comp`: one APR block (spec §4.2) of one
//! channel and one stage, as the GPU computes it, in f64.
//!
//! The design has a fixed layout of [`P`] = 18 columns,
//! `[1, 8 scaled features, u, v, u², uv, v², u³, u²v, uv², v³]`; a dropped
//! feature (spread ≤ 1e-6 over `A_c`, or an absent visibility plane) is a
//! column of zeros. With the ridge on every column but the intercept, a zero
//! column decouples (`M⁻¹` has `1/λ` there and `0` elsewhere in its row), so
//! `H`, `β` on the other columns and `tr H` equal those of the compact design
//! of [`super::apr`]. Order K uses the leading [`PK`]`[K]` columns.
//!
//! One pass over the window finds `A_c` and the feature spreads; a second
//! accumulates `M = Σ K_h x xᵀ`, `V = Σ K_h² σ̂²_{t−1} x xᵀ` and the right-hand
//! sides (`K_h` times `1/max(v, 1)` under APR-OUTLIER-W, as everywhere below); `M + Λ` is factored once (`L`, APR-RIDGE-BLOCK) and inverted
//! (`L⁻¹`, lower triangular), and the leading blocks of `L⁻¹` serve every
//! order: `M_K⁻¹ = L_K⁻ᵀ L_K⁻¹`. With `G = L⁻¹ V L⁻ᵀ` and
//! `E = L⁻¹ M0 L⁻ᵀ` (`M0 = M`, no ridge), `tr H(K) = Σ_{a<p_K} E_aa` and
//! `Σ_i K_h(i) var(i) = tr(M_K⁻¹ V_K M_K⁻¹ M0_K) = Σ_{a,b<p_K} G_ab E_ab`;
//! a third pass sums the squared bias `Σ K_h (x_iᵀ β_K − ŷ_{t−1}(i))²` of the
//! four orders.

use super::linalg::{EPS_PIVOT, RIDGE_FLOOR, SOLVE_RETRIES};
use super::spp_of;

/// Design columns: the 18 of §4.2's order 3 and two more slots, of which
/// the temporal window uses one (APR-TEMPORAL-COLUMNS); unused columns are
/// zero and dropped.
pub const P: usize = 20;
/// Feature columns (normal xyz, albedo rgb, depth, visibility).
pub const NF: usize = 8;
/// Columns of order K: `1 + NF + (K+1)(K+2)/2 − 1`.
pub const PK: [usize; 4] = [9, 11, 14, 18];
/// §10.2's temporal window: the frames `t−2..t+2`, the centre frame at
/// index [`HALF`] of a [`block_in`] window.
pub const FRAMES: usize = 5;
/// See [`FRAMES`].
pub const HALF: usize = 2;
/// Columns of order K in the temporal window (APR-TEMPORAL-COLUMNS, in
/// place of 3D-POLY): §4.2's monomials in `(u, v)` of degree ≤ K, and `τ`
/// from K = 1 on.
pub const PK_T: [usize; 4] = [9, 12, 15, 19];

/// The temporal kernel's bandwidth in frames (3D-KERNEL: half the
/// temporal extent).
pub const TIME_BANDWIDTH: f64 = 2.0;
/// The column of the temporal design that holds `τ` ([`row_in`]).
pub const TAU_COLUMN: usize = 11;
pub use super::apr::{BANDWIDTH, FEATURE_EPS, REJECT_K, RIDGE};
/// Window radius and centre spacing (29×29 blocks every 14 pixels), signed.
pub const RADIUS: i64 = super::apr::RADIUS as i64;
/// f32 values per (block, channel) in the state buffer, [`Block::state`].
pub const STATE: usize = crate::shared::APR_STATE;
/// Offsets in a state record ([`Block::state`]): `β_y`, `β_s` and the
/// feature spreads, each starting on a multiple of 4 so that the gather
/// reads them as whole vec4s (APR-STATE-VEC4).
pub const ST_BETA_Y: usize = 4;
/// See [`ST_BETA_Y`].
pub const ST_BETA_S: usize = 24;
/// See [`ST_BETA_Y`].
pub const ST_SCALES: usize = 44;

/// What a block kernel reads for one channel and stage: f32 planes as on
/// the GPU.
#[derive(Clone, Copy)]
pub struct Inputs<'a> {
    /// Width in pixels.
    pub w: usize,
    /// Height in pixels.
    pub h: usize,
    /// The channel's (outlier-cleaned) values `y`.
    pub y: &'a [f32],
    /// Their variances `v`.
    pub v: &'a [f32],
    /// `ŷ_{t−1}` (stage 1: `y`).
    pub yprev: &'a [f32],
    /// `σ̂²_{t−1}` (stage 1: `v`).
    pub s2prev: &'a [f32],
    /// Feature planes in §4.1's order; `None`: absent (a zero column).
    pub feats: [Option<&'a [f32]>; NF],
    /// Sample counts (valid iff `spp_of >= 1`).
    pub spp: &'a [f32],
    /// APR-OUTLIER-W: the kernel is `K_h·o_i` ([`super::apr::outlier_weight`]).
    pub clamped: bool,
    /// APR-PIXEL-TEST in the gather ([`super::apr::channel`], [`super::pixel_test_limit`]).
    pub pixel_test: bool,
    /// APR-COUNT-CAP: the image's mean count
    /// ([`spp_total_mean`](super::spp_total::spp_total_mean)); `None`: the
    /// spec's test.
    pub nbar: Option<f32>,
}

impl Inputs<'_> {
    /// Whether pixel `i` is valid (§0.2).
    pub fn valid(&self, i: usize) -> bool {
        spp_of(self.spp[i]) >= 1.0
    }

    /// Feature `j` at pixel `i` (0 when absent).
    pub fn feat(&self, j: usize, i: usize) -> f64 {
        self.feats[j].map_or(0.0, |f| f[i] as f64)
    }

    /// The block's kernel at pixel `q`: `K_h(q)·o_q` (APR-OUTLIER-W).
    pub fn fit_weight(&self, c: usize, q: usize) -> f64 {
        weight(self.w, c, q) * super::apr::outlier_weight(self.v[q] as f64, self.clamped)
    }

    /// The variance pixel `q` enters the interval test with: `v_q`, times
    /// [`test_scale`](super::apr::test_scale) under APR-COUNT-CAP.
    pub fn test_var(&self, q: usize) -> f64 {
        self.v[q] as f64
            * self
                .nbar
                .map_or(1.0, |m| super::apr::test_scale(self.spp[q], m))
    }

    /// The confidence-interval test of §4.2 step 1 (`i` always accepts
    /// itself; the caller checks validity).
    pub fn accepts(&self, c: usize, i: usize) -> bool {
        i == c || accepts_from(self, c, self, i)
    }
}

/// The confidence-interval test of pixel `i` of frame `fi` against the
/// centre `c` of frame `fc` (§4.2 step 1; §10.2: against the centre frame),
/// each on its own frame's test variance.
pub fn accepts_from(fc: &Inputs, c: usize, fi: &Inputs, i: usize) -> bool {
    (fi.y[i] as f64 - fc.y[c] as f64).abs()
        <= REJECT_K * (fi.test_var(i) + fc.test_var(c)).max(0.0).sqrt()
}

/// The kernel `K(i)` of pixel `i`, `dt` frames from the block's centre `c`
/// (3D-KERNEL; `dt = 0`: the spatial `K_h`).
pub fn weight_dt(w: usize, c: usize, i: usize, dt: i64) -> f64 {
    let dx = (i % w) as f64 - (c % w) as f64;
    let dy = (i / w) as f64 - (c / w) as f64;
    let t = dt as f64;
    (-(dx * dx + dy * dy) / (2.0 * BANDWIDTH * BANDWIDTH)
        - t * t / (2.0 * TIME_BANDWIDTH * TIME_BANDWIDTH))
        .exp()
}

/// Kernel weight `K_h(i)` of pixel `i` in the block of `c`.
pub fn weight(w: usize, c: usize, i: usize) -> f64 {
    let dx = (i % w) as f64 - (c % w) as f64;
    let dy = (i / w) as f64 - (c / w) as f64;
    (-(dx * dx + dy * dy) / (2.0 * BANDWIDTH * BANDWIDTH)).exp()
}

/// The design row of pixel `i` in the block of `c` with feature spreads
/// `scales` (0: dropped).
pub fn row(inp: &Inputs, c: usize, scales: &[f64; NF], i: usize) -> [f64; P] {
    row_in(inp, inp, c, scales, i, None)
}

/// The design row of pixel `i` of frame `fi` in the block of `c` (of frame
/// `fc`): `dt` `None`, the spatial layout of [`row`]; `Some(dt)`, the
/// temporal window's (APR-TEMPORAL-COLUMNS), `[1, 8 scaled features, u, v,
/// τ, u², uv, v², u³, u²v, uv², v³, 0]` with `τ = dt/2`.
pub fn row_in(
    fc: &Inputs,
    fi: &Inputs,
    c: usize,
    scales: &[f64; NF],
    i: usize,
    dt: Option<i64>,
) -> [f64; P] {
    let w = fi.w;
    let u = ((i % w) as f64 - (c % w) as f64) / RADIUS as f64;
    let v = ((i / w) as f64 - (c / w) as f64) / RADIUS as f64;
    let mut x = [0.0; P];
    x[0] = 1.0;
    for j in 0..NF {
        if scales[j] > 0.0 {
            x[1 + j] = (fi.feat(j, i) - fc.feat(j, c)) / scales[j];
        }
    }
    // §4.2's monomials in (u, v) of degree 1..3, in column order.
    let m = [
        u,
        v,
        u * u,
        u * v,
        v * v,
        u * u * u,
        u * u * v,
        u * v * v,
        v * v * v,
    ];
    match dt {
        None => x[9..18].copy_from_slice(&m),
        Some(dt) => {
            x[9..11].copy_from_slice(&m[..2]);
            x[11] = dt as f64 / HALF as f64;
            x[12..19].copy_from_slice(&m[2..]);
        }
    }
    x
}

/// The clipped window of `c` in raster order: `(pixel)` of valid pixels
/// `c` accepts.
pub fn accepted(inp: &Inputs, c: usize) -> Vec<usize> {
    accepted_in(&[Some(*inp)], c)
        .into_iter()
        .map(|(_, q)| q)
        .collect()
}

/// The frames of a block's window: one frame (the spatial block of §4.2),
/// or [`FRAMES`] frames `t−2..t+2` around the centre frame at [`HALF`]
/// (§10.2; `None` outside the sequence).
fn centre_of(frames: &[Option<Inputs>]) -> (usize, Option<i64>) {
    match frames.len() {
        1 => (0, None),
        FRAMES => (HALF, Some(0)),
        n => panic!("a block's window has 1 or {FRAMES} frames, not {n}"),
    }
}

/// The accepted set of the block of `c` (a pixel of the centre frame) over
/// its window's frames, frame by frame and in raster order: `(frame,
/// pixel)` of the valid pixels the interval test against `c` accepts.
pub fn accepted_in(frames: &[Option<Inputs>], c: usize) -> Vec<(usize, usize)> {
    let (k0, _) = centre_of(frames);
    let ctr = frames[k0].as_ref().expect("the centre frame is present");
    let (w, h) = (ctr.w as i64, ctr.h as i64);
    let (cx, cy) = ((c as i64) % w, (c as i64) / w);
    let mut v = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        let Some(f) = f else { continue };
        for qy in (cy - RADIUS).max(0)..=(cy + RADIUS).min(h - 1) {
            for qx in (cx - RADIUS).max(0)..=(cx + RADIUS).min(w - 1) {
                let q = (qy * w + qx) as usize;
                if f.valid(q) && ((k == k0 && q == c) || accepts_from(ctr, c, f, q)) {
                    v.push((k, q));
                }
            }
        }
    }
    v
}

/// One block's result: what the state keeps (§4.2 step 6).
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// The chosen order `K̂`.
    pub order: usize,
    /// `ξ̂_c(K̂)`.
    pub xi: f64,
    /// `tr H(K̂)`.
    pub trace: f64,
    /// ALONE or SOLVE-FAIL: `β` is the centre value only.
    pub degenerate: bool,
    /// `β_y` (entries past `PK[K̂]` are 0).
    pub beta_y: [f64; P],
    /// `β_s`, `s = √v` (0 when not asked).
    pub beta_s: [f64; P],
    /// Feature spreads `s_j` (0: dropped).
    pub scales: [f64; NF],
    /// The temporal window's design (§10.2, [`row_in`]).
    pub temporal: bool,
}

impl Block {
    /// The f32 state layout shared with the GPU: `[K̂, ξ̂, tr H, degenerate,
    /// β_y (18), 0 × 2, β_s (18), 0 × 2, s_j (8)]` ([`ST_BETA_Y`],
    /// [`ST_BETA_S`], [`ST_SCALES`]).
    pub fn state(&self) -> [f32; STATE] {
        let mut s = [0.0f32; STATE];
        s[0] = self.order as f32;
        s[1] = self.xi as f32;
        s[2] = self.trace as f32;
        s[3] = self.degenerate as u8 as f32;
        for j in 0..P {
            s[ST_BETA_Y + j] = self.beta_y[j] as f32;
            s[ST_BETA_S + j] = self.beta_s[j] as f32;
        }
        for j in 0..NF {
            s[ST_SCALES + j] = self.scales[j] as f32;
        }
        s
    }

    /// The block's output `x_iᵀ β` (of `β_y`, or `β_s` with `s`) at pixel `i`.
    pub fn eval(&self, inp: &Inputs, c: usize, i: usize, s: bool) -> f64 {
        let x = row_in(inp, inp, c, &self.scales, i, self.temporal.then_some(0));
        let b = if s { &self.beta_s } else { &self.beta_y };
        x.iter().zip(b).map(|(x, b)| x * b).sum()
    }
}

/// Lower Cholesky factor of `M + Λ` (18×18, row-major), pivots tested on
/// the kept columns only (a dropped column's pivot is exactly λ). `None` on
/// a failed pivot.
fn cholesky(m: &[[f64; P]; P], kept: &[bool; P], lambda: f64, eps: f64) -> Option<[[f64; P]; P]> {
    let a = |i: usize, j: usize| m[i][j] + if i == j && i > 0 { lambda } else { 0.0 };
    let max_diag = (0..P)
        .filter(|&j| kept[j])
        .map(|j| a(j, j))
        .fold(0.0, f64::max);
    let mut l = [[0.0; P]; P];
    for i in 0..P {
        for j in 0..=i {
            let mut s = a(i, j);
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                // `s > thresh` is false for NaN too (as in linalg).
                if kept[i] && !(s > eps * max_diag && s.is_finite()) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    Some(l)
}

/// `L⁻¹` of a lower-triangular `L`.
fn invert_lower(l: &[[f64; P]; P]) -> [[f64; P]; P] {
    let mut r = [[0.0; P]; P];
    for j in 0..P {
        r[j][j] = 1.0 / l[j][j];
        for i in j + 1..P {
            let mut s = 0.0;
            for k in j..i {
                s += l[i][k] * r[k][j];
            }
            r[i][j] = -s / l[i][i];
        }
    }
    r
}

/// `L⁻¹ X L⁻ᵀ` for a lower-triangular `L⁻¹`.
fn sandwich(li: &[[f64; P]; P], x: &[[f64; P]; P]) -> [[f64; P]; P] {
    let mut t = [[0.0; P]; P];
    for a in 0..P {
        for b in 0..P {
            t[a][b] = (0..=a).map(|k| li[a][k] * x[k][b]).sum();
        }
    }
    let mut o = [[0.0; P]; P];
    for a in 0..P {
        for b in 0..P {
            o[a][b] = (0..=b).map(|k| t[a][k] * li[b][k]).sum();
        }
    }
    o
}

/// `M_K⁻¹ b` on the leading `p` columns: `L_K⁻ᵀ (L_K⁻¹ b)`.
fn solve(li: &[[f64; P]; P], p: usize, b: &[f64; P]) -> [f64; P] {
    let mut z = [0.0; P];
    for a in 0..p {
        z[a] = (0..=a).map(|k| li[a][k] * b[k]).sum();
    }
    let mut x = [0.0; P];
    for a in 0..p {
        x[a] = (a..p).map(|k| li[k][a] * z[k]).sum();
    }
    x
}

/// One block of channel `inp` centred at `c` (a valid pixel), stage
/// `(yprev, s2prev)`; `with_s`: also `β_s` (every stage but the last).
pub fn block(inp: &Inputs, c: usize, with_s: bool, eps: f64) -> Block {
    block_in(&[Some(*inp)], c, with_s, eps)
}

/// One block centred at `c` over the frames of its window (see
/// [`accepted_in`]): the spread, the moments `M`, `V` and the right-hand
/// sides over the whole accepted set; the error (bias, variance), the
/// trace and the normaliser over its centre-frame slice only (SLICE),
/// with `M0` the slice's moments; the orders [`PK`] (one frame) or
/// [`PK_T`] (the temporal window).
pub fn block_in(frames: &[Option<Inputs>], c: usize, with_s: bool, eps: f64) -> Block {
    let (k0, dt0) = centre_of(frames);
    let temporal = dt0.is_some();
    let ctr = frames[k0].as_ref().expect("the centre frame is present");
    let fr = |k: usize| frames[k].as_ref().expect("an accepted frame is present");
    let dt = |k: usize| dt0.map(|_| k as i64 - k0 as i64);
    let acc = accepted_in(frames, c);
    let mut scales = [0.0; NF];
    for (j, s) in scales.iter_mut().enumerate() {
        if ctr.feats[j].is_none() {
            continue;
        }
        let fc = ctr.feat(j, c);
        let m = acc
            .iter()
            .map(|&(k, q)| (fr(k).feat(j, q) - fc).abs())
            .fold(0.0, f64::max);
        *s = if m <= FEATURE_EPS { 0.0 } else { m };
    }
    let degenerate = |scales| {
        let mut by = [0.0; P];
        let mut bs = [0.0; P];
        by[0] = ctr.y[c] as f64;
        bs[0] = (ctr.v[c] as f64).max(0.0).sqrt();
        Block {
            order: 0,
            xi: ctr.v[c] as f64,
            trace: 1.0,
            degenerate: true,
            beta_y: by,
            beta_s: if with_s { bs } else { [0.0; P] },
            scales,
            temporal,
        }
    };
    if acc.len() <= 1 {
        return degenerate(scales);
    }
    let fit_weight = |k: usize, q: usize| {
        let f = fr(k);
        weight_dt(f.w, c, q, dt(k).unwrap_or(0))
            * super::apr::outlier_weight(f.v[q] as f64, f.clamped)
    };
    let mut m = [[0.0; P]; P];
    let mut m0 = [[0.0; P]; P];
    let mut vm = [[0.0; P]; P];
    let (mut bp, mut by, mut bs) = ([0.0; P], [0.0; P], [0.0; P]);
    let (mut wsum, mut wslice) = (0.0, 0.0);
    for &(k, q) in &acc {
        let f = fr(k);
        let x = row_in(ctr, f, c, &scales, q, dt(k));
        let kw = fit_weight(k, q);
        let kv = kw * kw * f.s2prev[q] as f64;
        let (yp, y, s) = (
            f.yprev[q] as f64,
            f.y[q] as f64,
            (f.v[q] as f64).max(0.0).sqrt(),
        );
        for a in 0..P {
            for b in 0..P {
                m[a][b] += kw * x[a] * x[b];
                vm[a][b] += kv * x[a] * x[b];
                if k == k0 {
                    m0[a][b] += kw * x[a] * x[b];
                }
            }
            bp[a] += kw * x[a] * yp;
            by[a] += kw * x[a] * y;
            bs[a] += kw * x[a] * s;
        }
        wsum += kw;
        if k == k0 {
            wslice += kw;
        }
    }
    let mut kept = [true; P];
    for j in 0..NF {
        kept[1 + j] = scales[j] > 0.0;
    }
    if temporal && acc.iter().all(|&(k, _)| k == k0) {
        // The τ column is zero without another frame: dropped, as a
        // feature without spread.
        kept[TAU_COLUMN] = false;
    }
    let orders: &[usize] = if temporal { &PK_T } else { &PK };
    for k in kept.iter_mut().skip(*orders.last().unwrap()) {
        *k = false;
    }
    let nkept = kept.iter().filter(|&&k| k).count();
    let mean_diag = (0..P).filter(|&j| kept[j]).map(|j| m[j][j]).sum::<f64>() / nkept as f64;
    let mut lambda = RIDGE * wsum;
    let mut factor = None;
    for attempt in 0..=SOLVE_RETRIES {
        if attempt > 0 {
            lambda = (10.0 * lambda).max(RIDGE_FLOOR * mean_diag);
        }
        factor = cholesky(&m, &kept, lambda, eps);
        if factor.is_some() {
            break;
        }
    }
    let Some(l) = factor else {
        return degenerate(scales);
    };
    let li = invert_lower(&l);
    // G = L⁻¹ V L⁻ᵀ and E = L⁻¹ M0 L⁻ᵀ (M0: the slice's moments, without
    // the ridge): tr H_K = Σ_{a<p} E_aa and Σ K_h var = tr(M_K⁻¹ V_K M_K⁻¹
    // M0_K) = Σ_{a,b<p} G_ab E_ab, both free of the cancellation of
    // `p − λ Σ (M⁻¹)_jj` in f32.
    let g = sandwich(&li, &vm);
    let e = sandwich(&li, &m0);
    let no = orders.len();
    let mut betas = [[0.0; P]; 4];
    let mut varsum = [0.0; 4];
    let mut trace = [0.0; 4];
    for (k, &p) in orders.iter().enumerate() {
        betas[k] = solve(&li, p, &bp);
        for a in 0..p {
            trace[k] += e[a][a];
            for b in 0..p {
                varsum[k] += g[a][b] * e[a][b];
            }
        }
    }
    let mut rss = [0.0; 4];
    for &(k, q) in acc.iter().filter(|&&(k, _)| k == k0) {
        let f = fr(k);
        let x = row_in(ctr, f, c, &scales, q, dt(k));
        let kw = fit_weight(k, q);
        let yp = f.yprev[q] as f64;
        for o in 0..no {
            let r: f64 = x.iter().zip(&betas[o]).map(|(x, b)| x * b).sum::<f64>() - yp;
            rss[o] += kw * r * r;
        }
    }
    let mut best = 0;
    let xi = |o: usize| (rss[o] + varsum[o]) / wslice;
    for o in 1..no {
        if xi(o) < xi(best) {
            best = o;
        }
    }
    Block {
        order: best,
        xi: xi(best),
        trace: trace[best],
        degenerate: false,
        beta_y: solve(&li, orders[best], &by),
        beta_s: if with_s {
            solve(&li, orders[best], &bs)
        } else {
            [0.0; P]
        },
        scales,
        temporal,
    }
}

pub use crate::shared::apr_grid as grid;

/// Whether some valid sparse centre within 14 accepts pixel `i` (valid).
/// A pixel none accepts becomes an extra centre (COVER).
pub fn covered(inp: &Inputs, i: usize) -> bool {
    covering(inp.w, inp.h, i)
        .into_iter()
        .any(|c| inp.valid(c) && inp.accepts(c, i))
}

/// The sparse centres with `|i − c|_inf <= 14`, in raster order.
pub fn covering(w: usize, h: usize, i: usize) -> Vec<usize> {
    let r = RADIUS as usize;
    let (x, y) = (i % w, i / w);
    let lo = |a: usize| a.saturating_sub(r).div_ceil(r) * r;
    let mut v = Vec::new();
    let mut cy = lo(y);
    while cy <= (y + r).min(h - 1) {
        let mut cx = lo(x);
        while cx <= (x + r).min(w - 1) {
            v.push(cy * w + cx);
            cx += r;
        }
        cy += r;
    }
    v
}

/// The kernel in sparse mode: the state of every sparse block of the
/// channel (`grid` order; all zero for an invalid centre, order −1), each
/// over its window's frames ([`block_in`]: one frame, or §10.2's five); the
/// centres are the centre frame's.
pub fn sparse(frames: &[Option<Inputs>], with_s: bool, eps: f64) -> Vec<Option<Block>> {
    let inp = frames[centre_of(frames).0].expect("the centre frame is present");
    let (gw, gh) = grid(inp.w, inp.h);
    let r = RADIUS as usize;
    (0..gw * gh)
        .map(|b| {
            let c = (b / gw) * r * inp.w + (b % gw) * r;
            inp.valid(c).then(|| block_in(frames, c, with_s, eps))
        })
        .collect()
}

/// The kernel in extra mode at pixel `i`: `Some(block)` when `i` is a valid
/// pixel no sparse block accepts (its output is `β[0]`, the fit at its own
/// centre), over its window's frames: coverage is the centre frame's, the
/// block [`block_in`]'s.
pub fn extra(frames: &[Option<Inputs>], i: usize, with_s: bool, eps: f64) -> Option<Block> {
    let inp = frames[centre_of(frames).0].expect("the centre frame is present");
    (inp.valid(i) && !covered(&inp, i)).then(|| block_in(frames, i, with_s, eps))
}

/// The pivot threshold of the f64 twin (§0.5).
pub const EPS: f64 = EPS_PIVOT;
