//! `outlier_spread`: applies the redistribution (spec §4.4 step 4) in place to
//! the method's colour planes, from `box_rows` of the weights. Twin:
//! `reference::outlier_spread`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_spread.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_spread",
    bindings: &[
        read("rho_r"),
        read("rho_g"),
        read("rho_b"),
        read("add_r"),
        read("add_g"),
        read("add_b"),
        read("spp"),
        write("yr"),
        write("yg"),
        write("yb"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Rows per invocation (`SPAN` in the shader): one full column sum, then a
/// running sum, both exact pairs (TwoSum).
pub const SPAN: u32 = 32;

/// Per invocation: `2R+1` rows × 6 TwoSums (6 adds each) for the first
/// row, then per row 12 TwoSums and the update (≈ 15).
pub fn flops_per_invocation(radius: u32) -> f64 {
    (2.0 * radius as f64 + 1.0) * 36.0 + SPAN as f64 * (72.0 + 15.0)
}

/// Records `y ← max(0, y(1 + Σρ) + Σadd)`; `weights` are `box_rows` of ρ R,
/// G, B and add R, G, B.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    weights: [BufferSlice; 6],
    spp: BufferSlice,
    color: [BufferSlice; 3],
) -> Result<()> {
    let bindings = [&weights[..], &[spp], &color].concat();
    batch.dispatch(
        &DECL,
        precision,
        &bindings,
        bytemuck::bytes_of(push),
        push.width,
        push.height.div_ceil(SPAN),
        flops_per_invocation(push.radius),
    )
}
