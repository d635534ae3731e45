//! Scalar twin of `spirv/aos_fit.comp`: AOS's fits at one pixel (spec §5.3
//! steps 2–8) in the algebra the kernel uses, one workgroup per pixel.
//!
//! [`super::aos::pixel`] builds every equivalent kernel and bias image
//! explicitly. The kernel forms only what a fixed amount of workgroup memory
//! holds: the normal matrix `N = Σ K_i x_i x_iᵀ` of the order-5 design (at
//! most 51 columns), the right-hand sides `Σ K_i x_i y_i[ch]`, and one
//! Cholesky factor whose leading blocks serve orders 1 and 3
//! (AOS-ONE-RIDGE). Everything else follows from them:
//!
//! * `u_l = A_l⁻¹ e_1`, so the output is `m̂[ch] = u_lᵀ (X_lᵀ W y[ch])`;
//! * `bias_l = Σ_i l_i ξ_i = u_lᵀ N[0..p_l, :] β*_high` (the order-5
//!   coefficients of powers `l+1 ..= l+2`);
//! * `t_l = N[:, 0..p_l] u_l` restricted to those powers and `q_l = A*⁻¹ t_l`
//!   give the bias estimate's weights `g_i = K_i q_lᵀ x_i`;
//! * one more pass over the window sums `K_i² (u·x_i)²` (times `vbar_i`) for
//!   `u*`, `u_1`, `u_3`, and `K_i² (q_l·x_i)² vbar_i`: `σ*²`, the paper's
//!   `[A⁻¹BA⁻¹]_00 = Σ l_i²`, the sandwich variance and the bias variance.
//!
//! The AOS-SCALE column scales come from a first pass: the weighted mean
//! square of `Δz_j^v` for every power and component.

use super::aos::{BIAS_Z, INCREMENT, P_STAR, RIDGE, RMS_EPS};
use super::aos_space::{features, Proj, D};
use super::linalg::{ridge_cholesky, EPS_PIVOT};
use super::spp_of;
use crate::shared::{AosPush, AOS_BIAS_TEST, AOS_IDENTITY, AOS_SANDWICH};

/// Output planes, in order: colour R G B (clamped ≥ 0), `MSE_c`, the chosen
/// order (0: the input), rank `k`, `bias_1`, `var_1`, `bias_3`, `var_3`,
/// `σ*²`, `sd(bias_1)`, `sd(bias_3)`.
pub const OUTPUTS: usize = 13;

/// Names of the debug planes 4..13 (§5.5).
pub const DEBUG_NAMES: [&str; 9] = [
    "aos_order",
    "aos_rank",
    "aos_bias1",
    "aos_var1",
    "aos_bias3",
    "aos_var3",
    "aos_sigma2",
    "aos_bias_sd1",
    "aos_bias_sd3",
];

/// Most columns of the order-5 design: `1 + 5·D`.
pub const MAX_COLS: usize = 1 + P_STAR * D;

