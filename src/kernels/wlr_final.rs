//! `wlr_final`: WLR steps 9–10 (spec §2.3) per pixel — TSVD and `b_j`
//! recomputed exactly as in `wlr_fit` (same GLSL), the final local linear fit
//! at `h = hbar_c`, output clamped `>= 0`, and `MSE_c` from the model stored by
//! `wlr_fit`. Twin: [`crate::reference::wlr_final`].
//!
//! Outputs (bindings 24..28): R, G, B; `mse`; `flags` as a float: `wlr_fit`'s
//! flags | bit 1 FEW in the final fit | bit 0 SOLVE-FAIL (output `y_c`,
//! `mse = vbar_c`) | bit 5 invalid pixel (`spp < 1`: mean colour of its valid
//! 3×3 neighbours clamped `>= 0`, `mse = 0`).

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::WlrPush;

/// Declaration of `spirv/wlr_final.comp`: its bindings in binding order and the
/// size of [`WlrPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "wlr_final",
    bindings: &[
        read("normal_x"),
        read("normal_y"),
        read("normal_z"),
        read("depth"),
        read("albedo_r"),
        read("albedo_g"),
        read("albedo_b"),
        read("var_normal_x"),
        read("var_normal_y"),
        read("var_normal_z"),
        read("var_depth"),
        read("var_albedo_r"),
        read("var_albedo_g"),
        read("var_albedo_b"),
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("vbar"),
        read("spp"),
        read("hbar"),
        read("lambda1"),
        read("kappa0"),
        read("kappa1"),
        read("kflags"),
        write("out_r"),
        write("out_g"),
        write("out_b"),
        write("mse"),
        write("flags"),
    ],
    push_size: std::mem::size_of::<WlrPush>() as u32,
};

/// Names of the 5 output maps, in binding order.
pub const OUTPUTS: [&str; 5] = ["out_r", "out_g", "out_b", "mse", "flags"];

/// Per pixel: `(2R+1)²` neighbours × (TSVD: two passes; curvature pass; two
/// final-fit passes) plus the Jacobi and Cholesky solves.
pub fn flops_per_pixel(radius: u32) -> f64 {
    let n = ((2 * radius + 1) * (2 * radius + 1)) as f64;
    let tsvd = 2.0 * 81.0 * 2.0 + 40.0;
    let proj = 3.0 * 2.0 * 81.0;
    let curv = 15.0 * 32.0 + 30.0 * 2.0;
    let fit = (6.0 * 32.0 + 30.0) + (30.0 + 40.0);
    n * (tsvd + proj + curv + fit) + 2.0 * 10.0 * 81.0 * 9.0 * 4.0 + 2.0 * 19.0f64.powi(3)
}

/// Records `wlr_final` over a `width × height` image. Inputs as
/// [`super::wlr_fit::record`], plus `hbar = G_1(h_opt)` (`gauss_smooth` with
/// σ = 1) and `fit` = the `λ1`, `κ0`, `κ1`, `kflags` maps of `wlr_fit` (same
/// `radius` and `options`). `out` = the 5 maps of [`OUTPUTS`].
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    radius: u32,
    options: u32,
    features: [BufferSlice; 7],
    variances: [BufferSlice; 7],
    color: [BufferSlice; 3],
    vbar: BufferSlice,
    spp: BufferSlice,
    hbar: BufferSlice,
    fit: [BufferSlice; 4],
    out: [BufferSlice; 5],
) -> Result<()> {
    let push = WlrPush {
        width,
        height,
        radius,
        options,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(29);
    b.extend_from_slice(&features);
    b.extend_from_slice(&variances);
    b.extend_from_slice(&color);
    b.push(vbar);
    b.push(spp);
    b.push(hbar);
    b.extend_from_slice(&fit);
    b.extend_from_slice(&out);
    batch.dispatch(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        height,
        flops_per_pixel(radius),
    )
}
