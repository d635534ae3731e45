//! `sample_priority`: the per-pixel sampling priority `r_i` of spec §9.1
//! (relative MSE reduction, REL-CHANNELS), before MAP-SMOOTH and before the
//! global part of the sanitise rule (which [`super::sample_reduce`] applies).
//! Twin: `reference::sample_priority`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SamplePriorityPush;

/// Declaration of `spirv/sample_priority.comp`: its bindings in binding order
/// and the size of [`SamplePriorityPush`]; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "sample_priority",
    bindings: &[
        read("e_r"),
        read("e_g"),
        read("e_b"),
        read("d"),
        read("f_r"),
        read("f_g"),
        read("f_b"),
        read("spp"),
        write("r"),
    ],
    push_size: std::mem::size_of::<SamplePriorityPush>() as u32,
};

/// One `pow`, three divides and a few multiply-adds.
pub const FLOPS_PER_PIXEL: f64 = 30.0;

/// Records `out = r` over a `width × height` image from the error planes
/// `e` (one per channel; pass one plane three times for a shared estimate),
/// the local dimension `d`, the filtered colour `f` and the sample count
/// `spp`. `push.flags` selects ΔMSE input and the kflags decoding of `d`;
/// `push.eps` is `ε`. Invalid pixels and non-finite results get 0.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: SamplePriorityPush,
    e: [BufferSlice; 3],
    d: BufferSlice,
    f: [BufferSlice; 3],
    spp: BufferSlice,
    out: BufferSlice,
) -> Result<()> {
    batch.dispatch(
        &DECL,
        precision,
        &[e[0], e[1], e[2], d, f[0], f[1], f[2], spp, out],
        bytemuck::bytes_of(&push),
        push.width,
        push.height,
        FLOPS_PER_PIXEL,
    )
}
