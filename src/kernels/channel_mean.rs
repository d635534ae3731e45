//! `channel_mean`: `out = (a + b + c)/3` per pixel — `vbar` from the three
//! colour variances (spec §0.1 GREY), or `grey` from the colour.
//! Twin: `reference::channel_mean`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::ChannelMeanPush;

/// Declaration of `spirv/channel_mean.comp`: its bindings in binding order and
/// the size of [`ChannelMeanPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "channel_mean",
    bindings: &[read("a"), read("b"), read("c"), write("out")],
    push_size: std::mem::size_of::<ChannelMeanPush>() as u32,
};

/// Three loads, two adds, one multiply.
pub const FLOPS_PER_PIXEL: f64 = 3.0;

/// Records `out = (inputs[0] + inputs[1] + inputs[2])/3` over a
/// `width × height` image.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    inputs: [BufferSlice; 3],
    out: BufferSlice,
) -> Result<()> {
    let push = ChannelMeanPush {
        width,
        height,
        ..Default::default()
    };
    batch.dispatch(
        &DECL,
        precision,
        &[inputs[0], inputs[1], inputs[2], out],
        bytemuck::bytes_of(&push),
        width,
        height,
        FLOPS_PER_PIXEL,
    )
}
