//! `gauss_smooth`: the Gaussian map smoothing `G_σ` of spec §0.5 over valid
//! pixels (`spp_of >= 1`), not edge-aware; used for `hbar = G_1(h_opt)`
//! (§2.3 step 8), `G_1.5` (§6.2 step 8) and for the sampling map (§9.1
//! MAP-SMOOTH). Separable: [`super::gauss_rows`] sums the rows, this kernel
//! the columns (`2(2r+1)` taps per pixel instead of `(2r+1)²`).
//! Twin: `reference::gauss_smooth`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::SmoothPush;

/// Declaration of `spirv/gauss_smooth.comp`: its bindings in binding order and
/// the size of [`SmoothPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "gauss_smooth",
    bindings: &[read("num"), read("den"), write("out")],
    push_size: std::mem::size_of::<SmoothPush>() as u32,
};

/// The window radius `ceil(3σ)` of §0.5 (0 for `σ <= 0`).
pub fn radius(sigma: f32) -> u32 {
    crate::shared::gaussian_radius(sigma as f64) as u32
}

/// Per pixel: `2r+1` rows × (2 FMAs, weight step), and a division.
pub fn flops_per_pixel(sigma: f32) -> f64 {
    let r = radius(sigma) as f64;
    (2.0 * r + 1.0) * 6.0 + 4.0
}

/// Records `out = G_σ(map)` over a `width × height` image (both passes);
/// `spp` gives the validity, `scratch` (2 planes) holds the row sums.
/// Invalid pixels receive the smoothed value of their valid neighbours (0
/// if none).
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    sigma: f32,
    map: BufferSlice,
    spp: BufferSlice,
    scratch: [BufferSlice; 2],
    out: BufferSlice,
) -> Result<()> {
    let size = (width, height);
    record_row_sums(
        batch,
        precision,
        size,
        (0, height),
        sigma,
        map,
        spp,
        scratch,
    )?;
    record_columns(batch, precision, size, (0, height), sigma, scratch, out)
}

/// The first pass of [`record`] over the rows `[first, end)` only (`first` a
/// multiple of 8): the row sums of `map` and of the weights into `scratch`.
#[allow(clippy::too_many_arguments)]
pub fn record_row_sums(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    rows: (u32, u32),
    sigma: f32,
    map: BufferSlice,
    spp: BufferSlice,
    scratch: [BufferSlice; 2],
) -> Result<()> {
    let [num, den] = scratch;
    super::gauss_rows::record(
        batch,
        precision,
        (width, height),
        rows,
        sigma,
        radius(sigma),
        &[map],
        spp,
        &[num],
        den,
    )
}

/// The second pass of [`record`] over the output rows `[first, end)` only
/// (`first` a multiple of 8): it reads the row sums of the rows within
/// [`radius`] of them, which [`record_row_sums`] must have written.
pub fn record_columns(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    rows: (u32, u32),
    sigma: f32,
    scratch: [BufferSlice; 2],
    out: BufferSlice,
) -> Result<()> {
    let [num, den] = scratch;
    let push = SmoothPush {
        width,
        height,
        radius: radius(sigma),
        sigma,
        ..Default::default()
    };
    batch.dispatch_rows(
        &DECL,
        precision,
        &[num, den, out],
        bytemuck::bytes_of(&push),
        width,
        (rows, height),
        flops_per_pixel(sigma),
    )
}
