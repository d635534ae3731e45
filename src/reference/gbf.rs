//! Per-pixel routines of the G-buffer prefilter with world positions and
//! SURE (spec §6), shared by the twins [`gbf_sure`](super::gbf_sure) and
//! [`gbf_filter`](super::gbf_filter). GPU twin: `spirv/lib/gbf.glsl`.
//! Everything here is f64.
//!
//! Covariances are stored as the six unique entries `XX XY XZ YY YZ ZZ`
//! (the `position_covariance` layer order).

use super::spp_of;

/// Window radius: 7×7 (§6.2 step 4).
pub const RADIUS: usize = 3;
/// σ of the covariance smoothing and of the bandwidth smoothing (steps 1, 8).
pub use crate::shared::GBF_SMOOTH_SIGMA as SMOOTH_SIGMA;
/// Trial bandwidths (step 7).
pub const TRIAL_H: [f64; 6] = [0.0, 0.4, 0.8, 1.2, 1.6, 2.0];
/// H0: `hbar < H0` passes the pixel through (step 8).
pub const H0: f64 = 1e-3;

/// S-PSD (step 1): negative diagonal entries → 0, then
/// `S̃ = S̄ + ε I` with `ε = max(1e-3·tr(S̄)/3, 1e-10·(1 + |p|²))`.
pub fn regularise(sbar: [f64; 6], p: [f64; 3]) -> [f64; 6] {
    let mut s = sbar;
    for d in [0, 3, 5] {
        s[d] = s[d].max(0.0);
    }
    let tr = s[0] + s[3] + s[5];
    let p2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    let eps = (1e-3 * tr / 3.0).max(1e-10 * (1.0 + p2));
    for d in [0, 3, 5] {
        s[d] += eps;
    }
    s
}

/// The inverse a pixel's distances use.
///
/// Decision GBF-PD (ours): smoothing separately finalised entries can leave
/// `S̄` indefinite (pairwise Cauchy–Schwarz clamps do not make a 3×3 matrix
/// PSD) and `+ εI` does not always repair it: its inverse then has a
/// negative or infinite determinant and the filter weights became NaN. Such
/// a covariance says nothing usable about the pixel's footprint, so its
/// inverse is [`UNUSABLE`]·I: every distance through it is huge, the pixel
/// takes no neighbours and lends itself to none (it passes through).
pub fn regularised_inverse(sbar: [f64; 6], p: [f64; 3]) -> [f64; 6] {
    let s = regularise(sbar, p);
    if positive_definite(s) {
        inverse(s)
    } else {
        [UNUSABLE, 0.0, 0.0, UNUSABLE, 0.0, UNUSABLE]
    }
}

/// The inverse covariance of a pixel whose covariance is not positive
/// definite (GBF-PD): large enough that `exp(−d/2h²)` is 0 for any
/// neighbour, small enough that `d` stays finite in f32.
pub const UNUSABLE: f64 = 1e20;

/// Relative tolerance of [`positive_definite`]'s leading minors.
pub const PD_TOL: f64 = 1e-4;

/// Whether `[[a b c] [b d e] [c e f]]` is safely positive definite: every
/// leading minor above `PD_TOL` times the product of its diagonal.
pub fn positive_definite(s: [f64; 6]) -> bool {
    let [a, b, c, d, e, f] = s;
    let m2 = a * d - b * b;
    let det = a * (d * f - e * e) - b * (b * f - c * e) + c * (b * e - c * d);
    a > 0.0 && m2 > PD_TOL * a * d && det > PD_TOL * a * d * f
}

/// Inverse of a symmetric 3×3 matrix by adjugate / determinant.
pub fn inverse(s: [f64; 6]) -> [f64; 6] {
    let [a, b, c, d, e, f] = s; // [[a b c] [b d e] [c e f]]
    let ia = d * f - e * e;
    let ib = c * e - b * f;
    let ic = b * e - c * d;
    let id = a * f - c * c;
    let ie = b * c - a * e;
    let if_ = a * d - b * b;
    let det = a * ia + b * ib + c * ic;
    let r = 1.0 / det;
    [ia * r, ib * r, ic * r, id * r, ie * r, if_ * r]
}

