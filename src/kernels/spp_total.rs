//! `spp_total`: the image's sample total, `Σ ⌊16 n_i + ½⌋` over the valid
//! pixels as two 32-bit words and their number (APR-COUNT-CAP).
//! Twin: `reference::spp_total`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SppTotalPush;

/// Declaration of `spirv/spp_total.comp`: its bindings in binding order and
/// the size of [`SppTotalPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "spp_total",
    bindings: &[read("spp"), write("total").sized_by_record()],
    push_size: std::mem::size_of::<SppTotalPush>() as u32,
};

/// Words of the total: low and high word of the sum, the count.
pub const WORDS: usize = 3;

/// A load, a multiply and a round per pixel; the tree's adds.
pub const FLOPS_PER_PIXEL: f64 = 4.0;

/// Records the total of a `width × height` image's `spp` plane into
/// `total` ([`WORDS`] u32), which the caller has zeroed.
pub fn record(
    batch: &mut Batch,
    width: u32,
    height: u32,
    spp: BufferSlice,
    total: BufferSlice,
) -> Result<()> {
    DECL.require(1, &total, 4 * WORDS as u64)?;
    let push = SppTotalPush {
        width,
        height,
        ..Default::default()
    };
    batch.dispatch(
        &DECL,
        Precision::F32,
        &[spp, total],
        bytemuck::bytes_of(&push),
        width,
        height,
        FLOPS_PER_PIXEL,
    )
}
