//! `lp_temporal`: one frame of spec §10.1's LP temporal filter — the 7×7
//! reprojection search on the world position (SEARCH-7), RESET, the shift
//! of the time origin (TIME-ORIGIN) and the recursive least-squares update
//! with forgetting factor `λ` (from TEMPORAL-PRIOR's reset, with the slope
//! held at 0). Twin: `reference::lp_temporal`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{TemporalPush, TEMPORAL_MOTION, TEMPORAL_SEARCH, TEMPORAL_STATE};

/// A temporal kernel's declaration: the filter's inputs (bindings 0–16,
/// [`TemporalIn`], the previous state and TEMPORAL-MOTION's offsets), then
/// `$rest`.
macro_rules! temporal_decl {
    ($name:expr, $($rest:expr),* $(,)?) => {
        KernelDecl {
            name: $name,
            bindings: &[
                read("yr"), read("yg"), read("yb"),
                read("px"), read("py"), read("pz"),
                read("vx"), read("vy"), read("vz"),
                read("depth"), read("spp"),
                read("er"), read("eg"), read("eb"),
                read("prev").planes(crate::shared::TEMPORAL_STATE as u32),
                read("mx").sized_by_record(), read("my").sized_by_record(),
                $($rest),*
            ],
            push_size: std::mem::size_of::<crate::shared::TemporalPush>() as u32,
        }
    };
}
pub(crate) use temporal_decl;

/// Declaration of `spirv/lp_temporal.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = temporal_decl!(
    "lp_temporal",
    write("next").planes(TEMPORAL_STATE as u32),
    write("out_r"),
    write("out_g"),
    write("out_b"),
    write("source"),
);

/// Per pixel: the window's centre (4), per candidate of the 7×7 window the
/// shift (5), the two distances (3 + 3 multiply-adds and subtractions, 12) and the cost (3);
/// the update (about 20) and the stores; where the window moved,
/// TEMPORAL-MISREG's gradient (about 20) and TEMPORAL-SUBPIXEL's
/// resampling (the neighbours' distances 24, the derivatives and the
/// offset 30, the interpolation 36), counted as if everywhere; where it did
/// not, TEMPORAL-RIM's 3×3 range and brightest pixel (9 × 9) and its test
/// (10, and the history bound 3), counted as if everywhere too.
pub const FLOPS_PER_PIXEL: f64 = {
    let side = (2 * TEMPORAL_SEARCH + 1) as f64;
    4.0 + side * side * (5.0 + 12.0 + 3.0) + 20.0 + 20.0 + 90.0 + 94.0
};

/// What one frame of the filter reads: the spatial reconstruction, the
/// position (X, Y, Z) and depth planes, and the sample counts.
#[derive(Copy, Clone, Debug)]
pub struct TemporalIn {
    /// The spatially filtered colour R, G, B.
    pub color: [BufferSlice; 3],
    /// The `position` layer.
    pub position: [BufferSlice; 3],
    /// The `position_variance` layer.
    pub position_variance: [BufferSlice; 3],
    /// The `depth` layer.
    pub depth: BufferSlice,
    /// The sample counts.
    pub spp: BufferSlice,
    /// The method's error estimate of `color` (TEMPORAL-INFLATE).
    pub error: [BufferSlice; 3],
}

/// What it writes: the next state (read as `prev` by the next frame once
/// copied there), the output colour and the debug plane `source`.
#[derive(Copy, Clone, Debug)]
pub struct TemporalOut {
    /// The state after this frame ([`TEMPORAL_STATE`] planes).
    pub next: BufferSlice,
    /// The filtered colour R, G, B.
    pub color: [BufferSlice; 3],
    /// The reprojection's offset, or reset or pass-through
    /// ([`crate::shared::TEMPORAL_SOURCE_RESET`]).
    pub source: BufferSlice,
}

/// Planes in a [`TemporalIn`] ([`TemporalIn::planes`]).
pub const INPUT_PLANES: usize = 14;

impl TemporalIn {
    /// The planes in binding order (bindings 0–13): colour, position,
    /// position variance (3 each), depth, samples, error (3).
    pub fn planes(&self) -> Vec<BufferSlice> {
        let mut v: Vec<BufferSlice> = self.color.to_vec();
        v.extend(self.position);
        v.extend(self.position_variance);
        v.extend([self.depth, self.spp]);
        v.extend(self.error);
        v
    }

    /// The inputs whose [`planes`](Self::planes) are `plane(0..14)`.
    pub fn from_planes(plane: impl Fn(usize) -> BufferSlice) -> TemporalIn {
        let three = |k: usize| [plane(k), plane(k + 1), plane(k + 2)];
        TemporalIn {
            color: three(0),
            position: three(3),
            position_variance: three(6),
            depth: plane(9),
            spp: plane(10),
            error: three(11),
        }
    }

    /// The bindings 0–16 of the temporal kernel `decl`: these planes,
    /// `prev` and the motion offsets `motion` (X, Y per pixel; read only
    /// where `push` has [`TEMPORAL_MOTION`]).
    pub(crate) fn with_prev(
        &self,
        decl: &KernelDecl,
        push: &TemporalPush,
        prev: BufferSlice,
        motion: [BufferSlice; 2],
    ) -> Result<Vec<BufferSlice>> {
        if push.flags & TEMPORAL_MOTION != 0 {
            let bytes = 4 * push.width as u64 * push.height as u64;
            decl.require(15, &motion[0], bytes)?;
            decl.require(16, &motion[1], bytes)?;
        }
        let mut v = self.planes();
        v.push(prev);
        v.extend(motion);
        Ok(v)
    }
}

/// Records one frame over the push's image from the state planes `prev`,
/// with TEMPORAL-MOTION's offsets `motion` where `push` has
/// [`TEMPORAL_MOTION`].
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &TemporalPush,
    inp: &TemporalIn,
    prev: BufferSlice,
    motion: [BufferSlice; 2],
    out: &TemporalOut,
) -> Result<()> {
    let rest = [
        out.next,
        out.color[0],
        out.color[1],
        out.color[2],
        out.source,
    ];
    let groups: [&[BufferSlice]; 2] = [&inp.with_prev(&DECL, push, prev, motion)?, &rest];
    super::dispatch_image(batch, &DECL, precision, push, &groups, FLOPS_PER_PIXEL)
}
