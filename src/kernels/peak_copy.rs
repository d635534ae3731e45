//! `peak_copy`: the device's memory bandwidth for `mcdenoise bench` (issue
//! #13): `dst[i] = src[i]`, one f32 per invocation. Twin:
//! `reference::peak_copy`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::PeakPush;

/// Declaration of `spirv/peak_copy.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "peak_copy",
    bindings: &[read("src"), write("dst")],
    push_size: std::mem::size_of::<PeakPush>() as u32,
};

/// Bytes that cross memory per word: one f32 read, one written.
pub const BYTES_PER_WORD: f64 = 8.0;

/// Records `dst = src` over `push.width × push.height` f32 words, one vec4
/// per invocation (`push.width` must be a multiple of 4; `iterations` is
/// unused).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &PeakPush,
    src: BufferSlice,
    dst: BufferSlice,
) -> Result<()> {
    if push.width % 4 != 0 {
        return Err(crate::error::Error::InvalidArgument(format!(
            "peak_copy: width {} is not a multiple of 4 words",
            push.width
        )));
    }
    // No arithmetic; 4 "flops" an invocation only size the bands (watchdog
    // split).
    batch.dispatch(
        &DECL,
        precision,
        &[src, dst],
        bytemuck::bytes_of(push),
        push.width / 4,
        push.height,
        4.0,
    )
}
