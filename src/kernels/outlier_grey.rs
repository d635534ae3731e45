//! `outlier_grey`: the first pass of the outlier stage (spec §4.4 step 1):
//! per pixel, the order-preserving key of grey rounded to f32 (0 where the
//! pixel is invalid), so that the window kernels after it
//! ([`super::outlier_rows`], [`super::outlier_detect`],
//! [`super::outlier_median`]) load one plane per neighbour and decode grey
//! from it exactly. Twin: `reference::outlier_grey`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_grey.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_grey",
    bindings: &[
        read("cr"),
        read("cg"),
        read("cb"),
        read("spp"),
        write("keys"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Per pixel: two adds and a division (counted as 3), the validity test and
/// the key's bit operations (counted as 2).
pub fn flops_per_pixel() -> f64 {
    5.0
}

/// Records the keys of grey (u32 per pixel) into `keys`.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    color: [BufferSlice; 3],
    spp: BufferSlice,
    keys: BufferSlice,
) -> Result<()> {
    super::dispatch_image(
        batch,
        &DECL,
        precision,
        push,
        &[&color, &[spp, keys]],
        flops_per_pixel(),
    )
}
