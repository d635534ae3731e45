//! `apr_pack`: APR's features (normal xyz, albedo rgb, depth, visibility)
//! packed into two vec4 planes for [`super::apr_block`] and
//! [`super::apr_gather`] (APR-PACKED). Twin: `reference::apr_pack`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::AprPush;

/// Declaration of `spirv/apr_pack.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "apr_pack",
    bindings: &[
        read("normal_x"),
        read("normal_y"),
        read("normal_z"),
        read("albedo_r"),
        read("albedo_g"),
        read("albedo_b"),
        read("depth"),
        read("visibility"),
        write("features_a").planes(4),
        write("features_b").planes(4),
    ],
    push_size: std::mem::size_of::<AprPush>() as u32,
};

/// Per pixel: no arithmetic, 8 loads and 8 stores (counted as 1 so the band
/// estimate stays positive).
pub fn flops_per_pixel() -> f64 {
    1.0
}

/// Records the packing of the `push.width × push.height` image's `feats`
/// (visibility read only with `APR_VIS` in `push.flags`) into `out`: two
/// vec4 planes of `16 × width × height` bytes.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &AprPush,
    feats: &[BufferSlice; 8],
    out: [BufferSlice; 2],
) -> Result<()> {
    let groups: [&[BufferSlice]; 2] = [feats, &out];
    let flops = flops_per_pixel();
    super::dispatch_image(batch, &DECL, precision, push, &groups, flops)
}
