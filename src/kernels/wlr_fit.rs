//! `wlr_fit`: WLR steps 1–7 (spec §2.3) per pixel — TSVD (§0.6), curvature
//! bandwidths `b_j`, the five trial fits, the parametric fits and `h_opt`.
//! The per-pixel routines live in `spirv/lib/wlr.glsl`, shared with
//! `wlr_final`. Twin: [`crate::reference::wlr_fit`].
//!
//! Outputs (bindings 19..26): `h_opt`; `λ1`, `κ0`, `κ1` of the model
//! `MSE(h) = (λ1 h²)² + (κ0 + κ1 h^{-k})/n_c` that `wlr_final` evaluates at
//! `hbar` (for `κ1 <= 0`, `k = 0` and SOLVE-FAIL of the curvature fit:
//! `λ1 = κ1 = 0`, `κ0 = n_c·MSE_fixed`); `kflags = k + 16·flags` (§2.5 bits
//! 0, 2, 3, 4); `b_1..b_3` (debug, 0 for `j >= k`). Invalid centre: all 0.
//! Binding 17, `state`: per centre with `k >= 1`, the local space and the
//! `b_j` that `wlr_final` reads back instead of recomputing them
//! ([`STATE_WORDS`] per pixel, in a ring of [`WlrPush::ring_rows`] rows).

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::WlrPush;

/// Declaration of `spirv/wlr_fit.comp`: its bindings in binding order and the
/// size of [`WlrPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "wlr_fit",
    bindings: &[
        read("features_a"),
        read("features_b"),
        read("variances_a"),
        read("variances_b"),
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("vbar"),
        read("spp"),
        write("h_opt"),
        write("lambda1"),
        write("kappa0"),
        write("kappa1"),
        write("kflags"),
        write("b1"),
        write("b2"),
        write("b3"),
        write("state"),
    ],
    push_size: std::mem::size_of::<WlrPush>() as u32,
};

/// Names of the 8 output maps, in binding order.
pub const OUTPUTS: [&str; 8] = [
    "h_opt", "lambda1", "kappa0", "kappa1", "kflags", "b1", "b2", "b3",
];

/// Words (of the kernel's precision, f32 or f64) of the centre state per
/// pixel: 23 `vec4` (`WLR_STATE_VEC4` in `spirv/lib/wlr.glsl`).
pub const STATE_WORDS: usize = 23 * 4;

/// Per pixel: `(2R+1)²` neighbours × (TSVD: one pass with two 9×9 Gram
/// updates, TSVD-ONE-PASS; curvature pass: projection + 15 4×4 outer products; two trial
/// passes: projection + 5 × (kernel + 6 outer products / 3 dots)) plus the
/// Jacobi and Cholesky solves.
pub fn flops_per_pixel(radius: u32) -> f64 {
    let n = ((2 * radius + 1) * (2 * radius + 1)) as f64;
    let tsvd = 2.0 * 81.0 * 2.0 + 40.0;
    let proj = 3.0 * 2.0 * 81.0;
    let curv = 15.0 * 32.0 + 30.0 * 2.0;
    let trials = 5.0 * (6.0 * 32.0 + 30.0) + 5.0 * (30.0 + 40.0);
    n * (tsvd + proj + curv + trials) + 2.0 * 10.0 * 81.0 * 9.0 * 4.0 + 6.0 * 19.0f64.powi(3)
}

/// Records `wlr_fit` over the rows `rows = [first, end)` (`first` a multiple
/// of 8) of a `width × height` image with window radius `radius` (5
/// intermediate, 9 final) and `options` ([`WlrPush::options`] bits).
/// `packed` = the features (normal xyz, depth, albedo rgb) and their
/// variances as `gbf_pack` packs them (4 vec4 planes); `color` = R, G, B;
/// `vbar` = mean colour variance; `out` = the 8 maps of
/// [`OUTPUTS`]; `state` = a ring of `ring_rows` rows of [`STATE_WORDS`]
/// per pixel, which must hold the rows `wlr_final` will read.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    rows: (u32, u32),
    (radius, options): (u32, u32),
    packed: [BufferSlice; 4],
    color: [BufferSlice; 3],
    vbar: BufferSlice,
    spp: BufferSlice,
    out: [BufferSlice; 8],
    (state, ring_rows): (BufferSlice, u32),
) -> Result<()> {
    let push = WlrPush {
        width,
        height,
        radius,
        options,
        ring_rows,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(18);
    b.extend_from_slice(&packed);
    b.extend_from_slice(&color);
    b.push(vbar);
    b.push(spp);
    b.extend_from_slice(&out);
    b.push(state);
    batch.dispatch_rows(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        (rows, height),
        flops_per_pixel(radius),
    )
}
