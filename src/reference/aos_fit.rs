//! Scalar twin of `spirv/aos_fit.comp`: AOS's fits at one pixel (spec §5.3
//! steps 2–8) in the algebra the kernel uses, one workgroup per pixel.
//!
//! [`super::aos::pixel`] builds every equivalent kernel and bias image
//! explicitly. The kernel makes one pass over the window and forms only
//! what a fixed amount of workgroup memory holds: three Gram matrices of
//! the raw design rows `[1, Δz_j^v (v = 1..5, j < k)]` extended by colour,
//! `N = Σ K_i x_i x_iᵀ` (with the right-hand sides `Σ K_i x_i y_i[ch]`),
//! `B = Σ K_i² x_i x_iᵀ` and `G = Σ K_i² vbar_i x_i x_iᵀ`. AOS-SCALE comes
//! from `N`'s diagonal (the weighted mean squares), so the scaled, compact
//! matrices are `s_i s_j` times the raw entries. One Cholesky factor of `N`
//! serves all orders through its leading blocks (AOS-ONE-RIDGE). Then:
//!
//! * `u_l = A_l⁻¹ e_1`, so the output is `m̂[ch] = u_lᵀ (X_lᵀ W y[ch])`;
//! * `bias_l = Σ_i l_i ξ_i = u_lᵀ N[0..p_l, :] β*_high` (the order-5
//!   coefficients of powers `l+1 ..= l+2`);
//! * `t_l = N[:, 0..p_l] u_l` restricted to those powers and `q_l = A*⁻¹ t_l`
//!   give the bias estimate's weights `g_i = K_i q_lᵀ x_i`;
//! * the sums over the window are quadratic forms: `σ*² = u*ᵀ G u*`, the
//!   paper's `[A⁻¹BA⁻¹]_00 = u_lᵀ B u_l`, the sandwich variance
//!   `u_lᵀ G u_l` and the bias variance `q_lᵀ G q_l`;
//! * AOS-RESIDUAL: `res_l = u_lᵀ (X_lᵀ W grey) − grey_c`, and with the
//!   centre's weight `l_c = K_c u_l[0]` (its row is `e_1`),
//!   `Σ_i (l_i − δ_ic)² v_i = u_lᵀ G u_l − l_c² vbar_c + (l_c − 1)² v_c`;
//!   the window pass also sums `K_i (ln max(vbar_i, floor) + ln n_i)` and
//!   `K_i` over the pixels that are not all black, for `v_c` (ALL-BLACK);
//! * AOS-FEATNOISE: `β_l = A_l⁻¹ (X_lᵀ W grey)`, and with the power-1
//!   columns' `β s` and the projection, `(Σ_j |Σ_m β_m s_m P[m][j]| σ_j)²`.

use super::aos::{
    all_black, outlier_weight, residual_bias2, residual_centre_var, residual_ln_term, BIAS_Z,
    INCREMENT, P_STAR, RIDGE, RMS_EPS,
};
use super::aos_space::{features, Proj, D};
use super::linalg::{ridge_cholesky, EPS_PIVOT};
use super::spp_of;
use crate::shared::{
    AosPush, AOS_BIAS_TEST, AOS_FEATNOISE, AOS_IDENTITY, AOS_IDENTITY_FLOOR, AOS_OUTLIER_W,
    AOS_RESIDUAL, AOS_SANDWICH,
};

pub use crate::shared::{
    AOS_DEBUG_NAMES as DEBUG_NAMES, AOS_MAX_COLS as MAX_COLS, AOS_OUTPUTS as OUTPUTS,
};

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
    /// The features' variances (of the mean), in the order of `feats`
    /// (AOS-FEATNOISE).
    pub fvar: [&'a [f32]; 8],
}

