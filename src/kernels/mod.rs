//! One file per GPU kernel (`spirv/<name>.comp`): its binding declaration
//! ([`KernelDecl`]), its cost estimate and a function that records it into a
//! [`Batch`]. The scalar twin of each is `src/reference/<name>.rs`; the
//! constants both need live in [`crate::shared`], so nothing here imports
//! the twins.

use crate::gpu::KernelDecl;

pub mod aos_fit;
pub mod aos_nlm;
pub mod aos_space;
pub mod apr_block;
pub mod apr_gather;
pub mod apr_pack;
pub mod auto_blend;
pub mod auto_dis;
pub mod auto_score;
pub mod box_rows;
pub mod channel_mean;
pub mod estimate_variance;
pub mod finalize_covariance;
pub mod finalize_stats;
pub mod gauss_rows;
pub mod gauss_smooth;
pub mod gbf_filter;
pub mod gbf_pack;
pub mod gbf_prepare;
pub mod gbf_sure;
pub mod input_blend;
pub mod lp_centres;
pub mod lp_gather;
pub mod lp_reach;
pub mod lp_select;
pub mod lp_smooth;
pub mod lp_temporal;
pub mod lp_temporal_gain;
pub mod outlier_clip;
pub mod outlier_detect;
pub mod outlier_grey;
pub mod outlier_median;
pub mod outlier_rows;
pub mod outlier_spread;
pub mod outlier_weights;
pub mod peak_copy;
pub mod peak_fma;
pub mod pyramid_merge;
pub mod pyramid_pool;
pub mod sample_priority;
pub mod sample_reduce;
pub mod sample_scan;
pub mod sample_upsample;
pub mod sanitize;
pub mod sanitize_low_spp;
pub mod sanitize_quads;
pub mod spp_total;
pub mod temporal_motion;
pub mod tsvd_debug;
pub mod wlr_final;
pub mod wlr_fit;

/// Flops an exponential counts for in the kernels' cost functions:
/// llvmpipe's `exp2` is a range reduction and a degree-5 polynomial, about
/// 15 vector operations (an `exp` is the same after one multiply). The
/// rest of the convention: an add, multiply or compare (min/max) 1, a
/// multiply-add 2, a division or square root 1.
pub const EXP_FLOPS: f64 = 15.0;

/// Pixels of the span `[c − r, c + r]` inside `[0, n)` (`c < n`): a
/// window's extent along one axis, clipped to the image (the cost
/// functions' and `bench`'s count of a window's pixels).
pub fn clipped_span(c: usize, r: usize, n: usize) -> usize {
    (c + r).min(n - 1) + 1 - c.saturating_sub(r)
}

/// Every kernel, for the reflection test and `mcdenoise bench`.
pub const ALL: &[&KernelDecl] = &[
    &finalize_stats::DECL,
    &finalize_covariance::DECL,
    &sanitize::DECL,
    &sanitize_low_spp::DECL,
    &sanitize_quads::DECL,
    &estimate_variance::DECL,
    &tsvd_debug::DECL,
    &channel_mean::DECL,
    &spp_total::DECL,
    &gauss_rows::DECL,
    &gauss_smooth::DECL,
    &wlr_fit::DECL,
    &wlr_fit::DECL_VIS,
    &wlr_final::DECL,
    &wlr_final::DECL_VIS,
    &gbf_prepare::DECL,
    &gbf_sure::DECL,
    &gbf_filter::DECL,
    &gbf_pack::DECL,
    &lp_centres::DECL,
    &lp_reach::DECL,
    &lp_select::DECL,
    &lp_gather::DECL,
    &lp_smooth::DECL,
    &lp_temporal::DECL,
    &lp_temporal_gain::DECL,
    &temporal_motion::DECL,
    &aos_nlm::DECL,
    &aos_nlm::DECL_VIS,
    &aos_space::DECL,
    &aos_fit::DECL,
    &apr_block::DECL,
    &apr_gather::DECL,
    &apr_pack::DECL,
    &outlier_grey::DECL,
    &outlier_rows::DECL,
    &outlier_clip::DECL,
    &outlier_detect::DECL,
    &outlier_median::DECL,
    &box_rows::DECL,
    &outlier_weights::DECL,
    &outlier_spread::DECL,
    &auto_score::DECL,
    &auto_dis::DECL,
    &auto_blend::DECL,
    &pyramid_pool::DECL,
    &pyramid_merge::DECL,
    &input_blend::DECL,
    &sample_priority::DECL,
    &sample_reduce::DECL,
    &sample_scan::DECL,
    &sample_upsample::DECL,
    &peak_fma::DECL,
    &peak_copy::DECL,
];

use std::sync::Arc;

use crate::error::Result;
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, Precision};
use crate::shared::OutlierPush;

