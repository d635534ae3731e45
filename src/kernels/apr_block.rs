//! `apr_block`: one APR block (spec §4.2) per invocation, for one channel
//! and stage: acceptance, feature spreads, the moments over the 29×29
//! window, one ridge Cholesky (APR-RIDGE-BLOCK), the error of orders 0..3
//! from `L⁻¹` and a bias pass, the chosen order's `β_y` (and `β_s`). Sparse
//! mode writes each grid block's 52-float state
//! (`reference::apr_block::Block::state`);
//! extra mode (COVER) makes a block of every valid pixel no sparse centre
//! accepts and writes its values at that pixel to the extra planes. Twin:
//! `reference::apr_block`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision, QUEUE_HEADER_WORDS};
use crate::shared::AprPush;
use crate::shared::{
    apr_grid as grid, APR_EXTRA_PLANES, APR_P as P, APR_RADIUS as RADIUS, APR_STATE,
};

/// Declaration of `spirv/apr_block.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "apr_block",
    bindings: &[
        read("y"),
        read("v"),
        read("yprev"),
        read("s2prev"),
        read("features_a").planes(4),
        read("features_b").planes(4),
        read("spp"),
        write("state").sized_by_record(),
        write("extra").sized_by_record(),
        write("queue").sized_by_record(),
        read("spp_total").sized_by_record(),
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

/// Typical share of a sparse block's window that its confidence-interval
/// test accepts, measured with the CPU twins' inputs (after the outlier
/// stage, 16 spp): 0.83 (glossy_cornell), 0.97 (indirect_room), 0.93
/// (dof_checker), mean over the channels.
pub const SPARSE_ACCEPTED: f64 = 0.9;
/// The same for an extra block (COVER: a pixel no sparse centre accepts,
/// typically a spike or a thin feature, which few neighbours accept):
/// 0.20–0.21 (glossy_cornell), 0.46–0.48 (dof_checker).
pub const EXTRA_ACCEPTED: f64 = 0.3;

/// The work of one block whose 29×29 window holds `window` valid pixels
/// (841 inside the image), `accepted` of them in its accepted set `A_c`
/// (spec §4.2), as implemented (`p = 18` columns; without visibility its
/// column is 0 but still computed):
/// - per valid window pixel, the acceptance test in each of the three
///   passes (7 each);
/// - per accepted pixel: pass 1, the feature spreads (16); pass 2, the
///   design row (25: 8 scaled differences, `u`, `v`, 7 monomials), the
///   weight (`K_h`: 1 and an exponential, [`EXP_FLOPS`](super::EXP_FLOPS);
///   APR-OUTLIER-W: 2), the weighted rows and the `p(p+1)/2` multiply-adds
///   of the lower triangles of `M` and `V` (722), the three right-hand
///   sides (114); pass 3, the row and the weight again, the four orders'
///   predictions (`2·(9+11+14+18)`) and weighted squared errors (16);
/// - once: the ridge Cholesky (`p³/3`, square roots and divisions: 2115),
///   `L⁻¹` (1962), `G = L⁻¹VL⁻ᵀ` and `E = L⁻¹ML⁻ᵀ` (`L⁻¹` times a symmetric
///   matrix, then the lower half of the product by `L⁻ᵀ`: 8436 each), the
///   four orders' traces and variance sums over the symmetric blocks (826),
///   their `β` of `ŷ_{t−1}` (1548), `β_y` and `β_s` of the chosen order
///   (at most 1368) and the rest (70).
///
/// Not counted: the two padding columns of the `mat4` blocks, the upper
/// block triangle of the symmetric moments.
/// Flops as [`EXP_FLOPS`](super::EXP_FLOPS) counts them.
pub fn flops_of_block(window: f64, accepted: f64) -> f64 {
    flops_of_window_block(window, accepted, 1.0)
}

/// [`flops_of_block`] of a block of APR's temporal window (§10.2) over
/// `frames` frames, each with `window` valid pixels and `accepted`
/// accepted: passes 1 and 2 over every frame, pass 3 over the centre
/// frame, and (more than one frame) the centre frame's moments again
/// (SLICE: the acceptance test, the row, the weight and `M`'s lower
/// triangle).
pub fn flops_of_window_block(window: f64, accepted: f64, frames: f64) -> f64 {
    let p = P as f64;
    let weight = 1.0 + super::EXP_FLOPS + 2.0;
    let moments = 2.0 * (p + p * (p + 1.0)) + 2.0;
    let pass2 = 25.0 + weight + moments + 114.0;
    let pass3 = 25.0 + weight + 2.0 * (9.0 + 11.0 + 14.0 + 18.0) + 4.0 + 12.0;
    let slice = if frames > 1.0 {
        25.0 + weight + p * (p + 1.0) + 1.0
    } else {
        0.0
    };
    let once = 2115.0 + 1962.0 + 2.0 * 8436.0 + 826.0 + 1548.0 + 1368.0 + 70.0;
    // The acceptance test: passes 1 and 2 per frame, pass 3, and the
    // slice's pass.
    let tests = 2.0 * frames + if frames > 1.0 { 2.0 } else { 1.0 };
    window * tests * 7.0 + accepted * (frames * (16.0 + pass2) + pass3 + slice) + once
}

/// An upper bound of [`flops_of_block`], which sizes the extra blocks'
/// bands: a full 29×29 window, every pixel accepted.
pub fn flops_per_block() -> f64 {
    flops_of_block(841.0, 841.0)
}

/// Mean over the centres `0, step, 2·step, …` of a row of `len` pixels of
/// the extent of their windows `[c − R, c + R]` ([`RADIUS`]) clipped to the
/// row.
fn mean_extent(len: u32, step: usize) -> f64 {
    let n = len as usize;
    let centres = (0..n).step_by(step);
    let sum: usize = centres
        .clone()
        .map(|c| super::clipped_span(c, RADIUS, n))
        .sum();
    sum as f64 / centres.count().max(1) as f64
}

/// Records the sparse blocks (`push.mode = 0`; in raster order on a grid 8
/// invocations wide, so that every SIMD lane of lavapipe holds one, not the
/// block grid's shape: APR-LINEAR-BLOCKS), or the extra blocks
/// (`push.mode = 1`, COVER): band by band, the pixels no sparse centre
/// accepts are queued in `queue` (u32, [`queue_words`]) and then fitted by
/// an indirect dispatch, one invocation per entry, so that they fill whole
/// SIMD vectors (APR-EXTRA-QUEUE).
/// `feats`: the two vec4 planes of [`super::apr_pack`] (normal xyz, albedo
/// r; albedo g b, depth, visibility or 0). `extra_fraction`: the expected fraction of
/// pixels that become extra blocks, per channel (for the band split, the
/// progress and the timings' count; typical values in COVER's record).
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &AprPush,
    ch: &AprChannel,
    feats: &[BufferSlice; 2],
    (spp, sppt): (BufferSlice, BufferSlice),
    (state, extra, queue): (BufferSlice, BufferSlice, BufferSlice),
    extra_fraction: f64,
) -> Result<()> {
    DECL.require(10, &sppt, 4 * super::spp_total::WORDS as u64)?;
    let mut b = vec![ch.y, ch.v, ch.yprev, ch.s2prev];
    b.extend_from_slice(feats);
    b.extend([spp, state, extra, queue, sppt]);
    let (w, h) = (push.width as u64, push.height as u64);
    if push.mode == 0 {
        // The block states of channels 0..=channel.
        let (gw, gh) = grid(push.width as usize, push.height as usize);
        let cells = (gw * gh) as u64;
        DECL.require(
            7,
            &state,
            4 * (APR_STATE as u64) * (push.channel as u64 + 1) * cells,
        )?;
    } else {
        // This channel's extra-block planes (`stride` words apart) and the
        // queue of every pixel.
        let planes = APR_EXTRA_PLANES as u64 * push.channel as u64 + 3;
        DECL.require(8, &extra, 4 * (planes * push.stride as u64 + w * h))?;
        DECL.require(9, &queue, 4 * queue_words(w as usize, h as usize) as u64)?;
    }
    let push_bytes = bytemuck::bytes_of(push);
    // The frames a block reads (APR's temporal window, §10.2).
    let frames = if push.flags & crate::shared::APR_TEMPORAL != 0 {
        (push.window & 31).count_ones().max(1) as f64
    } else {
        1.0
    };
    if push.mode == 0 {
        // APR-LINEAR-BLOCKS: the blocks in raster order on a grid 8 wide.
        let (gw, gh) = grid(push.width as usize, push.height as usize);
        let rows = (gw * gh).div_ceil(8) as u32;
        // The blocks' typical work (their windows clipped to the image,
        // SPARSE_ACCEPTED of them accepted), spread over the grid's
        // invocations (the last row's idle lanes charged nothing).
        let window = mean_extent(push.width, RADIUS) * mean_extent(push.height, RADIUS);
        let block = flops_of_window_block(window, SPARSE_ACCEPTED * window, frames);
        let per_lane = block * (gw * gh) as f64 / (8.0 * rows.max(1) as f64);
        return batch.dispatch(&DECL, precision, &b, push_bytes, 8, rows, per_lane);
    }
    let (w, h) = (push.width, push.height);
    if w == 0 || h == 0 {
        return Ok(());
    }
    // Bands whose expected extra blocks stay within a submit's work, each
    // charged as a full block; the timings get their typical work.
    let px_flops = flops_of_window_block(841.0, 841.0, frames) * extra_fraction + SELECT_FLOPS;
    let window = mean_extent(w, 1) * mean_extent(h, 1);
    let extra_block = flops_of_window_block(window, EXTRA_ACCEPTED * window, frames);
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
                px * extra_fraction * extra_block,
                0.0,
            )
        })?;
        row0 += rows;
    }
    Ok(())
}

/// Per pixel of the extra blocks' selection: the acceptance test (7)
/// against the sparse centres within 14 until one accepts (2 to 9 of them
/// in reach; usually the first accepts): four tests.
const SELECT_FLOPS: f64 = 28.0;

/// Words of the extra blocks' queue of a `width × height` image: the
/// indirect dispatch's header (x, y, z), the count, one entry per pixel.
pub fn queue_words(width: usize, height: usize) -> usize {
    QUEUE_HEADER_WORDS + width * height
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_clipped_to_the_image() {
        // 256: centres 0, 14, …, 252; extents 15, 29 (17 of them), 18.
        assert!((mean_extent(256, 14) - (15.0 + 17.0 * 29.0 + 18.0) / 19.0).abs() < 1e-12);
        assert_eq!(mean_extent(1, 14), 1.0);
        assert!(mean_extent(1000, 1) < 29.0);
        assert!(flops_of_block(841.0, 0.9 * 841.0) < flops_per_block());
        assert!(flops_of_block(10.0, 1.0) > 0.0);
    }
}
