//! `lp_smooth`: the LP temporal filter's two directions combined per pixel
//! and channel, a two-filter smoother (TEMPORAL-SMOOTH, SMOOTH-SHORT).
//! Twin: `reference::lp_smooth`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::TwoWayPush;

/// Declaration of `spirv/lp_smooth.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "lp_smooth",
    bindings: &[
        read("yr"),
        read("yg"),
        read("yb"),
        read("fr"),
        read("fg"),
        read("fb"),
        read("pf"),
        read("br"),
        read("bg"),
        read("bb"),
        read("pb"),
        write("out_r"),
        write("out_g"),
        write("out_b"),
    ],
    push_size: std::mem::size_of::<TwoWayPush>() as u32,
};

/// Per pixel: two reciprocals (2), the two tests and weights (4) and the
/// denominator (2), per channel two multiply-adds, a subtraction, a
/// division and the clamp (5).
pub const FLOPS_PER_PIXEL: f64 = 8.0 + 3.0 * 5.0;

/// One direction of the filter on a frame: its output colour and `P₀₀`
/// after its update (0 where it passed the pixel through).
#[derive(Copy, Clone, Debug)]
pub struct Direction {
    /// The filtered colour R, G, B.
    pub color: [BufferSlice; 3],
    /// `P₀₀` per pixel.
    pub p00: BufferSlice,
}

impl Direction {
    fn bindings(&self) -> [BufferSlice; 4] {
        [self.color[0], self.color[1], self.color[2], self.p00]
    }
}

/// Records the combination over the push's image of `forward` and
/// `backward` on a frame whose method output is `y` into `out`.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &TwoWayPush,
    y: [BufferSlice; 3],
    forward: &Direction,
    backward: &Direction,
    out: [BufferSlice; 3],
) -> Result<()> {
    let groups: [&[BufferSlice]; 4] = [&y, &forward.bindings(), &backward.bindings(), &out];
    super::dispatch_image(batch, &DECL, precision, push, &groups, FLOPS_PER_PIXEL)
}
