//! `sample_scan`: the down-sweep of the sampling allocation's prefix sum
//! and the final integer counts (spec §9.2 ROUNDING steps 2–3). Each
//! workgroup scans one block of [`BLOCK`](super::sample_reduce::BLOCK)
//! elements in a fixed order and adds the block's offset from the level
//! above. Integer arithmetic only: bit-identical to the twin
//! `reference::sample_scan`.

use super::sample_reduce::{with_grid, FLOPS_PER_ELEMENT};
use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SampleTreePush;

/// Declaration of `spirv/sample_scan.comp`: its bindings in binding order and
/// the size of [`SampleTreePush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "sample_scan",
    bindings: &[read("r"), read("spp"), write("tree"), write("counts")],
    push_size: std::mem::size_of::<SampleTreePush>() as u32,
};

pub use crate::shared::{
    SCAN_INNER as MODE_INNER, SCAN_LEAF as MODE_LEAF, SCAN_NO_LEVEL as NO_LEVEL,
};

/// Records one level of the down-sweep (see [`SampleTreePush`] for the
/// fields; the grid fields are filled here). `counts` is the u32 output
/// plane (written by the leaf mode only). Integer kernel: always the f32
/// variant.
pub fn record(
    batch: &mut Batch,
    push: SampleTreePush,
    r: BufferSlice,
    spp: BufferSlice,
    tree: BufferSlice,
    counts: BufferSlice,
) -> Result<()> {
    let push = with_grid(push);
    batch.dispatch(
        &DECL,
        Precision::F32,
        &[r, spp, tree, counts],
        bytemuck::bytes_of(&push),
        push.width,
        push.height,
        FLOPS_PER_ELEMENT,
    )
}
