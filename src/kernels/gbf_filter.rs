//! `gbf_filter`: G-buffer prefilter steps 9–10 (spec §6) — the seven
//! features [`super::gbf_pack`] packed, filtered with the 7×7 weights at
//! `hbar` in one pass, with propagated variances (GBF-VAR). Twin:
//! `reference::gbf_filter`.

use crate::error::{Error, Result};
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::GbfPush;

/// Declaration of `spirv/gbf_filter.comp`: its bindings in binding order and
/// the size of [`GbfPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "gbf_filter",
    bindings: &[
        read("position_x"),
        read("position_y"),
        read("position_z"),
        read("inv_xx"),
        read("inv_xy"),
        read("inv_xz"),
        read("inv_yy"),
        read("inv_yz"),
        read("inv_zz"),
        read("hbar"),
        read("features_a").sized_by_record(),
        read("features_b").sized_by_record(),
        read("variances_a").sized_by_record(),
        read("variances_b").sized_by_record(),
        write("out0"),
        write("out1"),
        write("out2"),
        write("out3"),
        write("out4"),
        write("out5"),
        write("out6"),
        write("var_out0"),
        write("var_out1"),
        write("var_out2"),
        write("var_out3"),
        write("var_out4"),
        write("var_out5"),
        write("var_out6"),
    ],
    push_size: std::mem::size_of::<GbfPush>() as u32,
};

/// Pixels of a row one invocation filters (`GBF_PX` in the shader).
pub const PIXELS_PER_INVOCATION: u32 = 8;

/// Rows one invocation filters (`GBF_ROWS` in the shader): a chunk's first
/// row must be a multiple of 8 of them (the workgroup's height in blocks).
pub const ROWS_PER_INVOCATION: u32 = 2;

/// Per pixel, 49 neighbours × the work of one: the distance as in
/// [`super::gbf_sure::flops_per_pixel`] (29), the weight (one multiply and
/// an `exp2`, [`EXP_FLOPS`](super::EXP_FLOPS)), and the sums W, Σ w g of
/// the seven features (14) and Σ w² var(g) of their variances (1 + 14).
pub fn flops_per_pixel() -> f64 {
    49.0 * (29.0 + 1.0 + super::EXP_FLOPS + 1.0 + 14.0 + 15.0)
}

/// Records the filtering of the image rows `rows` (`[first, end)`, `first`
/// and `end` multiples of 16, or `end` the image's height: the dispatch
/// covers whole workgroups of 16 rows) from the packed features (`packed` from
/// [`super::gbf_pack`]: ranges that start at image row `base` and cover the
/// rows `rows` ± 3) into `out` (7 features, then their 7 variances; full
/// planes). `second_below` is [`GbfPush::second_below`]: 0 for the spec's
/// pass; above 0 GBF-SECOND's second pass, which filters only the pixels
/// with fewer samples and leaves the variance planes of `out` unwritten.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    rows: (u32, u32),
    base: u32,
    pos: [BufferSlice; 3],
    inv: [BufferSlice; 6],
    hbar: BufferSlice,
    packed: [BufferSlice; 4],
    out: [BufferSlice; 14],
    second_below: f32,
) -> Result<()> {
    let push = GbfPush {
        width,
        height,
        base,
        second_below,
        ..Default::default()
    };
    let b: Vec<BufferSlice> = [&pos[..], &inv, &[hbar], &packed, &out].concat();
    // One invocation per ROWS_PER_INVOCATION x PIXELS_PER_INVOCATION pixels
    // (register blocking: the shader's GBF_ROWS x GBF_PX); the grid's rows
    // are blocks of rows.
    let r = ROWS_PER_INVOCATION;
    if rows.0 % (8 * r) != 0 || (rows.1 % (8 * r) != 0 && rows.1 != height) {
        return Err(Error::InvalidArgument(format!(
            "gbf_filter: rows {rows:?} must start and end at multiples of {} (or end at the \
             image's height)",
            8 * r
        )));
    }
    // The packed planes hold the rows from `base` (at most 3 above the
    // first filtered row) to 3 below the last (the 7×7 window).
    if base > rows.0.saturating_sub(3) {
        return Err(Error::InvalidArgument(format!(
            "gbf_filter: packed rows start at {base}, after row {} of the first window",
            rows.0.saturating_sub(3)
        )));
    }
    let packed_bytes = 16 * width as u64 * ((rows.1 + 3).min(height).saturating_sub(base)) as u64;
    for (k, p) in packed.iter().enumerate() {
        DECL.require(10 + k, p, packed_bytes)?;
    }
    let grid = (rows.0 / r, rows.1.div_ceil(r));
    batch.dispatch_rows(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width.div_ceil(PIXELS_PER_INVOCATION),
        (grid, grid.1 - grid.0),
        flops_per_pixel() * (PIXELS_PER_INVOCATION * r) as f64,
    )
}
