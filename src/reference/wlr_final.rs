//! Scalar twin of `spirv/wlr_final.comp`: WLR steps 9–10 (spec §2.3) per
//! pixel — the final local linear fit at the smoothed bandwidth `hbar` and the
//! error estimate from the model `wlr_fit` stored. The per-pixel routines
//! live in [`super::wlr`].

use super::wlr::{final_pixel, invalid_fill, par_pixels, Planes, Stored, FLAG_INVALID};
use crate::shared::WlrPush;

/// Number of output planes (bindings 24..28): R, G, B, `mse`, `flags`.
pub const WLR_FINAL_OUTPUTS: usize = 5;

/// For every pixel of the image (`row0` ignored), on all cores. Inputs as the
/// kernel's bindings 0..23: the `wlr_fit` inputs, then `hbar = G_1(h_opt)`
/// and `fit` = `λ1`, `κ0`, `κ1`, `kflags` from `wlr_fit`. `out` =
/// [`WLR_FINAL_OUTPUTS`] full planes: the output colour (`>= 0`), the MSE
/// of step 10 (`>= 0`) and the flags of §2.5 as a float (`wlr_fit`'s flags |
/// bit 1 FEW in the final fit | bit 0 SOLVE-FAIL; bit 5 invalid pixel).
/// An invalid centre gets the mean colour of its valid 3x3 neighbours (§0.2,
/// clamped `>= 0`), `mse = 0`, flags = 32.
pub fn wlr_final(
    push: &WlrPush,
    feat: [&[f32]; 7],
    var: [&[f32]; 7],
    vis: Option<[&[f32]; 2]>,
    color: [&[f32]; 3],
    vbar: &[f32],
    spp: &[f32],
    hbar: &[f32],
    fit: [&[f32]; 4],
    out: &mut [Vec<f32>],
) {
    assert_eq!(out.len(), WLR_FINAL_OUTPUTS, "wlr_final: output planes");
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
    par_pixels::<WLR_FINAL_OUTPUTS>(w, h, out, |x, y| {
        let c = y * w + x;
        if !p.valid(c) {
            let m = invalid_fill(&p, x, y);
            return [
                m[0] as f32,
                m[1] as f32,
                m[2] as f32,
                0.0,
                FLAG_INVALID as f32,
            ];
        }
        let st = Stored {
            hbar: hbar[c] as f64,
            lambda1: fit[0][c] as f64,
            kappa0: fit[1][c] as f64,
            kappa1: fit[2][c] as f64,
            kflags: fit[3][c] as f64,
        };
        let f = final_pixel(&p, x, y, r, push.options, &st);
        [
            f.rgb[0] as f32,
            f.rgb[1] as f32,
            f.rgb[2] as f32,
            f.mse as f32,
            f.flags as f32,
        ]
    });
}
