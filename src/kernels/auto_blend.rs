//! `auto_blend`: `--method auto`'s blend of its three members from their
//! smoothed maps (AUTO-BLEND): per member the larger of its own relative
//! error estimate and the three-cornered hat of the pairs' disagreements,
//! weights `1 /` that, the weighted mean of the colours and the combined
//! error estimate `(Σ w √(k E) / Σ w)²`. Twin: `reference::auto_blend`.

use super::auto_score::auto_decl;
use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{AUTO_MAPS, AUTO_MEMBERS};

/// Declaration of `spirv/auto_blend.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = auto_decl!(
    "auto_blend",
    read("score0"),
    read("score1"),
    read("score2"),
    read("dis01"),
    read("dis02"),
    read("dis12"),
    write("out_r"),
    write("out_g"),
    write("out_b"),
    write("err_r"),
    write("err_g"),
    write("err_b"),
);

/// Per pixel: per member the hat estimate, the maximum, the weight's and
/// the factor's divisions, three multiply-adds for the colour and three
/// square roots with their multiply-adds for the error; the normalisation.
pub const FLOPS_PER_PIXEL: f64 = 3.0 * (3.0 + 1.0 + 2.0 + 6.0 + 3.0 + 9.0) + 10.0;

/// Records the blend of the members with `colors` and `errors` from their
/// smoothed `maps` into `color` and `error` over a `width × height` image.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    size: (u32, u32),
    colors: [[BufferSlice; 3]; AUTO_MEMBERS],
    errors: [[BufferSlice; 3]; AUTO_MEMBERS],
    maps: [BufferSlice; AUTO_MAPS],
    color: [BufferSlice; 3],
    error: [BufferSlice; 3],
) -> Result<()> {
    let rest: [&[BufferSlice]; 3] = [&maps, &color, &error];
    super::auto_score::dispatch(
        batch,
        &DECL,
        precision,
        size,
        colors,
        errors,
        &rest,
        FLOPS_PER_PIXEL,
    )
}
