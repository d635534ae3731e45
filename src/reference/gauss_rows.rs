//! Scalar twin of `spirv/gauss_rows.comp`: the row pass of the separable
//! Gaussian map smoothing `G_σ` (spec §0.5).

use super::spp_of;
use crate::shared::SmoothPush;

/// The 1-D weight `exp(−d²/(2σ²))` of `G_σ` at offset `d` (1 for `σ <= 0`,
/// whose radius is 0).
pub fn weight(sigma: f64, d: f64) -> f64 {
    if sigma > 0.0 {
        (-d * d / (2.0 * sigma * sigma)).exp()
    } else {
        1.0
    }
}

/// For every pixel (`row0` ignored) and map: the sum over the valid pixels
/// `q` of its row with `|q.x − x| <= push.radius` (clipped) of
/// `weight(q.x − x) · map(q)` into `sums`, and of the weights into `den`.
pub fn gauss_rows(
    push: &SmoothPush,
    maps: &[&[f32]],
    spp: &[f32],
    sums: &mut [Vec<f32>],
    den: &mut [f32],
) {
    assert_eq!(maps.len(), sums.len(), "gauss_rows: one sum per map");
    let (w, h) = (push.width as usize, push.height as usize);
    let r = push.radius as usize;
    let sigma = push.sigma as f64;
    for y in 0..h {
        for x in 0..w {
            let mut num = vec![0.0f64; maps.len()];
            let mut d = 0.0;
            for qx in x.saturating_sub(r)..(x + r + 1).min(w) {
                let q = y * w + qx;
                if spp_of(spp[q]) < 1.0 {
                    continue;
                }
                let g = weight(sigma, qx as f64 - x as f64);
                for (n, m) in num.iter_mut().zip(maps) {
                    *n += g * m[q] as f64;
                }
                d += g;
            }
            for (s, n) in sums.iter_mut().zip(&num) {
                s[y * w + x] = *n as f32;
            }
            den[y * w + x] = d as f32;
        }
    }
}

/// The column pass at pixel `(x, y)` of a `w × h` image: for each plane, the
/// sum over the rows `|q.y − y| <= radius` (clipped) of its column of
/// `weight(q.y − y) · plane(x, q.y)`, in f64. Shared by the twins of
/// `gauss_smooth` (a map's row sums and their weights) and `gbf_prepare`
/// (six covariance entries and their weights).
pub fn column_sums<const N: usize>(
    (w, h): (usize, usize),
    radius: usize,
    sigma: f64,
    planes: [&[f32]; N],
    (x, y): (usize, usize),
) -> [f64; N] {
    let mut s = [0.0f64; N];
    for qy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
        let g = weight(sigma, qy as f64 - y as f64);
        for (acc, p) in s.iter_mut().zip(&planes) {
            *acc += g * p[qy * w + x] as f64;
        }
    }
    s
}
