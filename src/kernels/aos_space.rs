//! `aos_space`: AOS's per-pixel TSVD local space (spec §5.3 step 1, §0.6)
//! over the 10 features of §5.1, stored as the projection `P` and rank `k`
//! ([`SPACE`] f32 per pixel) that `aos_fit` reads. Covers the rows
//! `base_row + [0, rows)`. Twin: `reference::aos_space`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::AosPush;
pub use crate::shared::AOS_SPACE as SPACE;

/// Declaration of `spirv/aos_space.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "aos_space",
    bindings: &[
        read("depth"),
        read("albedo_r"),
        read("albedo_g"),
        read("albedo_b"),
        read("normal_x"),
        read("normal_y"),
        read("normal_z"),
        read("visibility"),
        read("var_depth"),
        read("var_albedo_r"),
        read("var_albedo_g"),
        read("var_albedo_b"),
        read("var_normal_x"),
        read("var_normal_y"),
        read("var_normal_z"),
        read("var_visibility"),
        read("spp"),
        write("space").sized_by_record(),
    ],
    push_size: std::mem::size_of::<AosPush>() as u32,
};

/// Per pixel: one pass over the `(2R+1)²` window (TSVD-ONE-PASS) with two
/// 10×10 symmetric Gram updates, `G` and `EᵀE` (2 × 55 multiply-adds), and
/// the sums, ranges and square roots (~40 flops), plus two 10×10 Jacobi
/// eigen-decompositions (~6 sweeps × 45 rotations × 60 flops).
pub fn flops_per_pixel(radius: u32) -> f64 {
    let n = ((2 * radius + 1) * (2 * radius + 1)) as f64;
    n * (2.0 * 2.0 * 55.0 + 40.0) + 2.0 * 6.0 * 45.0 * 60.0
}

/// Records the local spaces of rows `push.base_row + [0, rows)`;
/// `feats`/`vars`: depth, albedo rgb, normal xyz, visibility; `space` holds
/// `rows × width × SPACE` f32, `rows` rounded up to whole workgroups of 8
/// rows unless the band ends at the image's last row.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &AosPush,
    rows: u32,
    feats: &[BufferSlice; 8],
    vars: &[BufferSlice; 8],
    spp: BufferSlice,
    space: BufferSlice,
) -> Result<()> {
    // The band's projections from `base_row`: whole workgroups of 8 rows,
    // clipped to the image.
    let band = rows
        .next_multiple_of(8)
        .min(push.height.saturating_sub(push.base_row));
    DECL.require(
        17,
        &space,
        4 * (SPACE as u64) * push.width as u64 * band as u64,
    )?;
    let groups: [&[BufferSlice]; 3] = [feats, vars, &[spp, space]];
    let flops = flops_per_pixel(push.radius);
    super::dispatch_groups(
        batch,
        &DECL,
        precision,
        push,
        (push.width, rows),
        &groups,
        flops,
    )
}
