//! `gbf_filter`: G-buffer prefilter steps 9–10 (spec §6) — up to four
//! feature planes filtered with the 7×7 weights at `hbar`, with propagated
//! variances (GBF-VAR). Twin: [`crate::reference::gbf_filter`].

use crate::error::Result;
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
        read("spp"),
        read("hbar"),
        read("feature0"),
        read("feature1"),
        read("feature2"),
        read("feature3"),
        read("var_feature0"),
        read("var_feature1"),
        read("var_feature2"),
        read("var_feature3"),
        write("out0"),
        write("out1"),
        write("out2"),
        write("out3"),
        write("var_out0"),
        write("var_out1"),
        write("var_out2"),
        write("var_out3"),
    ],
    push_size: std::mem::size_of::<GbfPush>() as u32,
};

/// Per pixel: 49 neighbours × (distance with two stored inverses, one exp,
/// 4 + 4 accumulations).
pub fn flops_per_pixel() -> f64 {
    49.0 * (60.0 + 30.0 + 16.0)
}

/// Records the filtering of the first `count` (1..=4) of `feat` (and `var`);
/// unused slots must still be bound (any plane) and their outputs get 0.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    count: u32,
    pos: [BufferSlice; 3],
    inv: [BufferSlice; 6],
    spp: BufferSlice,
    hbar: BufferSlice,
    feat: [BufferSlice; 4],
    var: [BufferSlice; 4],
    out: [BufferSlice; 8],
) -> Result<()> {
    let push = GbfPush {
        width,
        height,
        count,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(27);
    b.extend_from_slice(&pos);
    b.extend_from_slice(&inv);
    b.push(spp);
    b.push(hbar);
    b.extend_from_slice(&feat);
    b.extend_from_slice(&var);
    b.extend_from_slice(&out);
    batch.dispatch(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        height,
        flops_per_pixel(),
    )
}
