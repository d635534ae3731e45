//! `finalize_covariance`: position sums → covariance of the position samples
//! divided by n (6 planes XX XY XZ YY YZ ZZ). Twin:
//! `reference::finalize_covariance`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::FinalizePush;

/// Declaration of `spirv/finalize_covariance.comp`: its bindings in binding
/// order and the size of [`FinalizePush`]; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "finalize_covariance",
    bindings: &[
        read("sum_x"),
        read("sum_y"),
        read("sum_z"),
        read("sumsq_x"),
        read("sumsq_y"),
        read("sumsq_z"),
        read("sum_xy"),
        read("sum_xz"),
        read("sum_yz"),
        read("count"),
        write("cov_xx"),
        write("cov_xy"),
        write("cov_xz"),
        write("cov_yy"),
        write("cov_yz"),
        write("cov_zz"),
    ],
    push_size: std::mem::size_of::<FinalizePush>() as u32,
};

/// Estimated floating-point operations per pixel (for band splitting): three
/// means, three variances and three clamped cross terms.
pub const FLOPS_PER_PIXEL: f64 = 40.0;

/// Records the covariance finalize. `sums` = Σx Σy Σz, `sumsqs` = Σx² Σy² Σz²,
/// `cross` = Σxy Σxz Σyz, `cov` = outputs XX XY XZ YY YZ ZZ.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    sums: [BufferSlice; 3],
    sumsqs: [BufferSlice; 3],
    cross: [BufferSlice; 3],
    count: BufferSlice,
    cov: [BufferSlice; 6],
) -> Result<()> {
    let push = FinalizePush {
        width,
        height,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(16);
    b.extend_from_slice(&sums);
    b.extend_from_slice(&sumsqs);
    b.extend_from_slice(&cross);
    b.push(count);
    b.extend_from_slice(&cov);
    batch.dispatch(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        height,
        FLOPS_PER_PIXEL,
    )
}
