//! `gbf_prepare`: G-buffer prefilter step 1 (spec §6) — the position
//! covariance smoothed with `G_1.5` (the column pass over
//! [`super::gauss_rows`]' row sums of the six entries), regularised (S-PSD)
//! and inverted: `S̃⁻¹` per pixel, which `gbf_sure` and `gbf_filter` read
//! for every neighbour. Twin: `reference::gbf_prepare`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::GbfPush;

/// Declaration of `spirv/gbf_prepare.comp`: its bindings in binding order and
/// the size of [`GbfPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "gbf_prepare",
    bindings: &[
        read("rows_xx"),
        read("rows_xy"),
        read("rows_xz"),
        read("rows_yy"),
        read("rows_yz"),
        read("rows_zz"),
        read("rows_weight"),
        read("position_x"),
        read("position_y"),
        read("position_z"),
        write("inv_xx"),
        write("inv_xy"),
        write("inv_xz"),
        write("inv_yy"),
        write("inv_yz"),
        write("inv_zz"),
    ],
    push_size: std::mem::size_of::<GbfPush>() as u32,
};

/// Pixels of a column one invocation prepares (`GP_ROWS` in the shader).
pub const ROWS_PER_INVOCATION: u32 = 8;

/// Per pixel: 11 rows × (weight step, 7 FMAs) and one 3×3 inverse.
pub fn flops_per_pixel() -> f64 {
    11.0 * 16.0 + 60.0
}

/// Records `S̃⁻¹` over a `width × height` image (with its row pass);
/// `scratch` (7 planes) holds the row sums.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    cov: [BufferSlice; 6],
    pos: [BufferSlice; 3],
    spp: BufferSlice,
    scratch: [BufferSlice; 7],
    inv: [BufferSlice; 6],
) -> Result<()> {
    let sigma = crate::shared::GBF_SMOOTH_SIGMA;
    super::gauss_rows::record(
        batch,
        precision,
        (width, height),
        (0, height),
        sigma,
        super::gauss_smooth::radius(sigma),
        &cov,
        spp,
        &scratch[..6],
        scratch[6],
    )?;
    let push = GbfPush {
        width,
        height,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(16);
    b.extend_from_slice(&scratch);
    b.extend_from_slice(&pos);
    b.extend_from_slice(&inv);
    // One invocation per ROWS_PER_INVOCATION pixels of a column (register
    // blocking: the shader's GP_ROWS); the grid's rows are blocks of rows.
    let grid_rows = height.div_ceil(ROWS_PER_INVOCATION);
    batch.dispatch_rows(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        ((0, grid_rows), grid_rows),
        flops_per_pixel() * ROWS_PER_INVOCATION as f64,
    )
}