/// `M v` for a symmetric `M` stored as six entries.
#[inline]
pub fn mul(m: [f64; 6], v: [f64; 3]) -> [f64; 3] {
    [
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[1] * v[0] + m[3] * v[1] + m[4] * v[2],
        m[2] * v[0] + m[4] * v[1] + m[5] * v[2],
    ]
}

#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The planes the prefilter reads.
#[derive(Copy, Clone, Debug)]
pub struct Planes<'a> {
    /// Image width in pixels; every plane has `width * height` values.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Position X, Y, Z.
    pub pos: [&'a [f32]; 3],
    /// Position variance (of the mean) X, Y, Z; only [`sure`] reads it.
    pub pos_var: Option<[&'a [f32]; 3]>,
    /// `S̃⁻¹`, the inverse of the regularised smoothed covariance (six
    /// entries), from [`gbf_prepare`](super::gbf_prepare).
    pub inv: [&'a [f32]; 6],
    /// Sample count `n` per pixel (f32); valid when `spp_of(n) >= 1` (§0.2).
    pub spp: &'a [f32],
}

impl Planes<'_> {
    /// Whether pixel index `q` is valid: `spp_of(spp[q]) >= 1` (§0.2).
    #[inline]
    pub fn valid(&self, q: usize) -> bool {
        spp_of(self.spp[q]) >= 1.0
    }

    /// World position `p_q` of pixel index `q`, in f64.
    #[inline]
    pub fn position(&self, q: usize) -> [f64; 3] {
        std::array::from_fn(|k| self.pos[k][q] as f64)
    }

    /// `S̃⁻¹` of pixel `q`.
    #[inline]
    pub fn inv_cov(&self, q: usize) -> [f64; 6] {
        std::array::from_fn(|k| self.inv[k][q] as f64)
    }
}

/// Steps 1 for pixel `(x, y)`: `S̄ = G_1.5(S)` over the valid pixels of the
/// clipped 11×11 window (each of the six entries; 0 if none is valid), then
/// S-PSD regularisation with the pixel's position and the inverse.
pub fn prepare_pixel(
    cov: [&[f32]; 6],
    pos: [&[f32]; 3],
    spp: &[f32],
    width: usize,
    height: usize,
    x: usize,
    y: usize,
) -> [f64; 6] {
    let sigma = SMOOTH_SIGMA as f64;
    let r = (3.0 * sigma).ceil() as usize;
    let mut num = [0.0; 6];
    let mut den = 0.0;
    for qy in y.saturating_sub(r)..(y + r + 1).min(height) {
        for qx in x.saturating_sub(r)..(x + r + 1).min(width) {
            let q = qy * width + qx;
            if spp_of(spp[q]) < 1.0 {
                continue;
            }
            let (dx, dy) = (qx as f64 - x as f64, qy as f64 - y as f64);
            let g = (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp();
            for k in 0..6 {
                num[k] += g * cov[k][q] as f64;
            }
            den += g;
        }
    }
    let sbar = num.map(|v| if den > 0.0 { v / den } else { 0.0 });
    let q = y * width + x;
    regularised_inverse(sbar, std::array::from_fn(|k| pos[k][q] as f64))
}

/// One neighbour of the window: index, `Δ = p_i − p_c`, `M_i Δ` and `d_i`.
#[derive(Clone, Debug)]
pub struct Neighbour {
    /// Pixel index `i` of the neighbour (`y * width + x`).
    pub q: usize,
    /// `Δ_i = p_i − p_c`, world units.
    pub delta: [f64; 3],
    /// `M_i Δ_i` with `M_i = S̃_c⁻¹ + S̃_i⁻¹` (step 3), reused by the
    /// divergence (step 5).
    pub m_delta: [f64; 3],
    /// Distance `d_i = Δ_iᵀ M_i Δ_i` (step 3; `>= 0`, 0 at the centre).
    pub d: f64,
}

/// The valid pixels of the 7×7 window of `c` in raster order with their
/// distances (step 3); the centre has `Δ = 0`, `d = 0`.
pub fn neighbours(p: &Planes, cx: usize, cy: usize) -> Vec<Neighbour> {
    let c = cy * p.width + cx;
    let pc = p.position(c);
    let inv_c = p.inv_cov(c);
    let mut out = Vec::with_capacity(49);
    for qy in cy.saturating_sub(RADIUS)..(cy + RADIUS + 1).min(p.height) {
        for qx in cx.saturating_sub(RADIUS)..(cx + RADIUS + 1).min(p.width) {
            let q = qy * p.width + qx;
            if !p.valid(q) {
                continue;
            }
            if q == c {
                out.push(Neighbour {
                    q,
                    delta: [0.0; 3],
                    m_delta: [0.0; 3],
                    d: 0.0,
                });
                continue;
            }
            let pq = p.position(q);
            let delta = [pq[0] - pc[0], pq[1] - pc[1], pq[2] - pc[2]];
            let inv_q = p.inv_cov(q);
            let m: [f64; 6] = std::array::from_fn(|k| inv_c[k] + inv_q[k]);
            let m_delta = mul(m, delta);
            out.push(Neighbour {
                q,
                delta,
                m_delta,
                d: dot(delta, m_delta),
            });
        }
    }
    out
}

/// Weight of a neighbour at bandwidth `h > 0` (step 4; the centre, `d = 0`,
/// has 1).
#[inline]
pub fn weight(n: &Neighbour, h: f64) -> f64 {
    (-n.d / (2.0 * h * h)).exp()
}

/// `(p̂_c, div p̂_c)` at bandwidth `h > 0` (steps 4–5).
pub fn filter_position(p: &Planes, nb: &[Neighbour], h: f64) -> ([f64; 3], f64) {
    let mut w_sum = 0.0;
    let mut acc = [0.0; 3];
    for n in nb {
        let w = weight(n, h);
        let pq = p.position(n.q);
        w_sum += w;
        for k in 0..3 {
            acc[k] += w * pq[k];
        }
    }
    let phat = acc.map(|a| a / w_sum);
    let mut s = 0.0;
    for n in nb {
        let w = weight(n, h);
        let pq = p.position(n.q);
        s += w * dot(
            n.m_delta,
            [pq[0] - phat[0], pq[1] - phat[1], pq[2] - phat[2]],
        );
    }
    let div = 3.0 / w_sum + s / (w_sum * h * h);
    (phat, div)
}

/// `SURE(h)` for the six trial bandwidths (step 6) at the valid pixel `c`.
pub fn sure(p: &Planes, cx: usize, cy: usize) -> [f64; 6] {
    let c = cy * p.width + cx;
    let pv = p.pos_var.expect("gbf::sure needs the position variance");
    let vbar = (0..3).map(|k| pv[k][c] as f64).sum::<f64>() / 3.0;
    let pc = p.position(c);
    let nb = neighbours(p, cx, cy);
    let mut out = [vbar; 6];
    for (s, &h) in TRIAL_H.iter().enumerate().skip(1) {
        let (phat, div) = filter_position(p, &nb, h);
        let e2: f64 = (0..3).map(|k| (phat[k] - pc[k]).powi(2)).sum();
        out[s] = e2 / 3.0 - vbar + 2.0 * vbar / 3.0 * div;
    }
    out
}

/// Step 7: `h_opt` of a SURE curve (ties to the smaller h).
pub fn choose(sure: &[f64; 6]) -> f64 {
    let mut best = 0;
    for s in 1..6 {
        if sure[s] < sure[best] {
            best = s;
        }
    }
    TRIAL_H[best]
}

/// Step 9–10: the filtered value and its variance of each of `feat` (with
/// variances `var`) at the valid pixel `c` with bandwidth `hbar`; H0
/// passes through.
pub fn filter_features(
    p: &Planes,
    cx: usize,
    cy: usize,
    hbar: f64,
    feat: &[&[f32]],
    var: &[&[f32]],
) -> Vec<(f64, f64)> {
    let c = cy * p.width + cx;
    if hbar < H0 {
        return feat
            .iter()
            .zip(var)
            .map(|(f, v)| (f[c] as f64, v[c] as f64))
            .collect();
    }
    let nb = neighbours(p, cx, cy);
    let w: Vec<f64> = nb.iter().map(|n| weight(n, hbar)).collect();
    let w_sum: f64 = w.iter().sum();
    feat.iter()
        .zip(var)
        .map(|(f, v)| {
            let (mut g, mut gv) = (0.0, 0.0);
            for (n, &wi) in nb.iter().zip(&w) {
                let a = wi / w_sum;
                g += a * f[n.q] as f64;
                gv += a * a * v[n.q] as f64;
            }
            (g, gv)
        })
        .collect()
}