/// Records a per-pixel kernel over a `width × height` grid (in bands, as
/// [`Batch::dispatch`]): the binding groups concatenated in order, `push`
/// as the push constants.
pub(crate) fn dispatch_groups<P: bytemuck::Pod>(
    batch: &mut Batch,
    decl: &KernelDecl,
    precision: Precision,
    push: &P,
    (width, height): (u32, u32),
    groups: &[&[BufferSlice]],
    flops_per_pixel: f64,
) -> Result<()> {
    let bindings: Vec<BufferSlice> = groups.concat();
    batch.dispatch(
        decl,
        precision,
        &bindings,
        bytemuck::bytes_of(push),
        width,
        height,
        flops_per_pixel,
    )
}

/// Records a per-pixel kernel over the image its push constants name
/// (their first two u32, width and height: the convention of every kernel,
/// [`crate::gpu::reflect::Extent::Planes`]): the binding groups concatenated
/// in order.
pub(crate) fn dispatch_image<P: bytemuck::Pod>(
    batch: &mut Batch,
    decl: &KernelDecl,
    precision: Precision,
    push: &P,
    groups: &[&[BufferSlice]],
    flops_per_pixel: f64,
) -> Result<()> {
    let bytes = bytemuck::bytes_of(push);
    let word = |k: usize| u32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap());
    let size = (word(0), word(1));
    dispatch_groups(batch, decl, precision, push, size, groups, flops_per_pixel)
}

/// Records one of the outlier stage's kernels over the queue of detected
/// pixels (`outlier_detect`'s, whose header holds the indirect dispatch
/// arguments): the binding groups concatenated in order, one invocation per
/// entry. The cost estimate (`flops` and `bytes` per entry) assumes
/// [`outlier_median::DETECTED_FRACTION`] of the push's image is queued.
#[allow(clippy::too_many_arguments)]
pub(crate) fn dispatch_queued(
    batch: &mut Batch,
    decl: &KernelDecl,
    precision: Precision,
    push: &OutlierPush,
    groups: &[&[BufferSlice]],
    queue: BufferSlice,
    flops: f64,
    bytes: f64,
) -> Result<()> {
    let entries = push.width as f64 * push.height as f64 * outlier_median::DETECTED_FRACTION;
    batch.dispatch_indirect(
        decl,
        precision,
        &groups.concat(),
        bytemuck::bytes_of(push),
        queue.sub(0, 12)?,
        entries * flops,
        entries * bytes,
    )
}

/// Runs one kernel once on data held by the host: binding `i` gets
/// `inputs[i]` for `i < inputs.len()`; the following bindings are fresh
/// zeroed buffers of `outputs[j]` 32-bit words each (f32, or u32 bits for
/// counters), returned in order. For tests and benchmarks: it uploads and
/// downloads everything.
#[allow(clippy::too_many_arguments)]
pub fn run_planes(
    ctx: &Arc<GpuContext>,
    decl: &KernelDecl,
    precision: Precision,
    push: &[u8],
    width: usize,
    height: usize,
    inputs: &[&[f32]],
    outputs: &[usize],
    flops_per_pixel: f64,
) -> Result<(Vec<Vec<f32>>, Vec<crate::gpu::KernelTiming>)> {
    let bound: Vec<Bound> = inputs
        .iter()
        .map(|&p| Bound::In(p))
        .chain(outputs.iter().map(|&n| Bound::Out(n)))
        .collect();
    run_bound(
        ctx,
        decl,
        precision,
        push,
        (width, height),
        &bound,
        flops_per_pixel,
    )
}

/// One binding of [`run_bound`].
#[derive(Copy, Clone, Debug)]
pub enum Bound<'a> {
    /// A plane uploaded from the host.
    In(&'a [f32]),
    /// A fresh zeroed buffer of this many 32-bit words, read back.
    Out(usize),
}

/// [`run_planes`] with the inputs and outputs in any binding order (a
/// kernel whose inputs follow an output): binding `i` is `bindings[i]`;
/// returns the [`Bound::Out`] buffers' contents in order.
pub fn run_bound(
    ctx: &Arc<GpuContext>,
    decl: &KernelDecl,
    precision: Precision,
    push: &[u8],
    (width, height): (usize, usize),
    bindings: &[Bound],
    flops_per_pixel: f64,
) -> Result<(Vec<Vec<f32>>, Vec<crate::gpu::KernelTiming>)> {
    let mut buffers = Vec::with_capacity(bindings.len());
    for (i, b) in bindings.iter().enumerate() {
        buffers.push(match *b {
            Bound::In(p) => GpuBuffer::from_slice(ctx, &format!("{}.in{i}", decl.name), p)?,
            Bound::Out(len) => GpuBuffer::from_slice(
                ctx,
                &format!("{}.out{i}", decl.name),
                &vec![0.0f32; len.max(1)],
            )?,
        });
    }
    let slices: Vec<_> = buffers.iter().map(|b| b.slice()).collect();
    let mut batch = Batch::new(ctx)?;
    batch.dispatch(
        decl,
        precision,
        &slices,
        push,
        width as u32,
        height as u32,
        flops_per_pixel,
    )?;
    let timings = batch.finish()?;
    let outs = bindings
        .iter()
        .zip(&buffers)
        .filter_map(|(b, buf)| match *b {
            Bound::Out(len) => Some(buf.read_vec::<f32>(len)),
            Bound::In(_) => None,
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((outs, timings))
}
