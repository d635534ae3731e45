//! `lp_temporal_gain`: what the LP temporal filter (§10.1) will make of
//! this frame at each pixel, read from the previous frame's state without
//! changing it, as a factor on the error estimate an adaptive pass's
//! sample map reads (TEMPORAL-MAP). Twin: `reference::lp_temporal_gain`.

use super::lp_temporal::{temporal_decl, TemporalIn};
use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::TemporalPush;

/// Declaration of `spirv/lp_temporal_gain.comp`; checked against the
/// SPIR-V by reflection.
pub const DECL: KernelDecl = temporal_decl!(
    "lp_temporal_gain",
    read("sr"),
    read("sg"),
    read("sb"),
    write("gr"),
    write("gg"),
    write("gb"),
);

/// The filter's search and update (`lp_temporal`'s) and three products.
pub const FLOPS_PER_PIXEL: f64 = super::lp_temporal::FLOPS_PER_PIXEL + 4.0;

/// Records the factor's product with `error` into `scaled` over the push's
/// image, from the filter's inputs, its state planes `prev` and
/// TEMPORAL-MOTION's offsets `motion` (as `lp_temporal::record`).
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &TemporalPush,
    inp: &TemporalIn,
    prev: BufferSlice,
    motion: [BufferSlice; 2],
    error: [BufferSlice; 3],
    scaled: [BufferSlice; 3],
) -> Result<()> {
    let groups: [&[BufferSlice]; 3] = [&inp.with_prev(&DECL, push, prev, motion)?, &error, &scaled];
    super::dispatch_image(batch, &DECL, precision, push, &groups, FLOPS_PER_PIXEL)
}
