//! `temporal_motion`: one level of TEMPORAL-MOTION's coarse-to-fine search
//! for where each pixel's surface was in the previous frame, over pyramids
//! of both frames' world positions (`pyramid_pool`); its full-resolution
//! offsets (level 0) centre the LP temporal filter's 7×7 window
//! (`lp_temporal`). Twin:
//! `reference::temporal_motion`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::MotionPush;

/// Declaration of `spirv/temporal_motion.comp`; checked against the SPIR-V
/// by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "temporal_motion",
    bindings: &[
        read("cx"),
        read("cy"),
        read("cz"),
        read("cn"),
        read("qx"),
        read("qy"),
        read("qz"),
        read("qn"),
        read("ox_c").sized_by_record(),
        read("oy_c").sized_by_record(),
        write("ox"),
        write("oy"),
    ],
    push_size: std::mem::size_of::<MotionPush>() as u32,
};

/// Per pixel: the centre (3), then per candidate (the pixel, the centre
/// and the 5×5 window) the count test and the squared distance (3
/// subtractions, 3 multiply-adds) and the comparison.
pub const FLOPS_PER_PIXEL: f64 = 3.0 + 27.0 * (1.0 + 9.0 + 1.0);

/// One level's planes: positions X, Y, Z and counts.
pub type LevelPlanes = [BufferSlice; 4];

/// Records one level over the push's image: the search of this frame's
/// level `cur` in the previous frame's `prev`, centred on twice the
/// coarser level's offsets `coarse` where `push.coarse` is set (not read
/// otherwise), into the offsets `out` (X, Y).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &MotionPush,
    cur: &LevelPlanes,
    prev: &LevelPlanes,
    coarse: [BufferSlice; 2],
    out: [BufferSlice; 2],
) -> Result<()> {
    if push.coarse != 0 {
        let bytes = 4 * push.coarse_width as u64 * push.coarse_height as u64;
        DECL.require(8, &coarse[0], bytes)?;
        DECL.require(9, &coarse[1], bytes)?;
    }
    let groups: [&[BufferSlice]; 4] = [cur, prev, &coarse, &out];
    super::dispatch_image(batch, &DECL, precision, push, &groups, FLOPS_PER_PIXEL)
}
