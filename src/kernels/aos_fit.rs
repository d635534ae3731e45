//! `aos_fit`: AOS's fits (spec §5.3 steps 2–8), one workgroup of
//! [`THREADS`] invocations per pixel with the order-5 normal matrix in
//! workgroup memory (§5.4). Reads `aos_space`'s projections; writes
//! [`OUTPUTS`] planes `push.stride` f32 values apart in one binding. Twin:
//! [`crate::reference::aos_fit`], which also states the algebra.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
pub use crate::reference::aos_fit::{DEBUG_NAMES, MAX_COLS, OUTPUTS};
use crate::shared::AosPush;

/// Invocations per pixel (the kernel's `local_size_x`).
pub const THREADS: u32 = 64;

/// Declaration of `spirv/aos_fit.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "aos_fit",
    bindings: &[
        read("depth"),
        read("albedo_r"),
        read("albedo_g"),
        read("albedo_b"),
        read("normal_x"),
        read("normal_y"),
        read("normal_z"),
        read("visibility"),
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("vbar"),
        read("spp"),
        read("space"),
        read("var_depth"),
        read("var_albedo_r"),
        read("var_albedo_g"),
        read("var_albedo_b"),
        read("var_normal_x"),
        read("var_normal_y"),
        read("var_normal_z"),
        read("var_visibility"),
        write("dst"),
    ],
    push_size: std::mem::size_of::<AosPush>() as u32,
};

/// Per pixel with `p` design columns (`1 + 5k`, at most [`MAX_COLS`]) over
/// `n = (2R+1)²` window pixels, in its one window pass: the row's
/// projection (10×10 plus the feature differences, ~220 flops) and powers
/// (~50), and three Gram matrices (weights `K`, `K²`, `K² vbar`) of the rows
/// extended by the three colours, as the `nb(nb+1)/2` 4×4 blocks of the
/// lower block triangle (`nb = ⌈(p+3)/4⌉`, 32 flops per block, row and
/// matrix). After it: the Cholesky (`p³/3`), seven triangular solves
/// (`2p²` each) and seven quadratic forms over the blocks. The rank varies
/// per pixel: the count takes `p = 1 + 5·rank`.
pub fn flops_per_pixel(radius: u32, rank: f64) -> f64 {
    let n = ((2 * radius + 1) * (2 * radius + 1)) as f64;
    let p = 1.0 + 5.0 * rank;
    let nb = ((p + 3.0) / 4.0).ceil();
    let pairs = nb * (nb + 1.0) / 2.0;
    n * (220.0 + 50.0 + 3.0 * 32.0 * pairs)
        + p * p * p / 3.0
        + 7.0 * 2.0 * p * p
        + 7.0 * 40.0 * pairs
}

/// Records the fits of rows `push.base_row + [0, rows)` (`push.flags`:
/// `AOS_SANDWICH`, `AOS_BIAS_TEST`, `AOS_IDENTITY`, `AOS_OUTLIER_W`,
/// `AOS_RESIDUAL`, `AOS_FEATNOISE`). `vars`: the features' variances. `rank` is the mean TSVD
/// rank assumed by the cost count (progress and the roofline only).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &AosPush,
    rows: u32,
    feats: &[BufferSlice; 8],
    color: [BufferSlice; 3],
    vbar: BufferSlice,
    spp: BufferSlice,
    space: BufferSlice,
    vars: &[BufferSlice; 8],
    dst: BufferSlice,
    rank: f64,
) -> Result<()> {
    let mut b = Vec::with_capacity(DECL.bindings.len());
    b.extend_from_slice(feats);
    b.extend_from_slice(&color);
    b.extend([vbar, spp, space]);
    b.extend_from_slice(vars);
    b.push(dst);
    batch.dispatch(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(push),
        push.width * THREADS,
        rows,
        flops_per_pixel(push.radius, rank) / THREADS as f64,
    )
}
