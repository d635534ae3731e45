//! `outlier_weights`: the redistribution weights `ρ_o = e_o / Σ_{Ω_o(43)} ŷ`
//! (or the DARK-WINDOW share) at pixels with an excess (spec §4.4 step 4).
//! Twin: [`crate::reference::outlier_weights`].

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_weights.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_weights",
    bindings: &[
        read("er"),
        read("eg"),
        read("eb"),
        read("sr"),
        read("sg"),
        read("sb"),
        read("cnt"),
        write("rho_r"),
        write("rho_g"),
        write("rho_b"),
        write("add_r"),
        write("add_g"),
        write("add_b"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Per pixel: the excess test, and at detected pixels `2R+1` rows × 4 adds.
pub fn flops_per_pixel(radius: u32) -> f64 {
    3.0 + super::outlier_median::DETECTED_FRACTION * (2.0 * radius as f64 + 1.0) * 4.0
}

/// Records the weights: `sums` are `box_rows` of ŷ per channel, `count` of the
/// valid count; `out` = ρ R, G, B, add R, G, B.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    excess: [BufferSlice; 3],
    sums: [BufferSlice; 3],
    count: BufferSlice,
    out: [BufferSlice; 6],
) -> Result<()> {
    super::dispatch_outlier(
        batch,
        &DECL,
        precision,
        push,
        &[&excess, &sums, &[count], &out],
        flops_per_pixel(push.radius),
    )
}
