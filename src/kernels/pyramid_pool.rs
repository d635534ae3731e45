//! `pyramid_pool`: one plane of the sanitised statistics pooled over 2×2
//! blocks into the pyramid's coarse level (PYRAMID-LOWBAND). Twin:
//! `reference::pyramid_pool`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::PyramidPush;

/// Declaration of `spirv/pyramid_pool.comp`; checked against the SPIR-V
/// by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "pyramid_pool",
    bindings: &[
        read("src").sized_by_record(),
        read("spp").sized_by_record(),
        write("dst"),
    ],
    push_size: std::mem::size_of::<PyramidPush>() as u32,
};

/// Per coarse pixel: four counts tested, four weighted sums (multiply-add,
/// and the weight's product), one division.
pub const FLOPS_PER_PIXEL: f64 = 4.0 * (1.0 + 1.0 + 3.0) + 2.0;

/// Records the pooling of the fine plane `src` (with the fine counts
/// `spp`) into the coarse plane `dst`, over the push's coarse image.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &PyramidPush,
    src: BufferSlice,
    spp: BufferSlice,
    dst: BufferSlice,
) -> Result<()> {
    let fine = 4 * push.other_width as u64 * push.other_height as u64;
    DECL.require(0, &src, fine)?;
    DECL.require(1, &spp, fine)?;
    let groups: [&[BufferSlice]; 1] = [&[src, spp, dst]];
    super::dispatch_image(batch, &DECL, precision, push, &groups, FLOPS_PER_PIXEL)
}
