//! Scalar twin of `spirv/tsvd_debug.comp`: the TSVD debug outputs of spec §0.6
//! (`rank k`, `τ`, `‖E‖₂`, `σ_1..σ_9`) for the 9-D WLR feature set, per pixel.

use super::spp_of;
use super::tsvd::{gather_window, local_space};
use crate::shared::TsvdPush;

/// Feature dimension: `(px, py, nrm_x, nrm_y, nrm_z, dep, a_r, a_g, a_b)`
/// (spec §2.1), with variances `(0, 0, vn_x, vn_y, vn_z, vd, va_r, va_g, va_b)`.
pub const TSVD_DEBUG_D: usize = 9;

/// Number of output planes: rank (as float), τ, ‖E‖₂, σ_1..σ_9, and the rank
/// again (the kernel's rank as the methods compute it, which must be the
/// same) — bindings 15..27 of the kernel, in this order.
pub const TSVD_DEBUG_OUTPUTS: usize = 4 + TSVD_DEBUG_D;

/// For every pixel `c` of the `push.width × push.height` image (`row0` is
/// ignored: all bands at once), builds the TSVD local space (spec §0.6) of
/// `Ω_c(push.radius)` (clipped, valid pixels only, `spp_of >= 1`) and writes
/// `out[0] = k`, `out[1] = τ`, `out[2] = ‖E‖₂`, `out[3 + m] = σ_{m+1}`,
/// `out[12] = k`.
/// An invalid centre gets 0 in every output.
///
/// `feat` are the planes nx, ny, nz, depth, ar, ag, ab (kernel bindings 0..6),
/// `var` their variances in the same order (bindings 7..13), `spp` binding 14;
/// `out` holds [`TSVD_DEBUG_OUTPUTS`] full planes.
pub fn tsvd_debug(
    push: &TsvdPush,
    feat: [&[f32]; 7],
    var: [&[f32]; 7],
    spp: &[f32],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), TSVD_DEBUG_OUTPUTS, "tsvd_debug: output planes");
    let (w, h) = (push.width as usize, push.height as usize);
    let r = push.radius as usize;
    for cy in 0..h {
        for cx in 0..w {
            let c = cy * w + cx;
            if spp_of(spp[c]) < 1.0 {
                for plane in out.iter_mut() {
                    plane[c] = 0.0;
                }
                continue;
            }
            // §0.6: Ω_c(R), D = 9 raw features
            let win = gather_window(w, h, cx, cy, r, TSVD_DEBUG_D, |px, py, x, e2| {
                let q = py * w + px;
                x[0] = px as f64;
                x[1] = py as f64;
                e2[0] = 0.0;
                e2[1] = 0.0;
                for j in 0..7 {
                    x[2 + j] = feat[j][q] as f64;
                    e2[2 + j] = var[j][q] as f64;
                }
                spp_of(spp[q]) >= 1.0
            });
            let ls = local_space(&win.x, &win.e2, TSVD_DEBUG_D);
            out[0][c] = ls.k as f32;
            out[1][c] = ls.tau as f32;
            out[2][c] = ls.specnorm as f32;
            for m in 0..TSVD_DEBUG_D {
                out[3 + m][c] = ls.sigma[m] as f32;
            }
            out[3 + TSVD_DEBUG_D][c] = ls.k as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn planes(w: usize, h: usize, seed: u64) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
        let mut s = seed;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let feat = (0..7)
            .map(|j| {
                (0..w * h)
                    .map(|i| ((i % w) as f32 * 0.1 * (j + 1) as f32).sin() + 0.2 * next())
                    .collect()
            })
            .collect();
        let var = (0..7)
            .map(|_| (0..w * h).map(|_| 1e-3 * next()).collect())
            .collect();
        (feat, var)
    }

    #[test]
    fn outputs_are_consistent() {
        let (w, h) = (13, 11);
        let (feat, var) = planes(w, h, 0x5EED);
        let mut spp = vec![4.0f32; w * h];
        spp[5 * w + 6] = 0.0;
        spp[0] = f32::NAN;
        let mut out = vec![vec![-1.0f32; w * h]; TSVD_DEBUG_OUTPUTS];
        let push = TsvdPush {
            width: w as u32,
            height: h as u32,
            row0: 0,
            radius: 3,
        };
        let f: [&[f32]; 7] = std::array::from_fn(|j| feat[j].as_slice());
        let v: [&[f32]; 7] = std::array::from_fn(|j| var[j].as_slice());
        tsvd_debug(&push, f, v, &spp, &mut out);
        for c in 0..w * h {
            if c == 5 * w + 6 || c == 0 {
                assert!(out.iter().all(|p| p[c] == 0.0), "invalid centre {c}");
                continue;
            }
            let k = out[0][c];
            assert!(
                (2.0..=9.0).contains(&k) && k.fract() == 0.0,
                "rank {k} at {c}"
            );
            assert!(out[2][c] > 0.0);
            assert!((out[1][c] - 2.0 * out[2][c]).abs() <= 1e-6 * out[1][c]);
            for m in 0..8 {
                assert!(out[3 + m][c] >= out[4 + m][c]);
            }
            // every retained component beyond MINRANK is above τ
            for m in 2..k as usize {
                assert!(out[3 + m][c] > out[1][c]);
            }
        }
    }

    #[test]
    fn one_pixel_image_has_rank_zero() {
        let one = [0.5f32];
        let push = TsvdPush {
            width: 1,
            height: 1,
            row0: 0,
            radius: 5,
        };
        let mut out = vec![vec![-1.0f32; 1]; TSVD_DEBUG_OUTPUTS];
        tsvd_debug(&push, [&one; 7], [&one; 7], &[1.0], &mut out);
        assert!(out.iter().all(|p| p[0] == 0.0));
    }
}