/// The [`OUTPUTS`] values of pixel `c` with projection `proj`.
pub fn fit_pixel(push: &AosPush, inp: &FitInputs, c: usize, proj: &Proj) -> [f64; OUTPUTS] {
    let (w, h) = (push.width as usize, push.height as usize);
    let mut o = [0.0; OUTPUTS];
    if spp_of(inp.spp[c]) < 1.0 {
        for ch in 0..3 {
            let plane = inp.color[ch];
            o[ch] =
                super::valid_mean_3x3(w, h, c, |q| spp_of(inp.spp[q]) >= 1.0, |q| plane[q] as f64)
                    .max(0.0);
        }
        return o;
    }
    let vbar = |q: usize| inp.vbar[q] as f64;
    let col = |ch: usize, q: usize| inp.color[ch][q] as f64;
    let black = |q: usize| all_black(vbar(q), [0, 1, 2].map(|ch| col(ch, q)));
    // AOS-FALLBACK: the input, error vbar_c.
    for ch in 0..3 {
        o[ch] = col(ch, c).max(0.0);
    }
    o[3] = vbar(c);
    o[13] = vbar(c);
    o[5] = proj.k as f64;
    let k = proj.k;
    if k == 0 {
        return o;
    }
    let r = push.radius as usize;
    let (cx, cy) = (c % w, c / w);
    let xc = features(w, &inp.feats, c);
    let bw = r.max(1) as f64;
    // The one window pass: valid pixels in raster order, the raw extended
    // rows [1, Δz_j^v (v = 1..5, j < k), R, G, B], and three Gram matrices:
    // N (weight K), B (K²) and G (K² vbar).
    let pr = 1 + P_STAR * k;
    let pe = pr + 3;
    let mut nr = vec![0.0; pe * pe];
    let mut br = vec![0.0; pr * pr];
    let mut gr = vec![0.0; pr * pr];
    let mut xr = vec![0.0; pe];
    let (mut lnsum, mut lnk) = (0.0, 0.0);
    for qy in cy.saturating_sub(r)..(cy + r + 1).min(h) {
        for qx in cx.saturating_sub(r)..(cx + r + 1).min(w) {
            let q = qy * w + qx;
            if spp_of(inp.spp[q]) < 1.0 {
                continue;
            }
            let (dx, dy) = (qx as f64 - cx as f64, qy as f64 - cy as f64);
            let mut kw = (-(dx * dx + dy * dy) / (2.0 * bw * bw)).exp();
            if push.flags & AOS_OUTLIER_W != 0 {
                kw *= outlier_weight(vbar(q));
            }
            let dz = proj.dz(&features(w, &inp.feats, q), &xc);
            xr[0] = 1.0;
            for i in 1..pr {
                xr[i] = powi(dz[(i - 1) % k], (i - 1) / k + 1);
            }
            for ch in 0..3 {
                xr[pr + ch] = col(ch, q);
            }
            if !black(q) {
                lnsum += kw * residual_ln_term(vbar(q), spp_of(inp.spp[q]));
                lnk += kw;
            }
            let (k2, kv) = (kw * kw, kw * kw * vbar(q));
            for i in 0..pe {
                for j in 0..=i {
                    nr[i * pe + j] += kw * xr[i] * xr[j];
                    if i < pr {
                        br[i * pr + j] += k2 * xr[i] * xr[j];
                        gr[i * pr + j] += kv * xr[i] * xr[j];
                    }
                }
            }
        }
    }
    // AOS-SCALE from the raw diagonal; columns below RMS_EPS are dropped.
    let ksum = nr[0];
    let mut cols: Vec<(usize, usize, f64)> = vec![(0, 0, 1.0)];
    for i in 1..pr {
        let rms = (nr[i * pe + i] / ksum).sqrt();
        if rms >= RMS_EPS {
            cols.push(((i - 1) / k + 1, i, 1.0 / rms));
        }
    }
    let pc = cols.len();
    let p_of = |l: usize| cols.iter().filter(|c| c.0 <= l).count();
    let sym = |m: &[f64], stride: usize, a: usize, b: usize| {
        if a >= b {
            m[a * stride + b]
        } else {
            m[b * stride + a]
        }
    };
    let compact = |m: &[f64], stride: usize| -> Vec<f64> {
        let mut out = vec![0.0; pc * pc];
        for (i, ci) in cols.iter().enumerate() {
            for (j, cj) in cols.iter().enumerate() {
                out[i * pc + j] = sym(m, stride, ci.1, cj.1) * ci.2 * cj.2;
            }
        }
        out
    };
    let n = compact(&nr, pe);
    let bm = compact(&br, pr);
    let gm = compact(&gr, pr);
    let rhs: [Vec<f64>; 3] = std::array::from_fn(|ch| {
        cols.iter()
            .map(|c| nr[(pr + ch) * pe + c.1] * c.2)
            .collect()
    });
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
    // σ*² = u*ᵀ G u*; per order u_lᵀ B u_l (the paper's [A⁻¹BA⁻¹]_00),
    // u_lᵀ G u_l (sandwich) and q_lᵀ G q_l (the bias variance): the sums
    // Σ K²(a·x_i)²(vbar_i) as quadratic forms.
    let qf = |m: &[f64], a: &[f64]| -> f64 {
        let mut s = 0.0;
        for (i, ai) in a.iter().enumerate() {
            for (j, aj) in a.iter().enumerate() {
                s += ai * m[i * pc + j] * aj;
            }
        }
        s
    };
    let pad = |u: &[f64]| -> Vec<f64> {
        let mut v = u.to_vec();
        v.resize(pc, 0.0);
        v
    };
    let sigma2 = qf(&gm, &u_star);
    let mut sq = [0.0; 2];
    let mut sw = [0.0; 2];
    let mut bv = [0.0; 2];
    for o_i in 0..2 {
        let u = pad(&us[o_i]);
        sq[o_i] = qf(&bm, &u);
        sw[o_i] = qf(&gm, &u);
        bv[o_i] = qf(&gm, &qs[o_i]);
    }
    let v_c = residual_centre_var(vbar(c), lnsum, lnk, spp_of(inp.spp[c]));
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
        let mut bias2 = counted * counted;
        if push.flags & AOS_RESIDUAL != 0 {
            let fit: f64 = us[o_i].iter().zip(&grey).map(|(u, y)| u * y).sum();
            let res = fit - (col(0, c) + col(1, c) + col(2, c)) / 3.0;
            let kc = if push.flags & AOS_OUTLIER_W != 0 {
                outlier_weight(vbar(c))
            } else {
                1.0
            };
            let lc = kc * us[o_i][0];
            let res_var = sw[o_i] - lc * lc * vbar(c) + (lc - 1.0) * (lc - 1.0) * v_c;
            bias2 = bias2.max(residual_bias2(res, res_var, spp_of(inp.spp[c])));
        }
        let mse = var + bias2;
        o[6 + 2 * o_i] = b;
        o[7 + 2 * o_i] = var;
        o[11 + o_i] = bv[o_i].sqrt();
        if best.map_or(true, |(_, m)| mse < m) {
            best = Some((o_i, mse));
        }
    }
    o[10] = sigma2;
    let (o_i, mse) = best.expect("two orders");
    if push.flags & AOS_IDENTITY != 0 {
        // AOS-IDENTITY-FLOOR.
        let v = if push.flags & AOS_IDENTITY_FLOOR != 0 {
            super::aos::identity_floor(
                (w, h),
                c,
                vbar(c),
                spp_of(inp.spp[c]),
                |q| spp_of(inp.spp[q]) >= 1.0 && !black(q),
                |q| inp.vbar[q] * spp_of(inp.spp[q]) as f32,
            )
        } else {
            vbar(c)
        };
        if v < mse {
            o[3] = v;
            o[13] = v;
            return o;
        }
    }
    for ch in 0..3 {
        o[ch] = us[o_i]
            .iter()
            .zip(&rhs[ch])
            .map(|(u, y)| u * y)
            .sum::<f64>()
            .max(0.0);
    }
    o[3] = mse;
    o[13] = mse;
    if push.flags & AOS_FEATNOISE != 0 {
        // AOS-FEATNOISE: g_j = Σ_m β_(1,m) s_(1,m) P[m][j].
        let beta_l = solve(ps[o_i], &grey);
        let mut g = [0.0; D];
        for (col, b) in cols.iter().zip(&beta_l) {
            if col.0 == 1 {
                let m = col.1 - 1;
                for (gj, p) in g.iter_mut().zip(&proj.p[m]) {
                    *gj += b * col.2 * p;
                }
            }
        }
        let sd = |j: usize| {
            if j < 2 {
                0.0
            } else {
                (inp.fvar[j - 2][c] as f64).max(0.0).sqrt()
            }
        };
        let s: f64 = (0..D).map(|j| g[j].abs() * sd(j)).sum();
        o[3] += s * s;
    }
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
