//! `peak_fma`: the device's arithmetic peak for `mcdenoise bench` (issue
//! #13). Every invocation runs `push.iterations` rounds of eight independent
//! `real4` FMAs and stores one value. Twin: `reference::peak_fma`.

use crate::error::Result;
use crate::gpu::reflect::write;
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::PeakPush;

/// Declaration of `spirv/peak_fma.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "peak_fma",
    bindings: &[write("out")],
    push_size: std::mem::size_of::<PeakPush>() as u32,
};

/// Flops of one invocation: 8 chains × 4 lanes × 2 (an FMA is a multiply and
/// an add) per round, plus the setup and the final sum (~40).
pub fn flops_per_invocation(iterations: u32) -> f64 {
    64.0 * iterations as f64 + 40.0
}

/// Records `peak_fma` over `push.width × push.height` invocations writing
/// `out` (one f32 each).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &PeakPush,
    out: BufferSlice,
) -> Result<()> {
    batch.dispatch(
        &DECL,
        precision,
        &[out],
        bytemuck::bytes_of(push),
        push.width,
        push.height,
        flops_per_invocation(push.iterations),
    )
}
