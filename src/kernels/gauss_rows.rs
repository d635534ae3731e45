//! `gauss_rows`: the row pass of the separable Gaussian map smoothing `G_σ`
//! (spec §0.5) for one map or six, with the row sums of the weights over
//! the valid pixels. Its column passes are `gauss_smooth` (one map) and
//! `gbf_prepare` (the six covariance entries). Twin:
//! `reference::gauss_rows`.

use crate::error::{Error, Result};
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SmoothPush;

/// Declaration of `spirv/gauss_rows.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "gauss_rows",
    bindings: &[
        read("m0"),
        read("m1"),
        read("m2"),
        read("m3"),
        read("m4"),
        read("m5"),
        read("spp"),
        write("s0"),
        write("s1"),
        write("s2"),
        write("s3"),
        write("s4"),
        write("s5"),
        write("den"),
    ],
    push_size: std::mem::size_of::<SmoothPush>() as u32,
};

/// Pixels of a row one invocation sums (`GR_PX` in the shader).
pub const PIXELS_PER_INVOCATION: u32 = 8;

/// Per pixel: `2r+1` taps × (validity, one FMA per map, weight step).
pub fn flops_per_pixel(radius: u32, maps: usize) -> f64 {
    (2.0 * radius as f64 + 1.0) * (4.0 + 2.0 * maps as f64)
}

/// Records the row sums of `maps` (1 or 6 planes) into `sums` (as many) and
/// of the weights into `den`, for `G_σ` with `radius` (`ceil(3σ)`, or 0 for
/// `σ <= 0`), over the rows `rows = [first, end)` of a `width × height`
/// image (`first` a multiple of 8; `(0, height)` for all): a row's sums need
/// no other row.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    rows: (u32, u32),
    sigma: f32,
    radius: u32,
    maps: &[BufferSlice],
    spp: BufferSlice,
    sums: &[BufferSlice],
    den: BufferSlice,
) -> Result<()> {
    if !(maps.len() == 1 || maps.len() == 6) || sums.len() != maps.len() {
        return Err(Error::InvalidArgument(format!(
            "gauss_rows smooths 1 or 6 maps into as many sums, got {} and {}",
            maps.len(),
            sums.len()
        )));
    }
    let push = SmoothPush {
        width,
        height,
        radius,
        sigma,
        count: maps.len() as u32,
        ..Default::default()
    };
    // With one map the other slots are bound to it and never accessed.
    let mut b: Vec<BufferSlice> = (0..6).map(|k| maps[k % maps.len()]).collect();
    b.push(spp);
    b.extend((0..6).map(|k| sums[k % sums.len()]));
    b.push(den);
    batch.dispatch_rows(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        // One invocation per PIXELS_PER_INVOCATION pixels of a row
        // (register blocking: the shader's GR_PX).
        width.div_ceil(PIXELS_PER_INVOCATION),
        (rows, height),
        flops_per_pixel(radius, maps.len()) * PIXELS_PER_INVOCATION as f64,
    )
}
