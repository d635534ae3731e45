//! `lp_centres`: one sparse-centre pass of LP (spec §3.5) on the candidate
//! grid of granularity `g`. A candidate `(g·gx, g·gy)` that is valid and not
//! covered by a centre of an earlier pass (read from the `lp_reach` plane of
//! the state before the pass, PASS-SNAPSHOT) becomes a centre: TSVD on the 19×19 window (§0.6), RLS ring
//! by ring with the recursive error estimate (§3.3–3.4), `r_opt`, and its
//! 36-value state ([`LpStateLayout`](crate::shared::LpStateLayout)) is
//! written to its own pixel of the state planes; nothing else is written.
//! Twin: `reference::lp_centres`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::LpPush;

/// Declaration of `spirv/lp_centres.comp`: its bindings in binding order and
/// the size of [`LpPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "lp_centres",
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
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("var_color_r"),
        read("var_color_g"),
        read("var_color_b"),
        read("spp"),
        read("reach"),
        write("state0"),
        write("state1"),
        write("state2"),
        write("state3"),
        write("state4"),
        write("state5"),
        write("state6"),
        write("state7"),
        write("state8"),
    ],
    push_size: std::mem::size_of::<LpPush>() as u32,
};

/// The planes of sanitised (and possibly prefiltered) statistics that
/// `lp_centres` and `lp_gather` read.
pub struct LpInputs {
    /// normal x, y, z, depth, albedo r, g, b.
    pub feat: [BufferSlice; 7],
    /// Their variances (of the mean), same order.
    pub var: [BufferSlice; 7],
    /// Colour R, G, B.
    pub color: [BufferSlice; 3],
    /// Colour variances (of the mean) R, G, B.
    pub cvar: [BufferSlice; 3],
    /// Sample count `n` per pixel (f32); a pixel is valid when `n >= 1`.
    pub spp: BufferSlice,
}

/// Per grid cell that becomes a centre (the dispatch charges it to every
/// candidate cell; `bench` rescales a run's total to the cells that became
/// centres): 361 neighbours × (TSVD: two passes
/// with two 9×9 Gram updates; RLS: three projections, two 10×10 mat-vecs and
/// one rank-1 update, 3 channels) plus two 9×9 Jacobi decompositions.
pub fn flops_per_centre() -> f64 {
    let n = 361.0;
    let tsvd = 2.0 * 81.0 * 2.0 + 40.0;
    let rls = 3.0 * 162.0 + 3.0 * 200.0 + 100.0;
    n * (tsvd + rls) + 2.0 * 10.0 * 81.0 * 9.0 * 4.0
}

/// Records one pass (`push.granularity`, `push.pass`; `push.width/height`
/// are the image's) over its candidate grid. `reach` is the `lp_reach` plane
/// of the state before this pass; `state` the 9 vec4 planes.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &LpPush,
    inp: &LpInputs,
    reach: BufferSlice,
    state: [BufferSlice; 9],
) -> Result<()> {
    let mut b = Vec::with_capacity(DECL.bindings.len());
    b.extend_from_slice(&inp.feat);
    b.extend_from_slice(&inp.var);
    b.extend_from_slice(&inp.color);
    b.extend_from_slice(&inp.cvar);
    b.push(inp.spp);
    b.push(reach);
    b.extend_from_slice(&state);
    let (gw, gh) = push.centre_grid();
    batch.dispatch(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(push),
        gw,
        gh,
        flops_per_centre(),
    )
}
