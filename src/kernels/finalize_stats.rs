//! `finalize_stats`: accumulation sums of one scalar channel → mean and
//! variance of the mean. Twin: `reference::finalize_stats`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::FinalizePush;

/// Declaration of `spirv/finalize_stats.comp`: its bindings in binding order
/// and the size of [`FinalizePush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "finalize_stats",
    bindings: &[
        read("sum"),
        read("sumsq"),
        read("count"),
        write("mean"),
        write("var"),
    ],
    push_size: std::mem::size_of::<FinalizePush>() as u32,
};

/// Estimated floating-point operations per pixel (for band splitting).
pub const FLOPS_PER_PIXEL: f64 = 10.0;

/// Records one channel's finalize over a `width` x `height` image; `origin`
/// is what the channel's samples were accumulated relative to. Every
/// slice holds one plane of `width * height` f32 values.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    sum: BufferSlice,
    sumsq: BufferSlice,
    count: BufferSlice,
    mean: BufferSlice,
    var: BufferSlice,
    origin: f32,
) -> Result<()> {
    let push = FinalizePush {
        width,
        height,
        origin,
        ..Default::default()
    };
    batch.dispatch(
        &DECL,
        precision,
        &[sum, sumsq, count, mean, var],
        bytemuck::bytes_of(&push),
        width,
        height,
        FLOPS_PER_PIXEL,
    )
}
