//! `apr_block`: one APR block (spec §4.2) per invocation, for one channel
//! and stage: acceptance, feature spreads, the moments over the 29×29
//! window, one ridge Cholesky (APR-RIDGE-BLOCK), the error of orders 0..3
//! from `L⁻¹` and a bias pass, the chosen order's `β_y` (and `β_s`). Sparse
//! mode writes each grid block's 52-float state
//! ([`reference::apr_block::Block::state`](crate::reference::apr_block::Block::state));
//! extra mode (COVER) makes a block of every valid pixel no sparse centre
//! accepts and writes its values at that pixel to the extra planes. Twin:
//! `reference::apr_block`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision, QUEUE_HEADER_WORDS};
use crate::reference::apr_block::{grid, P};
use crate::shared::AprPush;

/// Declaration of `spirv/apr_block.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "apr_block",
    bindings: &[
        read("y"),
        read("v"),
        read("yprev"),
        read("s2prev"),
        read("features_a"),
        read("features_b"),
        read("spp"),
        write("state"),
        write("extra"),
        write("queue"),
    ],
    push_size: std::mem::size_of::<AprPush>() as u32,
};

/// The planes one channel's blocks read.
#[derive(Clone, Copy)]
pub struct AprChannel {
    /// The channel's values and variances (outlier-cleaned).
    pub y: BufferSlice,
    /// See `y`.
    pub v: BufferSlice,
    /// `ŷ_{t−1}` (stage 1: `y`).
    pub yprev: BufferSlice,
    /// `σ̂²_{t−1}` (stage 1: `v`).
    pub s2prev: BufferSlice,
}

/// Per block: three passes over 841 pixels (the moments: 30 4×4 outer
/// products, 960 flops a pixel; the bias: 4 × 18 multiply-adds) and the
/// 18×18 factorisation, inverse and `L⁻¹VL⁻ᵀ` (~12,000 flops).
pub fn flops_per_block() -> f64 {
    let p = P as f64;
    841.0 * (960.0 + 3.0 * 40.0 + 160.0) + 2.0 * p * p * p
}

/// Records the sparse blocks (`push.mode = 0`; in raster order on a grid 8
/// invocations wide, so that every SIMD lane of lavapipe holds one: laid
/// out on the 19×19 block grid of a 256² image, 8×8 workgroups left 37 % of
/// the lanes idle: APR-LINEAR-BLOCKS), or the extra blocks (`push.mode = 1`,
/// COVER): band by band, the pixels no sparse centre accepts are queued in
/// `queue` (u32, [`queue_words`]) and then fitted by an indirect dispatch,
/// one invocation per entry (APR-EXTRA-QUEUE: compacted per 8×8 workgroup
/// instead, a tile's one or two extra pixels left most lanes of their SIMD
/// vector idle; the extra blocks took 350 of `apr_block`'s 680 ms at 256²).
/// `feats`: the two vec4 planes of [`super::apr_pack`] (normal xyz, albedo
/// r; albedo g b, depth, visibility or 0). `extra_fraction`: the expected fraction of
/// pixels that become extra blocks (for the band split and progress).
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &AprPush,
    ch: &AprChannel,
    feats: &[BufferSlice; 2],
    spp: BufferSlice,
    (state, extra, queue): (BufferSlice, BufferSlice, BufferSlice),
    extra_fraction: f64,
) -> Result<()> {
    let mut b = vec![ch.y, ch.v, ch.yprev, ch.s2prev];
    b.extend_from_slice(feats);
    b.extend([spp, state, extra, queue]);
    let push_bytes = bytemuck::bytes_of(push);
    if push.mode == 0 {
        // APR-LINEAR-BLOCKS: the blocks in raster order on a grid 8 wide.
        let (gw, gh) = grid(push.width as usize, push.height as usize);
        let rows = (gw * gh).div_ceil(8) as u32;
        return batch.dispatch(&DECL, precision, &b, push_bytes, 8, rows, flops_per_block());
    }
    let (w, h) = (push.width, push.height);
    if w == 0 || h == 0 {
        return Ok(());
    }
    // Bands whose expected extra blocks stay within a submit's work.
    let px_flops = flops_per_block() * extra_fraction + SELECT_FLOPS;
    let band = batch.band_rows(px_flops * w as f64, 8);
    let fit = AprPush { mode: 2, ..*push };
    let mut row0 = 0;
    while row0 < h {
        let rows = band.min(h - row0);
        let px = (w * rows) as f64;
        batch.unit(px * px_flops, |batch| {
            batch.reset_queue(queue)?;
            batch.dispatch_rows(
                &DECL,
                precision,
                &b,
                push_bytes,
                w,
                ((row0, row0 + rows), h),
                SELECT_FLOPS,
            )?;
            batch.dispatch_indirect(
                &DECL,
                precision,
                &b,
                bytemuck::bytes_of(&fit),
                queue.sub(0, 12)?,
                px * extra_fraction * flops_per_block(),
                0.0,
            )
        })?;
        row0 += rows;
    }
    Ok(())
}

/// Per pixel of the extra blocks' selection: the acceptance test against
/// the (at most four) sparse centres within 14.
const SELECT_FLOPS: f64 = 100.0;

/// Words of the extra blocks' queue of a `width × height` image: the
/// indirect dispatch's header (x, y, z), the count, one entry per pixel.
pub fn queue_words(width: usize, height: usize) -> usize {
    QUEUE_HEADER_WORDS + width * height
}
