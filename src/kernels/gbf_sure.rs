//! `gbf_sure`: G-buffer prefilter steps 2–7 (spec §6) — SURE over the six
//! trial bandwidths with the regularised smoothed covariances, and `h_opt`.
//! Twin: `reference::gbf_sure`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::GbfPush;

/// Declaration of `spirv/gbf_sure.comp`: its bindings in binding order and the
/// size of [`GbfPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "gbf_sure",
    bindings: &[
        read("position_x"),
        read("position_y"),
        read("position_z"),
        read("var_position_x"),
        read("var_position_y"),
        read("var_position_z"),
        read("inv_xx"),
        read("inv_xy"),
        read("inv_xz"),
        read("inv_yy"),
        read("inv_yz"),
        read("inv_zz"),
        read("spp"),
        write("h_opt"),
    ],
    push_size: std::mem::size_of::<GbfPush>() as u32,
};

/// Pixels of a row one invocation computes (`SURE_PX` in the shader).
pub const PIXELS_PER_INVOCATION: u32 = 2;

/// Per pixel, 49 neighbours × the work of one: the difference of the
/// positions (3), the sum of the two stored symmetric inverses (6), the
/// matrix-vector product (15) and the distance (5); the five weights (three
/// scaled `exp2`, two of the others by four squarings: 3 + 3 ×
/// [`EXP_FLOPS`](super::EXP_FLOPS) + 4); and per weight the sums W, Σ w Δ,
/// Σ w d and Σ w MΔ (1 + 6 + 2 + 6 = 15).
pub fn flops_per_pixel() -> f64 {
    49.0 * (3.0 + 6.0 + 15.0 + 5.0 + 3.0 + 3.0 * super::EXP_FLOPS + 4.0 + 5.0 * 15.0)
}

/// Records `h_opt` over a `width × height` image.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    pos: [BufferSlice; 3],
    pos_var: [BufferSlice; 3],
    inv: [BufferSlice; 6],
    spp: BufferSlice,
    h_opt: BufferSlice,
) -> Result<()> {
    let push = GbfPush {
        width,
        height,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(14);
    b.extend_from_slice(&pos);
    b.extend_from_slice(&pos_var);
    b.extend_from_slice(&inv);
    b.push(spp);
    b.push(h_opt);
    // One invocation per PIXELS_PER_INVOCATION pixels of a row (register
    // blocking: the shader's SURE_PX).
    batch.dispatch_rows(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width.div_ceil(PIXELS_PER_INVOCATION),
        ((0, height), height),
        flops_per_pixel() * PIXELS_PER_INVOCATION as f64,
    )
}
