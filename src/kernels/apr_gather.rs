//! `apr_gather`: APR's blend (spec §4.3, Eq. 6) for every pixel and channel:
//! the `K_h`-weighted mean of the accepting sparse blocks' `x_iᵀβ`, `ξ̂` and
//! `tr H`, or the pixel's extra block. Writes `ŷ_t`, `σ̂_t²` (6 planes)
//! before the last stage and colour, error, dimension and extra mask
//! ([`OUTPUTS`]) at the last, `push.stride` f32 values apart in one binding.
//! Twin: `reference::apr_gather`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{AprPush, APR_EXTRA_PLANES, APR_OUTPUTS, APR_STAGE_OUTPUTS, APR_STATE};
pub use crate::shared::{
    APR_EXTRA_PLANES as EXTRA_PLANES, APR_OUTPUTS as OUTPUTS, APR_STAGE_OUTPUTS as STAGE_OUTPUTS,
};

/// Declaration of `spirv/apr_gather.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "apr_gather",
    bindings: &[
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("var_r"),
        read("var_g"),
        read("var_b"),
        read("features_a").planes(4),
        read("features_b").planes(4),
        read("spp"),
        read("state").sized_by_record(),
        read("extra").sized_by_record(),
        write("dst").sized_by_record(),
        read("spp_total").sized_by_record(),
    ],
    push_size: std::mem::size_of::<AprPush>() as u32,
};

/// Per pixel and channel: up to 4 blocks (9 on the grid lines), each a
/// design row and two 18-term dot products.
pub const FLOPS_PER_PIXEL: f64 = 3.0 * 4.0 * 120.0;

/// Records the gather of one stage (`push.last`).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &AprPush,
    color: [BufferSlice; 3],
    var: [BufferSlice; 3],
    feats: &[BufferSlice; 2],
    (spp, sppt): (BufferSlice, BufferSlice),
    state: BufferSlice,
    extra: BufferSlice,
    dst: BufferSlice,
) -> Result<()> {
    DECL.require(12, &sppt, 4 * super::spp_total::WORDS as u64)?;
    let (w, h) = (push.width as usize, push.height as usize);
    let (gw, gh) = crate::shared::apr_grid(w, h);
    let (pixels, stride) = ((w * h) as u64, push.stride as u64);
    // The three channels' block states, extra planes and the outputs.
    DECL.require(9, &state, 4 * (3 * APR_STATE * gw * gh) as u64)?;
    let extra_planes = 3 * APR_EXTRA_PLANES as u64 - 1;
    DECL.require(10, &extra, 4 * (extra_planes * stride + pixels))?;
    let outputs = if push.last != 0 {
        APR_OUTPUTS
    } else {
        APR_STAGE_OUTPUTS
    } as u64;
    DECL.require(11, &dst, 4 * ((outputs - 1) * stride + pixels))?;
    let groups: [&[BufferSlice]; 4] = [&color, &var, feats, &[spp, state, extra, dst, sppt]];
    let flops = FLOPS_PER_PIXEL;
    super::dispatch_image(batch, &DECL, precision, push, &groups, flops)
}
