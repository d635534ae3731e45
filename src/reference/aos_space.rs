//! Scalar twin of `spirv/aos_space.comp`: AOS's per-pixel TSVD local space
//! (spec §5.3 step 1, §0.6) over the 10 features of §5.1, stored as the
//! projection `Δz = P (x − x_c)` that `aos_fit` applies to every window
//! pixel.
//!
//! The GPU always uses D = 10: without a visibility layer the host binds a
//! zero plane, a constant component that §0.6 step 1 normalises to 0. It
//! adds a zero row and column to the covariances, so the rank and the local
//! coordinates equal the D = 9 space of [`super::aos`] (up to round-off and
//! the singular vectors' signs, which no fitted value depends on).

use super::spp_of;
use super::tsvd::{gather_window, local_space, projection, Projection};
use crate::shared::AosPush;

pub use crate::shared::{AOS_D as D, AOS_SPACE as SPACE};

/// A pixel's local space as the projection `Δz = P (x − x_c)` (§0.6).
pub type Proj = Projection<D>;

impl Projection<D> {
    /// Reads pixel `i`'s projection from a scratch of [`SPACE`] f32 each.
    pub fn read(scratch: &[f32], i: usize) -> Proj {
        let s = &scratch[i * SPACE..(i + 1) * SPACE];
        let mut p = [[0.0; D]; D];
        for (m, row) in p.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = s[m * D + j] as f64;
            }
        }
        Proj {
            k: s[D * D] as usize,
            p,
        }
    }
}

/// Raw features of pixel `q` (§5.1). `feats` = depth, albedo rgb, normal
/// xyz, visibility.
pub fn features(width: usize, feats: &[&[f32]; 8], q: usize) -> [f64; D] {
    let mut x = [0.0; D];
    x[0] = (q % width) as f64;
    x[1] = (q / width) as f64;
    for j in 0..8 {
        x[2 + j] = feats[j][q] as f64;
    }
    x
}

/// The local space of pixel `(cx, cy)` over `Ω_c(push.radius)`: valid
/// pixels, features with variances `vars` (0 for the coordinates).
pub fn space_pixel(
    push: &AosPush,
    feats: &[&[f32]; 8],
    vars: &[&[f32]; 8],
    spp: &[f32],
    cx: usize,
    cy: usize,
) -> Proj {
    let (w, h) = (push.width as usize, push.height as usize);
    if spp_of(spp[cy * w + cx]) < 1.0 {
        return Proj {
            k: 0,
            p: [[0.0; D]; D],
        };
    }
    let win = gather_window(w, h, cx, cy, push.radius as usize, D, |px, py, x, e2| {
        let q = py * w + px;
        x.copy_from_slice(&features(w, feats, q));
        e2[0] = 0.0;
        e2[1] = 0.0;
        for j in 0..8 {
            e2[2 + j] = vars[j][q] as f64;
        }
        spp_of(spp[q]) >= 1.0
    });
    projection(&local_space(&win.x, &win.e2, D))
}

/// The scratch of rows `push.base_row ..` (to the image's end): [`SPACE`]
/// f32 per pixel, as the kernel writes it.
pub fn aos_space(push: &AosPush, feats: &[&[f32]; 8], vars: &[&[f32]; 8], spp: &[f32]) -> Vec<f32> {
    let (w, h) = (push.width as usize, push.height as usize);
    let y0 = push.base_row as usize;
    let mut out = vec![0.0f32; (h - y0) * w * SPACE];
    let spaces = super::par_map((h - y0) * w, |i| {
        space_pixel(push, feats, vars, spp, i % w, y0 + i / w)
    });
    for (i, s) in spaces.iter().enumerate() {
        let o = &mut out[i * SPACE..(i + 1) * SPACE];
        for m in 0..D {
            for j in 0..D {
                o[m * D + j] = s.p[m][j] as f32;
            }
        }
        o[D * D] = s.k as f32;
    }
    out
}
