//! `pyramid_merge`: the fine reconstruction takes its low band from the
//! coarse level's, as a ratio weighed by the two error estimates, and the
//! error estimate follows (PYRAMID-LOWBAND). Twin:
//! `reference::pyramid_merge`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::PyramidPush;

/// Declaration of `spirv/pyramid_merge.comp`; checked against the SPIR-V
/// by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "pyramid_merge",
    bindings: &[
        read("fr"),
        read("fg"),
        read("fb"),
        read("er"),
        read("eg"),
        read("eb"),
        read("fspp"),
        read("cr").sized_by_record(),
        read("cg").sized_by_record(),
        read("cb").sized_by_record(),
        read("cer").sized_by_record(),
        read("ceg").sized_by_record(),
        read("ceb").sized_by_record(),
        read("cspp").sized_by_record(),
        write("outr"),
        write("outg"),
        write("outb"),
        write("oer"),
        write("oeg"),
        write("oeb"),
    ],
    push_size: std::mem::size_of::<PyramidPush>() as u32,
};

/// Per fine pixel: four coarse pixels, each the means of its block's four
/// fine colours and errors (24 adds, 6 divisions) and four weighted sums of
/// three channels (24 multiply-adds, 48); the weights (10); per channel the
/// blend and the ratio (about 12).
pub const FLOPS_PER_PIXEL: f64 = 4.0 * (24.0 + 6.0 + 48.0) + 10.0 + 3.0 * 12.0;

/// One level's reconstruction: colour, error estimate, sample counts.
#[derive(Copy, Clone, Debug)]
pub struct Level {
    /// The colour R, G, B.
    pub color: [BufferSlice; 3],
    /// The error estimate per channel.
    pub error: [BufferSlice; 3],
    /// The sample counts.
    pub spp: BufferSlice,
}

impl Level {
    fn bindings(&self) -> Vec<BufferSlice> {
        let mut v = self.color.to_vec();
        v.extend(self.error);
        v.push(self.spp);
        v
    }
}

/// Records the merge over the push's (fine) image into `color` and
/// `error`.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &PyramidPush,
    fine: &Level,
    coarse: &Level,
    color: [BufferSlice; 3],
    error: [BufferSlice; 3],
) -> Result<()> {
    let plane = 4 * push.other_width as u64 * push.other_height as u64;
    for (k, b) in coarse.bindings().iter().enumerate() {
        DECL.require(7 + k, b, plane)?;
    }
    let groups: [&[BufferSlice]; 4] = [&fine.bindings(), &coarse.bindings(), &color, &error];
    super::dispatch_image(batch, &DECL, precision, push, &groups, FLOPS_PER_PIXEL)
}