/// The planes `aos_fit` reads.
#[derive(Clone, Copy)]
pub struct FitInputs<'a> {
    /// Depth, albedo rgb, normal xyz, visibility (prefiltered).
    pub feats: [&'a [f32]; 8],
    /// Colour R, G, B.
    pub color: [&'a [f32]; 3],
    /// `vbar` (mean colour variance).
    pub vbar: &'a [f32],
    /// Sample counts.
    pub spp: &'a [f32],
}

/// The mean of the valid 3×3 neighbours of an invalid pixel (0 if none),
/// as every method fills invalid pixels (§0.2).
pub fn fill(w: usize, h: usize, plane: &[f32], spp: &[f32], c: usize) -> f64 {
    let (cx, cy) = (c % w, c / w);
    let (mut s, mut n) = (0.0, 0);
    for qy in cy.saturating_sub(1)..(cy + 2).min(h) {
        for qx in cx.saturating_sub(1)..(cx + 2).min(w) {
            let q = qy * w + qx;
            if spp_of(spp[q]) >= 1.0 {
                s += plane[q] as f64;
                n += 1;
            }
        }
    }
    if n > 0 {
        s / n as f64
    } else {
        0.0
    }
}

/// One window row: kernel weight and the design row (compact columns).
struct Row {
    q: usize,
    k: f64,
    x: Vec<f64>,
}

/// The [`OUTPUTS`] values of pixel `c` with projection `proj`.
pub fn fit_pixel(push: &AosPush, inp: &FitInputs, c: usize, proj: &Proj) -> [f64; OUTPUTS] {
    let (w, h) = (push.width as usize, push.height as usize);
    let mut o = [0.0; OUTPUTS];
    if spp_of(inp.spp[c]) < 1.0 {
        for ch in 0..3 {
            o[ch] = fill(w, h, inp.color[ch], inp.spp, c).max(0.0);
        }
        return o;
    }
    let vbar = |q: usize| inp.vbar[q] as f64;
    let col = |ch: usize, q: usize| inp.color[ch][q] as f64;
    // AOS-FALLBACK: the input, error vbar_c.
    for ch in 0..3 {
        o[ch] = col(ch, c).max(0.0);
    }
    o[3] = vbar(c);
    o[5] = proj.k as f64;
    let k = proj.k;
    if k == 0 {
        return o;
    }
    let r = push.radius as usize;
    let (cx, cy) = (c % w, c / w);
    let xc = features(w, &inp.feats, c);
    let bw = r.max(1) as f64;
    // Pass 0: Δz and K of the window's valid pixels (raster order), the
    // weighted mean squares of every power.
    let mut win: Vec<(usize, f64, [f64; D])> = Vec::new();
    for qy in cy.saturating_sub(r)..(cy + r + 1).min(h) {
        for qx in cx.saturating_sub(r)..(cx + r + 1).min(w) {
            let q = qy * w + qx;
            if spp_of(inp.spp[q]) < 1.0 {
                continue;
            }
            let (dx, dy) = (qx as f64 - cx as f64, qy as f64 - cy as f64);
            let kw = (-(dx * dx + dy * dy) / (2.0 * bw * bw)).exp();
            win.push((q, kw, proj.dz(&features(w, &inp.feats, q), &xc)));
        }
    }
    let ksum: f64 = win.iter().map(|t| t.1).sum();
    let mut cols: Vec<(usize, usize, f64)> = vec![(0, 0, 1.0)];
    for v in 1..=P_STAR {
        for j in 0..k {
            let ms: f64 = win.iter().map(|t| t.1 * powi(t.2[j], 2 * v)).sum::<f64>();
            let rms = (ms / ksum).sqrt();
            if rms >= RMS_EPS {
                cols.push((v, j, 1.0 / rms));
            }
        }
    }
    let pc = cols.len();
    let p_of = |l: usize| cols.iter().filter(|c| c.0 <= l).count();
    let rows: Vec<Row> = win
        .iter()
        .map(|&(q, kw, dz)| Row {
            q,
            k: kw,
            x: cols
                .iter()
                .map(|&(v, j, s)| if v == 0 { 1.0 } else { powi(dz[j], v) * s })
                .collect(),
        })
        .collect();
    // Pass 1: N and the right-hand sides.
    let mut n = vec![0.0; pc * pc];
    let mut rhs = [vec![0.0; pc], vec![0.0; pc], vec![0.0; pc]];
    for row in &rows {
        for i in 0..pc {
            for j in 0..=i {
                n[i * pc + j] += row.k * row.x[i] * row.x[j];
            }
            for (ch, b) in rhs.iter_mut().enumerate() {
                b[i] += row.k * row.x[i] * col(ch, row.q);
            }
        }
    }
    for i in 0..pc {
        for j in 0..i {
            n[j * pc + i] = n[i * pc + j];
        }
    }
    let chol = ridge_cholesky(&n, pc, RIDGE * ksum, EPS_PIVOT);
    if chol.failed {
        return o;
    }
    // Solves with leading blocks of the factor.
    let solve = |p: usize, b: &[f64]| -> Vec<f64> {
        let l = |i: usize, j: usize| chol.l[i * pc + j];
        let mut x = b[..p].to_vec();
        for i in 0..p {
            let mut s = x[i];
            for kk in 0..i {
                s -= l(i, kk) * x[kk];
            }
            x[i] = s / l(i, i);
        }
        for i in (0..p).rev() {
            let mut s = x[i];
            for kk in i + 1..p {
                s -= l(kk, i) * x[kk];
            }
            x[i] = s / l(i, i);
        }
        x
    };
    let mut e1 = vec![0.0; pc];
    e1[0] = 1.0;
    let grey: Vec<f64> = (0..pc)
        .map(|i| (rhs[0][i] + rhs[1][i] + rhs[2][i]) / 3.0)
        .collect();
    let u_star = solve(pc, &e1);
    let beta = solve(pc, &grey);
    let orders = [1usize, 3];
    let ps = orders.map(p_of);
    let us = ps.map(|p| solve(p, &e1));
    let mut bias = [0.0; 2];
    let mut qs: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for (o_i, &l) in orders.iter().enumerate() {
        let high = |i: usize| cols[i].0 > l && cols[i].0 <= l + INCREMENT;
        let p = ps[o_i];
        let u = &us[o_i];
        // bias_l = u_lᵀ N[0..p, :] β_high
        for i in 0..p {
            let nb: f64 = (0..pc)
                .filter(|&j| high(j))
                .map(|j| n[i * pc + j] * beta[j])
                .sum();
            bias[o_i] += u[i] * nb;
        }
        let t: Vec<f64> = (0..pc)
            .map(|i| {
                if high(i) {
                    (0..p).map(|j| n[i * pc + j] * u[j]).sum()
                } else {
                    0.0
                }
            })
            .collect();
        qs[o_i] = solve(pc, &t);
    }
    // Pass 2: σ*², Σ l², Σ l² vbar, Σ g² vbar.
    let dot = |a: &[f64], x: &[f64]| a.iter().zip(x).map(|(a, x)| a * x).sum::<f64>();
    let (mut sigma2, mut sq, mut sw, mut bv) = (0.0, [0.0; 2], [0.0; 2], [0.0; 2]);
    for row in &rows {
        let k2 = row.k * row.k;
        let vb = vbar(row.q);
        let ds = dot(&u_star, &row.x);
        sigma2 += k2 * ds * ds * vb;
        for o_i in 0..2 {
            let d = dot(&us[o_i], &row.x[..ps[o_i]]);
            sq[o_i] += k2 * d * d;
            sw[o_i] += k2 * d * d * vb;
            let g = dot(&qs[o_i], &row.x);
            bv[o_i] += k2 * g * g * vb;
        }
    }
    let mut best: Option<(usize, f64)> = None;
    for o_i in 0..2 {
        let var = if push.flags & AOS_SANDWICH != 0 {
            sw[o_i]
        } else {
            sq[o_i] * sigma2
        };
        let b = bias[o_i];
        let counted = if push.flags & AOS_BIAS_TEST == 0 || b * b > BIAS_Z * BIAS_Z * bv[o_i] {
            b
        } else {
            0.0
        };
        let mse = var + counted * counted;
        o[6 + 2 * o_i] = b;
        o[7 + 2 * o_i] = var;
        o[11 + o_i] = bv[o_i].sqrt();
        if best.map_or(true, |(_, m)| mse < m) {
            best = Some((o_i, mse));
        }
    }
    o[10] = sigma2;
    let (o_i, mse) = best.expect("two orders");
    if push.flags & AOS_IDENTITY != 0 && vbar(c) < mse {
        return o;
    }
    for ch in 0..3 {
        o[ch] = dot(&us[o_i], &rhs[ch][..ps[o_i]]).max(0.0);
    }
    o[3] = mse;
    o[4] = orders[o_i] as f64;
    o
}

/// `x^e` by repeated multiplication, as the kernel computes it.
fn powi(x: f64, e: usize) -> f64 {
    let mut p = 1.0;
    for _ in 0..e {
        p *= x;
    }
    p
}

/// `aos_fit` over rows `push.base_row ..` (to the image's end), reading the
/// projections of `scratch` ([`super::aos_space::aos_space`]'s layout,
/// indexed from `base_row`). Returns the [`OUTPUTS`] full planes; rows
/// before `base_row` stay 0.
pub fn aos_fit(push: &AosPush, inp: &FitInputs, scratch: &[f32]) -> Vec<Vec<f32>> {
    let (w, h) = (push.width as usize, push.height as usize);
    let y0 = push.base_row as usize;
    let px = super::par_map((h - y0) * w, |i| {
        fit_pixel(push, inp, y0 * w + i, &Proj::read(scratch, i))
    });
    let mut out = vec![vec![0.0f32; w * h]; OUTPUTS];
    for (i, v) in px.iter().enumerate() {
        for (plane, &x) in out.iter_mut().zip(v) {
            plane[y0 * w + i] = x as f32;
        }
    }
    out
}
