//! `tsvd_debug`: the feature normalisation and TSVD local space of spec §0.6
//! at every pixel, written as debug maps (rank k, τ, ‖E‖₂, σ₁..σ₉). The
//! routine itself lives in `spirv/lib/tsvd.glsl` and is shared by the WLR,
//! LP and AOS kernels. Twin: `reference::tsvd_debug`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::TsvdPush;

/// Declaration of `spirv/tsvd_debug.comp`: its bindings in binding order and
/// the size of [`TsvdPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "tsvd_debug",
    bindings: &[
        read("normal_x"),
        read("normal_y"),
        read("normal_z"),
        read("depth"),
        read("albedo_r"),
        read("albedo_g"),
        read("albedo_b"),
        read("var_normal_x"),
        read("var_normal_y"),
        read("var_normal_z"),
        read("var_depth"),
        read("var_albedo_r"),
        read("var_albedo_g"),
        read("var_albedo_b"),
        read("spp"),
        write("rank"),
        write("tau"),
        write("specnorm"),
        write("sigma1"),
        write("sigma2"),
        write("sigma3"),
        write("sigma4"),
        write("sigma5"),
        write("sigma6"),
        write("sigma7"),
        write("sigma8"),
        write("sigma9"),
        write("rank_methods"),
    ],
    push_size: std::mem::size_of::<TsvdPush>() as u32,
};

/// Names of the 13 output maps, in binding order. `rank_methods` is the rank
/// as WLR, LP and AOS compute it (`‖E‖₂` exact only where bounds on it
/// cannot decide the rank, `tsvd_lmax_bounds` in `spirv/lib/tsvd.glsl`);
/// it must equal `rank`.
pub const OUTPUTS: [&str; 13] = [
    "rank",
    "tau",
    "specnorm",
    "sigma1",
    "sigma2",
    "sigma3",
    "sigma4",
    "sigma5",
    "sigma6",
    "sigma7",
    "sigma8",
    "sigma9",
    "rank_methods",
];

/// Per pixel, twice (the exact local space and the methods'):
/// (2R+1)² neighbours × (min/max, two 9×9 Gram matrices) plus two 9×9
/// Jacobi solves.
pub fn flops_per_pixel(radius: u32) -> f64 {
    let n = ((2 * radius + 1) * (2 * radius + 1)) as f64;
    2.0 * (n * (18.0 + 2.0 * 81.0 * 2.0) + 2.0 * 10.0 * 81.0 * 9.0 * 4.0)
}

/// Records the debug kernel. `features` = normal xyz, depth, albedo rgb;
/// `variances` in the same order; `out` = the 13 maps of [`OUTPUTS`].
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    radius: u32,
    features: [BufferSlice; 7],
    variances: [BufferSlice; 7],
    spp: BufferSlice,
    out: [BufferSlice; 13],
) -> Result<()> {
    let push = TsvdPush {
        width,
        height,
        radius,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(27);
    b.extend_from_slice(&features);
    b.extend_from_slice(&variances);
    b.push(spp);
    b.extend_from_slice(&out);
    batch.dispatch(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        height,
        flops_per_pixel(radius),
    )
}
