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
    bindings: &[
        read("r").sized_by_record(),
        read("spp").sized_by_record(),
        write("tree").sized_by_record(),
        write("counts").sized_by_record(),
    ],
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
    let (n, blocks) = (
        push.n as u64,
        push.n.div_ceil(super::sample_reduce::BLOCK) as u64,
    );
    if n > 0 {
        // The leaf mode reads r and spp and writes the counts; the inner
        // one scans a level of the tree.
        let leaf = push.mode == MODE_LEAF;
        let words = if leaf { n } else { 0 };
        DECL.require(0, &r, 4 * words)?;
        DECL.require(1, &spp, 4 * words)?;
        DECL.require(3, &counts, 4 * words)?;
        let mut entries = if leaf {
            push.max_off.max(push.s_off).max(push.u_off) as u64 + 1
        } else {
            push.src_off.max(push.dst_off) as u64 + n
        };
        if push.par_off != NO_LEVEL {
            entries = entries.max(push.par_off as u64 + blocks);
        }
        DECL.require(2, &tree, 8 * entries)?;
    }
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
