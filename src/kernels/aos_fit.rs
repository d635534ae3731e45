//! `aos_fit`: AOS's fits (spec §5.3 steps 2–8), one workgroup of
//! [`THREADS`] invocations per pixel with the order-5 normal matrix in
//! workgroup memory (§5.4). Reads `aos_space`'s projections; writes
//! [`OUTPUTS`] planes `push.stride` f32 values apart in one binding. Twin:
//! `reference::aos_fit`, which also states the algebra.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{AosPush, AOS_SPACE as SPACE};
pub use crate::shared::{
    AOS_DEBUG_NAMES as DEBUG_NAMES, AOS_MAX_COLS as MAX_COLS, AOS_OUTPUTS as OUTPUTS,
};

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
        read("space").sized_by_record(),
        read("var_depth"),
        read("var_albedo_r"),
        read("var_albedo_g"),
        read("var_albedo_b"),
        read("var_normal_x"),
        read("var_normal_y"),
        read("var_normal_z"),
        read("var_visibility"),
        write("dst").sized_by_record(),
    ],
    push_size: std::mem::size_of::<AosPush>() as u32,
};

/// The estimate that sizes the bands (and, until `mcdenoise bench` rescales
/// it, the roofline's count): per pixel with `p` design columns (`1 + 5k`,
/// at most [`MAX_COLS`]) over `n = (2R+1)²` window pixels, in its one
/// window pass: the row's projection (10×10 plus the feature differences,
/// ~220 flops) and powers (~50), and three Gram matrices (weights `K`,
/// `K²`, `K² vbar`) of the rows extended by the three colours, as the
/// `nb(nb+1)/2` 4×4 blocks of the lower block triangle (`nb = ⌈(p+3)/4⌉`,
/// 32 flops per block, row and matrix). After it: the Cholesky (`p³/3`),
/// seven triangular solves (`2p²` each) and seven quadratic forms over the
/// blocks. The rank varies per pixel: the count takes `p = 1 + 5·rank`.
/// It charges the kernel's layout (the padded blocks, the colour rows of
/// `B` and `G`, the full 10-row projection): about 1.5× [`flops_of_pixel`]
/// at the same rank; kept for the bands, whose submits already take about
/// half a second on lavapipe at rank 3.
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

/// The work AOS needs at a valid pixel of TSVD rank `rank` (`p = 1 + 5k`
/// columns of the order-5 design; `p₁ = 1 + k`, `p₃ = 1 + 3k`) whose
/// window holds `window` valid pixels ((2R+1)² inside the image), as
/// implemented (spec §5.3; f64 arithmetic):
/// - per window pixel: `Δz` (10 differences, `10k` multiply-adds: the
///   projection's rows beyond `k` are 0), the kernel `K` (3 and an
///   exponential, [`EXP_FLOPS`](super::EXP_FLOPS)) and the outlier weight
///   (2), `K²` and `K² vbar` (2), AOS-RESIDUAL's `K (ln vbar + ln n)` (two
///   logarithms, counted as exponentials, and 5), the powers `Δz²…Δz⁵`
///   (`4k`), and the three Gram matrices `N`, `B`, `G`: per matrix the
///   weighted row (`p`) and the `p(p+1)/2` multiply-adds of its lower
///   triangle, and `N`'s three colour right-hand sides (`3p` multiply-adds):
///   `3p² + 12p`;
/// - once: AOS-SCALE (`p(p+1) + 6p`), the ridge Cholesky (`p³/3 + p²/2`),
///   eight triangular solves (`u*`, `β*`, `q₁`, `q₃` of order `p`; `u_l`,
///   `β_l` of orders `p₁`, `p₃`: `2s²` each), the bias vectors and biases
///   (`4k(p₁+p₃) + 2(2k+1)(p₁+p₃)`), the raw-layout vectors (`5p`), seven
///   quadratic forms over a symmetric `p × p` matrix (`1.5p(p+1)` each) and
///   the rest (the choice, the output, AOS-FEATNOISE: ~300).
///
/// Not counted: the padded lanes of the 4×4 blocks, the colour rows of `B`
/// and `G` (never read), the duplicate half of a symmetric matrix.
/// `mcdenoise bench` charges each pixel this at its rank (AOS's rank map);
/// a pixel of rank 0 (or invalid) does no fit (0).
/// Flops as [`EXP_FLOPS`](super::EXP_FLOPS) counts them.
pub fn flops_of_pixel(window: f64, rank: u32) -> f64 {
    if rank == 0 {
        return 0.0;
    }
    let e = super::EXP_FLOPS;
    let k = rank as f64;
    let p = 1.0 + 5.0 * k;
    let (p1, p3) = (1.0 + k, 1.0 + 3.0 * k);
    let row = 10.0 + 20.0 * k + (3.0 + e) + 2.0 + 2.0 + (2.0 * e + 5.0) + 4.0 * k;
    let gram = 3.0 * p * p + 12.0 * p;
    let scale = p * (p + 1.0) + 6.0 * p;
    let cholesky = p * p * p / 3.0 + p * p / 2.0;
    let solves = 2.0 * (4.0 * p * p + 2.0 * p1 * p1 + 2.0 * p3 * p3);
    let bias = 4.0 * k * (p1 + p3) + 2.0 * (2.0 * k + 1.0) * (p1 + p3);
    let forms = 5.0 * p + 7.0 * 1.5 * p * (p + 1.0);
    window * (row + gram) + scale + cholesky + solves + bias + forms + 300.0
}

/// Records the fits of rows `push.base_row + [0, rows)` (`push.flags`:
/// `AOS_SANDWICH`, `AOS_BIAS_TEST`, `AOS_IDENTITY`, `AOS_IDENTITY_FLOOR`,
/// `AOS_OUTLIER_W`, `AOS_RESIDUAL`, `AOS_FEATNOISE`). `vars`: the features'
/// variances. `rank` is the mean TSVD rank assumed by the cost count
/// (progress and the roofline only).
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
    let (w, pixels) = (push.width as u64, push.width as u64 * push.height as u64);
    DECL.require(13, &space, 4 * SPACE as u64 * w * rows as u64)?;
    DECL.require(
        22,
        &dst,
        4 * ((OUTPUTS as u64 - 1) * push.stride as u64 + pixels),
    )?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layout_estimate_exceeds_the_work_at_every_rank() {
        for radius in [5u32, 9] {
            let full = ((2 * radius + 1) * (2 * radius + 1)) as f64;
            assert_eq!(flops_of_pixel(full, 0), 0.0);
            for rank in 1..=10 {
                let (of, per) = (
                    flops_of_pixel(full, rank),
                    flops_per_pixel(radius, rank as f64),
                );
                assert!(
                    of < per && of > 0.3 * per,
                    "rank {rank}: {of} against {per}"
                );
            }
        }
    }
}
