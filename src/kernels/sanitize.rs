//! `sanitize`, `sanitize_low_spp`, `estimate_variance`: input sanitation of one
//! scalar channel (spec §0.4). Three kernels with one binding layout and one
//! push-constant struct, one per stage, run in that order by
//! [`crate::methods::prepare`]:
//!
//! - `sanitize` (stage 0, steps 1–2): non-finite values, variance clamp;
//! - `sanitize_low_spp` (stage 1, step 3): variance of pixels with spp < 2
//!   (host file [`super::sanitize_low_spp`]);
//! - `estimate_variance` (stage 2, step 4): the variance layer is missing
//!   (host file [`super::estimate_variance`]).
//!
//! They are separate pipelines because, on lavapipe, a kernel that merely
//! contains the 49-value medians of stages 1–2 runs every invocation much
//! slower, even where that path is not taken (SANITIZE's record).
//! Twin: `reference::sanitize`.

use crate::error::Result;
use crate::gpu::reflect::{read, write, BindingDecl};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SanitizePush;

/// The binding layout all three stages share.
pub const BINDINGS: &[BindingDecl] = &[
    read("value_in"),
    read("var_in"),
    read("spp"),
    write("value_out"),
    write("var_out"),
    write("counters").sized_by_record(),
];

/// Declaration of `spirv/sanitize.comp`: its bindings in binding order and the
/// size of [`SanitizePush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "sanitize",
    bindings: BINDINGS,
    push_size: std::mem::size_of::<SanitizePush>() as u32,
};

/// Cost per pixel by stage: a 3x3 median; a 5x5 median (rarely the MAD
/// fallback); a 7x7 window of 3x3 residuals and two 49-value medians.
pub fn flops_per_pixel(stage: u32) -> f64 {
    match stage {
        0 => 40.0,
        1 => 120.0,
        _ => 3000.0,
    }
}

/// The kernel of a stage.
pub fn decl(stage: u32) -> &'static KernelDecl {
    match stage {
        0 => &DECL,
        1 => &super::sanitize_low_spp::DECL,
        _ => &super::estimate_variance::DECL,
    }
}

/// Counters written by the kernels (u32 each, in this order).
pub const COUNTERS: [&str; 4] = [
    "non-finite values repaired",
    "negative or non-finite variances set to 0",
    "variances of spp<2 pixels taken from neighbours",
    "variances estimated from the image",
];

/// Records one stage (`push.stage`) over one channel: `planes` = value_in,
/// var_in, spp, value_out, var_out. `var_in` is ignored by stage 0 when
/// `push.has_var` is 0 (bind any plane); `counters` holds 4 u32 and is added
/// to (repairs outside the margins of `push.skip_lo`/`skip_hi`).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: SanitizePush,
    planes: [BufferSlice; 5],
    counters: BufferSlice,
) -> Result<()> {
    let grid = (push.width, flops_per_pixel(push.stage));
    record_grid(
        batch,
        decl(push.stage),
        precision,
        push,
        planes,
        counters,
        grid,
    )
}

/// Dispatches a kernel with the sanitation layout over `grid_width`
/// invocations per row of `push.height` rows, each costing `flops`
/// (`sanitize_quads` runs a quarter as many, each on four pixels).
pub(super) fn record_grid(
    batch: &mut Batch,
    decl: &KernelDecl,
    precision: Precision,
    push: SanitizePush,
    planes: [BufferSlice; 5],
    counters: BufferSlice,
    (grid_width, flops): (u32, f64),
) -> Result<()> {
    let [value_in, var_in, spp, value_out, var_out] = planes;
    // Four u32 counters (the shaders use up to the fourth).
    decl.require(5, &counters, 16)?;
    batch.dispatch(
        decl,
        precision,
        &[value_in, var_in, spp, value_out, var_out, counters],
        bytemuck::bytes_of(&push),
        grid_width,
        push.height,
        flops,
    )
}
