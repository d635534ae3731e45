//! `wlr_final`: WLR steps 9–10 (spec §2.3) per pixel — the local space and
//! the `b_j` that `wlr_fit` stored in its centre state (the same values the
//! twin recomputes), the final local linear fit at `h = hbar_c`, output
//! clamped `>= 0`, and `MSE_c` from the model stored by `wlr_fit`. Twin:
//! `reference::wlr_final`.
//!
//! Outputs (bindings 13..17): R, G, B; `mse`; `flags` as a float: `wlr_fit`'s
//! flags | bit 1 FEW in the final fit | bit 0 SOLVE-FAIL (output `y_c`,
//! `mse = vbar_c`) | bit 5 invalid pixel (`spp < 1`: mean colour of its valid
//! 3×3 neighbours clamped `>= 0`, `mse = 0`).

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::WlrPush;

/// Declaration of `spirv/wlr_final.comp`: its bindings in binding order and the
/// size of [`WlrPush`]; checked against the SPIR-V by reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "wlr_final",
    bindings: bindings!(),
    push_size: std::mem::size_of::<WlrPush>() as u32,
};

/// Declaration of `wlr_final_vis` (WLR-VIS): [`DECL`]'s bindings, then the
/// prefiltered visibility.
pub const DECL_VIS: KernelDecl = KernelDecl {
    name: "wlr_final_vis",
    bindings: bindings!(read("visibility")),
    push_size: std::mem::size_of::<WlrPush>() as u32,
};

/// The declaration of the variant that reads `features` (9, or 10 with the
/// visibility).
pub fn decl(features: usize) -> &'static KernelDecl {
    if features > 9 {
        &DECL_VIS
    } else {
        &DECL
    }
}

macro_rules! bindings {
    ($($extra:expr),*) => { &[
        read("features_a").planes(4),
        read("features_b").planes(4),
        read("color_r"),
        read("color_g"),
        read("color_b"),
        read("vbar"),
        read("spp"),
        read("hbar"),
        read("lambda1"),
        read("kappa0"),
        read("kappa1"),
        read("kflags"),
        read("state").sized_by_record(),
        write("out_r"),
        write("out_g"),
        write("out_b"),
        write("mse"),
        write("flags"),
        $($extra),*
    ] };
}
use bindings;

/// Names of the 5 output maps, in binding order.
pub const OUTPUTS: [&str; 5] = ["out_r", "out_g", "out_b", "mse", "flags"];

/// Typical share of a centre's valid window pixels in the support of the
/// final fit's kernel (`h = hbar_c`), measured with the CPU twins at `h_opt`
/// (R = 9, one centre in 64) on glossy_cornell, indirect_room and
/// dof_checker at 16 spp: 0.686, 0.716, 0.490.
pub const FINAL_SUPPORT: f64 = 0.63;

/// `wlr_final`'s work at a valid centre of rank `rank` whose window holds
/// `window` valid pixels: step 9's fit at one bandwidth, counted as
/// [`super::wlr_fit`]'s trial fits are (two passes; WLR-CI's share
/// [`super::wlr_fit::ACCEPTED`], the kernel's support [`FINAL_SUPPORT`]),
/// and step 10's MSE model and the centre (~30). The local space and the
/// `b_j` are read from `wlr_fit`'s centre state, not recomputed; a pixel of
/// rank 0 passes through (0). The padded lanes of the `mat4` blocks, the
/// duplicate half of the normal matrix and the neighbours outside the
/// kernel's support are not counted. `mcdenoise bench` charges each pixel
/// this at its rank; the dispatch charges the bound [`flops_per_pixel`].
/// Flops as [`EXP_FLOPS`](super::EXP_FLOPS) counts them.
pub fn flops_of_pixel(window: f64, rank: u32) -> f64 {
    flops_of(window, rank, 9.0)
}

/// [`flops_of_pixel`] of `wlr_final_vis` (ten features).
pub fn flops_of_pixel_vis(window: f64, rank: u32) -> f64 {
    flops_of(window, rank, 10.0)
}

fn flops_of(window: f64, rank: u32, d: f64) -> f64 {
    if rank == 0 {
        return 0.0;
    }
    super::wlr_fit::fits_flops(
        window,
        rank as f64,
        d,
        super::wlr_fit::ACCEPTED,
        &[FINAL_SUPPORT],
    ) + 30.0
}

/// An upper bound of [`flops_of_pixel`] (of [`flops_of_pixel_vis`] for 10
/// `features`), which sizes the bands: a full `(2R+1)²` window, rank 9,
/// every neighbour accepted and inside the kernel's support.
pub fn flops_per_pixel(radius: u32, features: usize) -> f64 {
    let n = ((2 * radius + 1) * (2 * radius + 1)) as f64;
    super::wlr_fit::fits_flops(n, 9.0, features as f64, 1.0, &[1.0]) + 30.0
}

/// Records `wlr_final` over the rows `rows = [first, end)` (`first` a
/// multiple of 8) of a `width × height` image. Inputs as
/// [`super::wlr_fit::record`] without the packed variances (`packed` = the
/// first two of its four planes), plus `hbar = G_1(h_opt)`
/// (`gauss_smooth` with σ = 1), `fit` = the `λ1`, `κ0`, `κ1`, `kflags` maps of
/// `wlr_fit` and its centre state ring (same `radius`, `options`,
/// `ring_rows`, and still holding these rows). `out` = the 5 maps of
/// [`OUTPUTS`]; `vis` = the prefiltered visibility for `wlr_final_vis`
/// (WLR-VIS, with `wlr_fit_vis`'s state), or `None` for `wlr_final`.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    rows: (u32, u32),
    (radius, options): (u32, u32),
    packed: [BufferSlice; 2],
    color: [BufferSlice; 3],
    vbar: BufferSlice,
    spp: BufferSlice,
    hbar: BufferSlice,
    fit: [BufferSlice; 4],
    (state, ring_rows): (BufferSlice, u32),
    out: [BufferSlice; 5],
    vis: Option<BufferSlice>,
) -> Result<()> {
    let features = if vis.is_some() { 10 } else { 9 };
    let decl = decl(features);
    super::wlr_fit::require_state(
        decl,
        12,
        precision,
        width,
        height,
        (&state, ring_rows),
        features,
    )?;
    let push = WlrPush {
        width,
        height,
        radius,
        options,
        ring_rows,
        ..Default::default()
    };
    let mut b = Vec::with_capacity(18);
    b.extend_from_slice(&packed);
    b.extend_from_slice(&color);
    b.push(vbar);
    b.push(spp);
    b.push(hbar);
    b.extend_from_slice(&fit);
    b.push(state);
    b.extend_from_slice(&out);
    b.extend(vis);
    batch.dispatch_rows(
        decl,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        width,
        (rows, height),
        flops_per_pixel(radius, features),
    )
}
