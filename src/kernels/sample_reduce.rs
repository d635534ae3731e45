//! `sample_reduce`: one level of the fixed-order reduction tree of the
//! sampling allocation (spec §9.1 sanitise, §9.2 ROUNDING). Each workgroup
//! reduces a block of [`BLOCK`] consecutive elements of a level into one
//! u64 entry of the tree buffer. Integer arithmetic only, so the result is
//! bit-identical to the twin `reference::sample_reduce`.
//! The levels are planned by [`crate::methods::sampling::TreeLayout`].

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SampleTreePush;

/// Declaration of `spirv/sample_reduce.comp`: its bindings in binding order and
/// the size of [`SampleTreePush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "sample_reduce",
    bindings: &[
        read("r").sized_by_record(),
        read("spp").sized_by_record(),
        write("tree").sized_by_record(),
    ],
    push_size: std::mem::size_of::<SampleTreePush>() as u32,
};

/// Elements per workgroup (= per tree block): the 8×8 workgroup, one
/// element per invocation. Mirrors `SAMPLE_BLOCK` in `spirv/lib/sampling.glsl`.
pub const BLOCK: u32 = 64;

pub use crate::shared::{
    REDUCE_LEAF_MAX as MODE_LEAF_MAX, REDUCE_LEAF_Q as MODE_LEAF_Q, REDUCE_LEAF_U as MODE_LEAF_U,
    REDUCE_MAX as MODE_MAX, REDUCE_SUM as MODE_SUM,
};

/// A few integer operations per element and six shared-memory steps.
pub const FLOPS_PER_ELEMENT: f64 = 16.0;

/// Largest number of workgroups per grid row (below Vulkan's guaranteed
/// `maxComputeWorkGroupCount[0]` of 65535).
pub const MAX_GROUPS_X: u32 = 4096;

/// The dispatch grid of a level of `n` elements: `(groups_x, width, height)`
/// in invocations, `ceil(n / BLOCK)` workgroups laid out row by row.
pub fn grid(n: u32) -> (u32, u32, u32) {
    let groups = n.div_ceil(BLOCK).max(1);
    let gx = groups.min(MAX_GROUPS_X);
    let gy = groups.div_ceil(gx);
    (gx, 8 * gx, 8 * gy)
}

/// Fills the grid fields of `push` (`width`, `height`, `groups_x`) from `push.n`.
pub fn with_grid(mut push: SampleTreePush) -> SampleTreePush {
    let (gx, w, h) = grid(push.n);
    push.groups_x = gx;
    push.width = w;
    push.height = h;
    push.row0 = 0;
    push
}

/// Records one level: `push.mode`, `n`, `src_off`, `dst_off` (and for the
/// leaf modes `max_off`, `s_off`) as in [`SampleTreePush`]; the grid fields
/// are filled here. `r` is the f32 priority map (read as bits), `spp` the
/// sample counts, `tree` the u64 tree buffer. Integer kernel: always the
/// f32 variant.
pub fn record(
    batch: &mut Batch,
    push: SampleTreePush,
    r: BufferSlice,
    spp: BufferSlice,
    tree: BufferSlice,
) -> Result<()> {
    let push = with_grid(push);
    let (n, blocks) = (push.n as u64, push.n.div_ceil(BLOCK) as u64);
    if n > 0 {
        // Leaf modes read r and spp; inner ones read the level below.
        let leaf = matches!(push.mode, MODE_LEAF_MAX | MODE_LEAF_Q | MODE_LEAF_U);
        let words = if leaf { n } else { 0 };
        DECL.require(0, &r, 4 * words)?;
        DECL.require(1, &spp, 4 * words)?;
        let mut entries = push.dst_off as u64 + blocks;
        match push.mode {
            MODE_MAX | MODE_SUM => entries = entries.max(push.src_off as u64 + n),
            MODE_LEAF_Q => entries = entries.max(push.max_off as u64 + 1),
            MODE_LEAF_U => entries = entries.max(push.max_off.max(push.s_off) as u64 + 1),
            _ => {}
        }
        DECL.require(2, &tree, 8 * entries)?;
    }
    batch.dispatch(
        &DECL,
        Precision::F32,
        &[r, spp, tree],
        bytemuck::bytes_of(&push),
        push.width,
        push.height,
        FLOPS_PER_ELEMENT,
    )
}
