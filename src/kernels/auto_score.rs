//! `auto_score`: the six maps `--method auto` smooths (AUTO-BLEND): each
//! member's relative error estimate `Σ_c E_m,c / (f_m,c² + 0.01)` and each
//! pair's disagreement `Σ_c (f_a,c − f_b,c)² / (f̄_c² + 0.01)`. Twin:
//! `reference::auto_score`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{AutoPush, AUTO_MAPS, AUTO_MEMBERS};

/// A declaration of `auto_score` or `auto_blend`: the three members'
/// colours and errors (18 planes, in the shaders' order), then `$rest`.
macro_rules! auto_decl {
    ($name:expr, $($rest:expr),* $(,)?) => {
        KernelDecl {
            name: $name,
            bindings: &[
                read("c0r"), read("c0g"), read("c0b"),
                read("c1r"), read("c1g"), read("c1b"),
                read("c2r"), read("c2g"), read("c2b"),
                read("e0r"), read("e0g"), read("e0b"),
                read("e1r"), read("e1g"), read("e1b"),
                read("e2r"), read("e2g"), read("e2b"),
                $($rest),*
            ],
            push_size: std::mem::size_of::<crate::shared::AutoPush>() as u32,
        }
    };
}
pub(crate) use auto_decl;

/// Declaration of `spirv/auto_score.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = auto_decl!(
    "auto_score",
    write("score0"),
    write("score1"),
    write("score2"),
    write("dis01"),
    write("dis02"),
    write("dis12"),
);

/// Per pixel: six maps of three channels, each a difference or clamp, a
/// multiply-add and a division, summed; the mean of three colours.
pub const FLOPS_PER_PIXEL: f64 = 6.0 * (3.0 * 5.0 + 2.0) + 9.0;

/// Records the maps of members with `colors` and `errors` into `maps` over
/// a `width × height` image.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    size: (u32, u32),
    colors: [[BufferSlice; 3]; AUTO_MEMBERS],
    errors: [[BufferSlice; 3]; AUTO_MEMBERS],
    maps: [BufferSlice; AUTO_MAPS],
) -> Result<()> {
    dispatch(
        batch,
        &DECL,
        precision,
        size,
        colors,
        errors,
        &[&maps],
        FLOPS_PER_PIXEL,
    )
}

/// Dispatches `auto_score` or `auto_blend` (`decl`) over a `width × height`
/// image: the members' colours, then their errors, then `rest` in order.
#[allow(clippy::too_many_arguments)]
pub(crate) fn dispatch(
    batch: &mut Batch,
    decl: &KernelDecl,
    precision: Precision,
    (width, height): (u32, u32),
    colors: [[BufferSlice; 3]; AUTO_MEMBERS],
    errors: [[BufferSlice; 3]; AUTO_MEMBERS],
    rest: &[&[BufferSlice]],
    flops_per_pixel: f64,
) -> Result<()> {
    let push = AutoPush {
        width,
        height,
        ..Default::default()
    };
    let bindings: Vec<BufferSlice> = colors
        .iter()
        .chain(&errors)
        .flat_map(|p| p.iter())
        .chain(rest.iter().flat_map(|p| p.iter()))
        .copied()
        .collect();
    batch.dispatch(
        decl,
        precision,
        &bindings,
        bytemuck::bytes_of(&push),
        width,
        height,
        flops_per_pixel,
    )
}
