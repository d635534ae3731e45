//! `auto_score`: one member's score map for `--method auto` (AUTO-BLEND),
//! its relative error estimate `Σ_c E_c / (f_c² + 0.01)`. Twin:
//! `reference::auto_score`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::AutoPush;

/// Declaration of `spirv/auto_score.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "auto_score",
    bindings: &[
        read("cr"),
        read("cg"),
        read("cb"),
        read("er"),
        read("eg"),
        read("eb"),
        write("score"),
    ],
    push_size: std::mem::size_of::<AutoPush>() as u32,
};

/// Per pixel: three channels, each a clamp, a multiply-add and a division,
/// summed.
pub const FLOPS_PER_PIXEL: f64 = 3.0 * 4.0 + 2.0;

/// Records the score of the member with `color` and `error` into `score`
/// over a `width × height` image.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    color: [BufferSlice; 3],
    error: [BufferSlice; 3],
    score: BufferSlice,
) -> Result<()> {
    let push = AutoPush {
        width,
        height,
        ..Default::default()
    };
    let bindings: Vec<BufferSlice> = color.iter().chain(&error).copied().chain([score]).collect();
    dispatch(batch, &DECL, precision, &push, &bindings, FLOPS_PER_PIXEL)
}

/// Dispatches one of `auto`'s kernels (`decl`) over `push`'s image with
/// `bindings` in order.
pub(crate) fn dispatch(
    batch: &mut Batch,
    decl: &KernelDecl,
    precision: Precision,
    push: &AutoPush,
    bindings: &[BufferSlice],
    flops_per_pixel: f64,
) -> Result<()> {
    batch.dispatch(
        decl,
        precision,
        bindings,
        bytemuck::bytes_of(push),
        push.width,
        push.height,
        flops_per_pixel,
    )
}
