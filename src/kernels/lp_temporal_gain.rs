//! `lp_temporal_gain`: what the LP temporal filter (§10.1) will make of
//! this frame at each pixel, read from the previous frame's state without
//! changing it, as a factor on the error estimate an adaptive pass's
//! sample map reads (TEMPORAL-MAP). Twin: `reference::lp_temporal_gain`.

use super::lp_temporal::TemporalIn;
use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{TemporalPush, TEMPORAL_STATE};

/// Declaration of `spirv/lp_temporal_gain.comp`; checked against the
/// SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "lp_temporal_gain",
    bindings: &[
        read("yr"),
        read("yg"),
        read("yb"),
        read("px"),
        read("py"),
        read("pz"),
        read("vx"),
        read("vy"),
        read("vz"),
        read("depth"),
        read("spp"),
        read("prev").planes(TEMPORAL_STATE as u32),
        read("er"),
        read("eg"),
        read("eb"),
        write("gr"),
        write("gg"),
        write("gb"),
    ],
    push_size: std::mem::size_of::<TemporalPush>() as u32,
};

/// The filter's search and update (`lp_temporal`'s) and three products.
pub const FLOPS_PER_PIXEL: f64 = super::lp_temporal::FLOPS_PER_PIXEL + 4.0;

/// Records the factor's product with `error` into `scaled` over the push's
/// image, from the filter's inputs and its state planes `prev`.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &TemporalPush,
    inp: &TemporalIn,
    prev: BufferSlice,
    error: [BufferSlice; 3],
    scaled: [BufferSlice; 3],
) -> Result<()> {
    let bindings: Vec<BufferSlice> = inp
        .color
        .iter()
        .chain(&inp.position)
        .chain(&inp.position_variance)
        .chain([&inp.depth, &inp.spp, &prev])
        .chain(&error)
        .chain(&scaled)
        .copied()
        .collect();
    batch.dispatch(
        &DECL,
        precision,
        &bindings,
        bytemuck::bytes_of(push),
        push.width,
        push.height,
        FLOPS_PER_PIXEL,
    )
}
