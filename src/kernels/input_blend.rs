//! `input_blend`: one channel of a reconstruction blended with
//! the input it was made from, by inverse error (INPUT-BLEND). Twin:
//! `reference::input_blend`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::BlendPush;

/// Declaration of `spirv/input_blend.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "input_blend",
    bindings: &[
        read("f"),
        read("e"),
        read("y"),
        read("v"),
        read("spp"),
        write("fout"),
        write("eout"),
    ],
    push_size: std::mem::size_of::<BlendPush>() as u32,
};

/// Per pixel of one channel: the window's trimmed mean variance (a test,
/// the largest values kept in order and a running mean, about 21 per pixel
/// of the `(2r + 1)²` window, and the kept values' last pass, about 40,
/// BLEND-TRIM), the residual's three running means (about 16 per pixel of
/// the `(2s + 1)²` window, BLEND-RESIDUAL) and the blend (about 14).
pub fn flops_per_pixel(radius: u32, residual_radius: u32) -> f64 {
    let side = 2.0 * radius as f64 + 1.0;
    let rs = residual_radius as f64;
    let residual = if residual_radius > 0 {
        16.0 * (2.0 * rs + 1.0) * (2.0 * rs + 1.0)
    } else {
        0.0
    };
    21.0 * side * side + residual + 54.0
}

/// One channel's planes.
#[derive(Copy, Clone, Debug)]
pub struct Channel {
    /// The reconstruction.
    pub color: BufferSlice,
    /// Its error estimate.
    pub error: BufferSlice,
    /// The input's mean.
    pub input: BufferSlice,
    /// The input's variance of the mean.
    pub variance: BufferSlice,
    /// The blend (written).
    pub out_color: BufferSlice,
    /// The blend's error estimate (written).
    pub out_error: BufferSlice,
}

/// Records the blend of one channel over the push's image.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &BlendPush,
    ch: &Channel,
    spp: BufferSlice,
) -> Result<()> {
    let planes = [
        ch.color,
        ch.error,
        ch.input,
        ch.variance,
        spp,
        ch.out_color,
        ch.out_error,
    ];
    super::dispatch_image(
        batch,
        &DECL,
        precision,
        push,
        &[&planes],
        flops_per_pixel(push.radius, push.residual_radius),
    )
}
