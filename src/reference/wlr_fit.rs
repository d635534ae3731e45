//! Scalar twin of `spirv/wlr_fit.comp`: WLR steps 1–7 (spec §2.3) per pixel —
//! TSVD, curvature bandwidths `b_j`, the five trial fits, the parametric fits
//! and `h_opt`. The per-pixel routines live in [`super::wlr`].

use super::wlr::{fit_pixel, par_pixels, Planes};
use crate::shared::WlrPush;

/// Number of output planes (bindings 19..26): `h_opt`, `λ1`, `κ0`, `κ1`,
/// `kflags = k + 16·flags`, `b1`, `b2`, `b3`.
pub const WLR_FIT_OUTPUTS: usize = 8;

/// For every pixel of the `push.width × push.height` image (`row0` ignored:
/// all bands at once), on all cores. Inputs as the kernel's bindings 0..18:
/// `feat` = normal x,y,z, depth, albedo r,g,b; `var` their variances;
/// `color` R,G,B; `vbar`; `spp`; with `vis` (`wlr_fit_vis`, bindings 18,
/// 19) the prefiltered visibility and its variance as a tenth feature
/// (WLR-VIS). `out` = [`WLR_FIT_OUTPUTS`] full planes.
/// An invalid centre (`spp_of < 1`) gets 0 everywhere.
///
/// The stored MSE model is such that `MSE(h) = (λ1 h²)² + (κ0 + κ1 h^{-k})/n_c`
/// always holds (see [`super::wlr::HChoice`]); pass-through pixels (`k = 0`,
/// SOLVE-FAIL of the curvature fit) have `λ1 = κ1 = 0`, `κ0 = n_c·vbar_c`,
/// `h_opt = 0.2`.
pub fn wlr_fit(
    push: &WlrPush,
    feat: [&[f32]; 7],
    var: [&[f32]; 7],
    vis: Option<[&[f32]; 2]>,
    color: [&[f32]; 3],
    vbar: &[f32],
    spp: &[f32],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), WLR_FIT_OUTPUTS, "wlr_fit: output planes");
    let (w, h) = (push.width as usize, push.height as usize);
    let p = Planes {
        width: w,
        height: h,
        feat,
        var,
        color,
        vbar,
        spp,
        vis,
    };
    let r = push.radius as usize;
    par_pixels::<WLR_FIT_OUTPUTS>(w, h, out, |x, y| {
        if !p.valid(y * w + x) {
            return [0.0; WLR_FIT_OUTPUTS];
        }
        let f = fit_pixel(&p, x, y, r, push.options);
        [
            f.h_opt as f32,
            f.lambda1 as f32,
            f.kappa0 as f32,
            f.kappa1 as f32,
            f.kflags() as f32,
            f.b[0] as f32,
            f.b[1] as f32,
            f.b[2] as f32,
        ]
    });
}
