//! Adaptive sampling (spec §9): from a method's error estimate to an integer
//! number of new samples per pixel whose total is exactly the pass budget.
//!
//! ```text
//! sample_priority  §9.1 r_i = (1/3) Σ ΔMSE[ch] / (f̂[ch]² + ε)   (per pixel)
//! gauss_smooth     §9.1 MAP-SMOOTH r ← G_σs(r)                   (σs > 0 only)
//! sample_reduce    max of r over valid pixels (+ "some pixel is invalid")
//! sample_reduce    S = Σ q_i   (q = r' as a 31-bit fraction of max r')
//! sample_reduce    U = Σ u_i,  u_i = floor(2^32 q_i / S)     (up-sweep)
//! sample_scan      exclusive offsets, top level down to level 1
//! sample_scan      P_i, Δn_i = floor(T P_i/U) − floor(T P_{i−1}/U)  → counts
//! ```
//!
//! Each reduction is a tree of levels of 64-element blocks, one workgroup per
//! block, combined in a fixed order; the prefix sum re-derives the leaf values
//! in its last pass, so nothing per pixel wider than 32 bits is stored and no
//! binding grows beyond one f32 plane. The allocation after `r` is integer
//! arithmetic only, hence bit-identical between [`record_sample_map`] and
//! [`run_cpu`] for the same `r` map ([`allocate_cpu`]).
//!
//! Deviation from the literal §9.2 step 1 (ROUNDING): `S` and `u_i` are not
//! computed from `r` in f64 but from `q_i`, the sanitised `r'_i` (f32) as an
//! exact 31-bit fixed-point fraction of the binade of `max r'`:
//! `S = Σ q_i` exactly (u64), `u_i = floor(2^32 q_i / S)` by exact u64
//! division. Vulkan does not require correctly-rounded f64 division, sums or
//! subnormal handling, so the literal formula could differ between devices;
//! this one cannot. It differs from the literal one only by the truncation of
//! `r'/max r'` to 2^-31 (pixels below `2^-31 max r'` get `u = 0`, where the
//! literal formula gives them `u ≤ 1` out of 2^32), and keeps every §9.2
//! and §9.4 property: `U ≤ 2^32` exactly, so `T·P_i < 2^64` for every u32
//! `T`; doubling every `r` only shifts exponents, so the counts are unchanged.

use std::sync::Arc;

use super::Method;
use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::kernels::{gauss_smooth, sample_priority, sample_reduce, sample_scan, sample_upsample};
use crate::reference;
use crate::reference::pyramid_pool::coarse_size;
use crate::shared::{
    PyramidPush, SamplePriorityPush, SampleTreePush, SmoothPush, SAMPLE_D_KFLAGS, SAMPLE_E_IS_DMSE,
};

/// `ε` of §9.1 for WLR, LP and APR.
pub const EPS_DEFAULT: f32 = 1e-3;
/// `ε` of §9.1 for AOS.
pub const EPS_AOS: f32 = 1e-4;
/// MAP-SMOOTH σs of WLR (§9.1); the plain mean uses 0 (no smoothing).
pub const SIGMA_WLR: f32 = 1.0;
/// MAP-SMOOTH σs of LP. Decision MAP-SMOOTH-LP (ours): 1 where the spec's
/// default is 0, for the reason of [`SIGMA_AOS`]; unsmoothed, LP's map
/// starved the ceiling beside the cornell lamp. It waited for
/// LP-PIXEL-TEST: before it, a smoothed map fed firefly clusters that LP
/// spread into blobs.
pub const SIGMA_LP: f32 = 1.0;
/// MAP-SMOOTH σs of AOS. Decision MAP-SMOOTH-AOS (ours): 2 where the spec's
/// default is 0. A regression method's error at a pixel falls with the
/// samples of its whole window, not of the pixel alone; unsmoothed, AOS's
/// map put its samples into isolated pixels and lost to uniform sampling.
pub const SIGMA_AOS: f32 = 2.0;
/// MAP-SMOOTH σs of APR. Decision MAP-SMOOTH-APR (ours): 4 where the spec's
/// default is 0, for the reason of [`SIGMA_AOS`] and APR's wider kernel
/// (`h = 14`).
pub const SIGMA_APR: f32 = 4.0;

/// How the `d` plane holds the local dimension `d_i` of §9.1.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum DimSource {
    /// The plane holds `d` itself (clamped to `>= 0`; APR's blended
    /// `tr H`, AOS's rank).
    #[default]
    Plain,
    /// The plane is WLR's `kflags = k + 16·flags` (§2.5): `d = floor(v) mod 16`.
    Kflags,
}

/// The per-method parameters of §9.1.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct SamplingParams {
    /// `ε` of `ΔMSE / (f̂² + ε)`; must be finite and `> 0`.
    pub eps: f32,
    /// MAP-SMOOTH σs in pixels; `<= 0` (or 0) disables the smoothing.
    pub sigma_s: f32,
    /// The error planes already hold `ΔMSE` (LP, §3.5): no `n^(-4/(d+4))`
    /// factor, and the `d` plane is not used.
    pub e_is_dmse: bool,
    /// How to read the `d` plane.
    pub dim: DimSource,
    /// Fraction of each map's budget spread uniformly over the pixels before
    /// the rest follows the priority (0: the spec's map; ours,
    /// SAMPLE-FLOOR). Must be in `[0, 1)`.
    pub floor: f32,
}

/// Splits a map's `budget` into what is spread evenly over the pixels
/// (`floor(floor·budget)`, by the exact cumulative rounding of §9.2 in
/// raster order: each pixel gets the floor or the ceiling of its share)
/// and what the priority distributes: the counts still sum to exactly
/// `budget`.
pub fn floor_split(budget: u32, floor: f32) -> (u32, u32) {
    if floor.is_nan() || floor <= 0.0 {
        return (0, budget);
    }
    let spread = (floor.min(1.0) as f64 * budget as f64).floor() as u32;
    (spread, budget - spread)
}

impl SamplingParams {
    /// The table of §9.1: WLR (`ε = 0.001`, `σs = 1`, `d` from kflags), LP
    /// (`ε = 0.001`, `σs` [`SIGMA_LP`], ΔMSE input), APR (`ε = 0.001`, `σs` [`SIGMA_APR`]), AOS
    /// (`ε = 0.0001`, `σs` [`SIGMA_AOS`]).
    /// [`Method::None`]: the unfiltered mean, `E_i = v_i` with `d_i = 0`.
    /// `options`' `sampling.smooth`, when set, replaces σs.
    pub fn for_method(method: Method) -> Result<SamplingParams> {
        Ok(method.info().sampling)
    }

    /// [`SamplingParams::for_method`] with `options`' `sampling.smooth`, when
    /// set, as σs.
    pub fn with_options(
        method: Method,
        options: &crate::options::Options,
    ) -> Result<SamplingParams> {
        let mut params = Self::for_method(method)?;
        if let Some(s) = options.number("sampling.smooth")? {
            params.sigma_s = s;
        }
        if let Some(f) = options.number("sampling.floor")? {
            params.floor = f;
        }
        Ok(params)
    }

    fn check(&self) -> Result<()> {
        if !(self.eps.is_finite() && self.eps > 0.0)
            || self.sigma_s.is_nan()
            || !(0.0..1.0).contains(&self.floor)
        {
            return Err(Error::InvalidArgument(format!(
                "sampling: ε must be finite and > 0, σs a number and the floor in [0, 1) (got ε = {}, σs = {}, floor = {})",
                self.eps, self.sigma_s, self.floor
            )));
        }
        Ok(())
    }

    fn push(&self, width: u32, height: u32) -> SamplePriorityPush {
        let mut flags = 0;
        if self.e_is_dmse {
            flags |= SAMPLE_E_IS_DMSE;
        }
        if self.dim == DimSource::Kflags {
            flags |= SAMPLE_D_KFLAGS;
        }
        SamplePriorityPush {
            width,
            height,
            flags,
            eps: self.eps,
            ..Default::default()
        }
    }
}

/// The GPU planes a method hands to [`record_sample_map`] (each one f32
/// plane of `width × height` pixels).
#[derive(Copy, Clone, Debug)]
pub struct SampleInputs {
    /// `E_i[ch]` (or `ΔMSE_i[ch]`), R, G, B; pass one plane three times for a
    /// shared estimate (WLR, AOS).
    pub error: [BufferSlice; 3],
    /// The local dimension plane (see [`DimSource`]); any plane if
    /// [`SamplingParams::e_is_dmse`].
    pub dim: BufferSlice,
    /// The filtered colour `f̂_i[ch]`, R, G, B.
    pub filtered: [BufferSlice; 3],
    /// The sample counts `n_i` (a pixel is valid iff `n_i >= 1`, §0.2).
    pub spp: BufferSlice,
}

/// The CPU twin of [`SampleInputs`]: slices of `width × height` values.
#[derive(Copy, Clone, Debug)]
pub struct CpuSampleInputs<'a> {
    /// `E_i[ch]` (or `ΔMSE_i[ch]`), R, G, B, as [`SampleInputs::error`].
    pub error: [&'a [f32]; 3],
    /// The local dimension `d_i`, as [`SampleInputs::dim`].
    pub dim: &'a [f32],
    /// The filtered colour `f̂_i[ch]`, R, G, B.
    pub filtered: [&'a [f32]; 3],
    /// The sample counts `n_i` (valid iff `n_i >= 1`, §0.2).
    pub spp: &'a [f32],
}

/// The levels of the reduction and scan trees for `n` pixels, as offsets
/// (in u64 entries) into one tree buffer. Level 0 is the pixels; level
/// `k >= 1` has `ceil(n_{k−1} / 64)` entries; the last level has one.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TreeLayout {
    /// Pixels.
    pub n: u32,
    /// `n_1 .. n_L` (so `levels.last() == 1`).
    pub levels: Vec<u32>,
    /// First entry of level `k` (index `k − 1`) of the max tree (the
    /// largest `r`, §9.1 sanitise).
    pub max_off: Vec<u32>,
    /// First entry of level `k` (index `k − 1`) of the q-sum tree
    /// (`S = sum_i q_i`, §9.2 step 1).
    pub q_off: Vec<u32>,
    /// First entry of level `k` (index `k − 1`) of the u-sum tree
    /// (`U = sum_i u_i`, §9.2 step 1).
    pub u_off: Vec<u32>,
    /// First entry of the exclusive offsets of level `k` (index `k − 1`),
    /// levels `1 .. L−1` only: the down-sweep of the prefix sum (§9.2 step 2).
    pub offs_off: Vec<u32>,
    /// Entries of the whole tree buffer.
    pub entries: u32,
}

impl TreeLayout {
    /// The layout for `n >= 1` pixels.
    pub fn new(n: u32) -> TreeLayout {
        let block = sample_reduce::BLOCK;
        let mut levels = vec![n.div_ceil(block).max(1)];
        while *levels.last().unwrap() > 1 {
            levels.push(levels.last().unwrap().div_ceil(block));
        }
        let mut at = 0u32;
        let mut region = |sizes: &[u32]| {
            sizes
                .iter()
                .map(|&s| {
                    let o = at;
                    at += s;
                    o
                })
                .collect::<Vec<u32>>()
        };
        let max_off = region(&levels);
        let q_off = region(&levels);
        let u_off = region(&levels);
        let offs_off = region(&levels[..levels.len() - 1]);
        TreeLayout {
            n,
            levels,
            max_off,
            q_off,
            u_off,
            offs_off,
            entries: at,
        }
    }

    fn top(off: &[u32]) -> u32 {
        *off.last().unwrap()
    }

    /// The dispatches of the allocation of `budget` with a `floor`
    /// fraction spread uniformly ([`floor_split`]), in order: `(is_scan,
    /// push)`. Shared by the GPU recording and the CPU chain so both run the
    /// same plan.
    pub fn plan(&self, budget: u32, floor: f32) -> Vec<(bool, SampleTreePush)> {
        let (spread, budget) = floor_split(budget, floor);
        let globals = SampleTreePush {
            max_off: Self::top(&self.max_off),
            s_off: Self::top(&self.q_off),
            u_off: Self::top(&self.u_off),
            budget,
            spread,
            par_off: sample_scan::NO_LEVEL,
            ..Default::default()
        };
        let l = self.levels.len();
        let mut out = Vec::new();
        for (leaf, inner, offs) in [
            (
                sample_reduce::MODE_LEAF_MAX,
                sample_reduce::MODE_MAX,
                &self.max_off,
            ),
            (
                sample_reduce::MODE_LEAF_Q,
                sample_reduce::MODE_SUM,
                &self.q_off,
            ),
            (
                sample_reduce::MODE_LEAF_U,
                sample_reduce::MODE_SUM,
                &self.u_off,
            ),
        ] {
            out.push((
                false,
                SampleTreePush {
                    mode: leaf,
                    n: self.n,
                    dst_off: offs[0],
                    ..globals
                },
            ));
            for k in 1..l {
                out.push((
                    false,
                    SampleTreePush {
                        mode: inner,
                        n: self.levels[k - 1],
                        src_off: offs[k - 1],
                        dst_off: offs[k],
                        ..globals
                    },
                ));
            }
        }
        // Down-sweep: level k (index k−1) for k = L−1 .. 1.
        for k in (1..l).rev() {
            out.push((
                true,
                SampleTreePush {
                    mode: sample_scan::MODE_INNER,
                    n: self.levels[k - 1],
                    src_off: self.u_off[k - 1],
                    dst_off: self.offs_off[k - 1],
                    par_off: if k < l - 1 {
                        self.offs_off[k]
                    } else {
                        sample_scan::NO_LEVEL
                    },
                    ..globals
                },
            ));
        }
        out.push((
            true,
            SampleTreePush {
                mode: sample_scan::MODE_LEAF,
                n: self.n,
                par_off: if l > 1 {
                    self.offs_off[0]
                } else {
                    sample_scan::NO_LEVEL
                },
                ..globals
            },
        ));
        out
    }
}

/// GPU scratch and output of the sampling map for one image size: the
/// priority map (and its smoothed copy), the tree buffer and the u32 count
/// plane. Allocate once per size; reusable for any number of
/// [`record_sample_map`] calls (each overwrites everything it reads).
#[derive(Debug)]
pub struct SamplingPlanes {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Plane 0: `r` of `sample_priority`; plane 1: `G_σs(r)`; planes 2–3:
    /// the smoothing's row sums.
    pub maps: PlaneSet,
    /// The reduction and scan trees ([`TreeLayout`]), u64 entries.
    pub tree: GpuBuffer,
    /// `Δn_i` per pixel, u32, raster order.
    pub counts: GpuBuffer,
    /// The tree levels for `width * height` pixels.
    pub layout: TreeLayout,
}

fn pixel_count(width: usize, height: usize) -> Result<u32> {
    let n = width.saturating_mul(height);
    if n == 0 || n > (u32::MAX - 64) as usize {
        return Err(Error::InvalidArgument(format!(
            "sampling: image of {width}×{height} pixels (need 1 ..= 2^32 − 65 pixels)"
        )));
    }
    Ok(n as u32)
}

impl SamplingPlanes {
    /// Allocates the planes for a `width × height` image (1 ..= 2^32 − 65
    /// pixels; one f32 plane must fit `maxStorageBufferRange`). The
    /// allocation's u64 integer arithmetic runs on pairs of 32-bit words
    /// (`spirv/lib/u64.glsl`): any device.
    pub fn new(ctx: &Arc<GpuContext>, width: usize, height: usize) -> Result<SamplingPlanes> {
        let n = pixel_count(width, height)?;
        let layout = TreeLayout::new(n);
        Ok(SamplingPlanes {
            width,
            height,
            maps: PlaneSet::new(ctx, "sampling.maps", n as usize, 4)?,
            tree: GpuBuffer::new(ctx, "sampling.tree", layout.entries as u64 * 8)?,
            counts: GpuBuffer::new(ctx, "sampling.counts", n as u64 * 4)?,
            layout,
        })
    }

    /// The priority map the allocation used (after MAP-SMOOTH when σs > 0),
    /// before the §9.1 sanitise of invalid pixels.
    pub fn priority(&self, params: &SamplingParams) -> BufferSlice {
        self.maps.plane(usize::from(params.sigma_s > 0.0))
    }
}

/// Records the whole §9 map into `batch`: priority (in `precision`),
/// optional MAP-SMOOTH, then the integer allocation of `budget` samples
/// ([`record_allocation`]). No CPU round trip; read the result with
/// [`download`] after the batch has run.
pub fn record_sample_map(
    batch: &mut Batch,
    precision: Precision,
    inputs: &SampleInputs,
    planes: &SamplingPlanes,
    budget: u32,
    params: &SamplingParams,
) -> Result<()> {
    record_priority(batch, precision, inputs, planes, params)?;
    record_allocation(
        batch,
        planes.priority(params),
        inputs.spp,
        planes,
        budget,
        params.floor,
    )
}

/// Records the priority map of §9.1 (in `precision`) and its optional
/// MAP-SMOOTH into `planes` ([`SamplingPlanes::priority`]): the part of
/// [`record_sample_map`] that is local to each pixel's neighbourhood.
pub fn record_priority(
    batch: &mut Batch,
    precision: Precision,
    inputs: &SampleInputs,
    planes: &SamplingPlanes,
    params: &SamplingParams,
) -> Result<()> {
    params.check()?;
    record_raw_priority(batch, precision, inputs, planes, params)?;
    record_smooth(batch, precision, inputs.spp, planes, params)
}

/// `sample_priority` over `planes`' image: §9.1's `r` of `inputs` into
/// plane 0, before MAP-SMOOTH.
fn record_raw_priority(
    batch: &mut Batch,
    precision: Precision,
    inputs: &SampleInputs,
    planes: &SamplingPlanes,
    params: &SamplingParams,
) -> Result<()> {
    sample_priority::record(
        batch,
        precision,
        params.push(planes.width as u32, planes.height as u32),
        inputs.error,
        inputs.dim,
        inputs.filtered,
        inputs.spp,
        planes.maps.plane(0),
    )
}

/// MAP-SMOOTH of `planes`' priority (plane 0 into plane 1) when σs > 0,
/// over the pixels whose counts `spp` are valid.
fn record_smooth(
    batch: &mut Batch,
    precision: Precision,
    spp: BufferSlice,
    planes: &SamplingPlanes,
    params: &SamplingParams,
) -> Result<()> {
    if params.sigma_s > 0.0 {
        gauss_smooth::record(
            batch,
            precision,
            planes.width as u32,
            planes.height as u32,
            params.sigma_s,
            planes.maps.plane(0),
            spp,
            [planes.maps.plane(2), planes.maps.plane(3)],
            planes.maps.plane(1),
        )?;
    }
    Ok(())
}

/// The whole §9 map of a coarse level (MAP-COARSE): the §9.1 priority of
/// `coarse_inputs` — a reconstruction of the statistics pooled over 2×2
/// blocks ([`crate::methods::pyramid::pool_cpu`]'s layout) — into
/// `coarse`'s plane 0, copied to the fine pixels of each block
/// (`sample_upsample`), MAP-SMOOTH at the fine resolution, and the
/// allocation of `budget` samples over the fine pixels, whose counts are
/// `spp`, into `planes`. [`coarse_run_cpu`] is its twin.
#[allow(clippy::too_many_arguments)]
pub fn record_coarse_sample_map(
    batch: &mut Batch,
    precision: Precision,
    coarse_inputs: &SampleInputs,
    coarse: &SamplingPlanes,
    spp: BufferSlice,
    planes: &SamplingPlanes,
    budget: u32,
    params: &SamplingParams,
) -> Result<()> {
    params.check()?;
    if coarse_size(planes.width, planes.height) != (coarse.width, coarse.height) {
        return Err(Error::InvalidArgument(format!(
            "sampling: a coarse map of {}x{} pixels for an image of {}x{}",
            coarse.width, coarse.height, planes.width, planes.height
        )));
    }
    record_raw_priority(batch, precision, coarse_inputs, coarse, params)?;
    let push = upsample_push((planes.width, planes.height));
    sample_upsample::record(
        batch,
        precision,
        &push,
        coarse.maps.plane(0),
        planes.maps.plane(0),
    )?;
    record_smooth(batch, precision, spp, planes, params)?;
    record_allocation(
        batch,
        planes.priority(params),
        spp,
        planes,
        budget,
        params.floor,
    )
}

/// `sample_upsample`'s push constants over a `(width, height)` image
/// from its coarse level ([`coarse_size`]).
pub fn upsample_push((width, height): (usize, usize)) -> PyramidPush {
    let (cw, ch) = coarse_size(width, height);
    PyramidPush {
        width: width as u32,
        height: height as u32,
        other_width: cw as u32,
        other_height: ch as u32,
        ..Default::default()
    }
}

/// Records §9.1 sanitise and §9.2 ROUNDING on a priority map `r` (f32 plane
/// of `planes.width × planes.height`): the counts, summing to exactly
/// `budget` (a `floor` fraction of it spread uniformly, [`floor_split`]),
/// land in `planes.counts`.
pub fn record_allocation(
    batch: &mut Batch,
    r: BufferSlice,
    spp: BufferSlice,
    planes: &SamplingPlanes,
    budget: u32,
    floor: f32,
) -> Result<()> {
    let tree = planes.tree.slice();
    for (scan, push) in planes.layout.plan(budget, floor) {
        if scan {
            sample_scan::record(batch, push, r, spp, tree, planes.counts.slice())?;
        } else {
            sample_reduce::record(batch, push, r, spp, tree)?;
        }
    }
    Ok(())
}

/// The counts `Δn_i` (raster order) of the last [`record_sample_map`] whose
/// batch has finished.
pub fn download(planes: &SamplingPlanes) -> Result<Vec<u32>> {
    planes.counts.read_vec::<u32>(planes.layout.n as usize)
}

/// The CPU path (`--backend cpu`): the scalar twins in the order of
/// [`record_sample_map`]. Returns the counts `Δn_i`, raster order.
pub fn run_cpu(
    width: usize,
    height: usize,
    inputs: &CpuSampleInputs,
    budget: u32,
    params: &SamplingParams,
) -> Result<Vec<u32>> {
    let r = priority_cpu(width, height, inputs, params)?;
    allocate_cpu(width, height, &r, inputs.spp, budget, params.floor)
}

/// The priority map of [`run_cpu`] (after MAP-SMOOTH when σs > 0).
pub fn priority_cpu(
    width: usize,
    height: usize,
    inputs: &CpuSampleInputs,
    params: &SamplingParams,
) -> Result<Vec<f32>> {
    let r = raw_priority_cpu(width, height, inputs, params)?;
    Ok(smooth_cpu(width, height, r, inputs.spp, params))
}

/// `sample_priority`'s twin over `inputs` (every plane checked).
fn raw_priority_cpu(
    width: usize,
    height: usize,
    inputs: &CpuSampleInputs,
    params: &SamplingParams,
) -> Result<Vec<f32>> {
    params.check()?;
    let n = pixel_count(width, height)? as usize;
    let all = inputs
        .error
        .iter()
        .chain(inputs.filtered.iter())
        .chain([&inputs.dim, &inputs.spp]);
    if all.into_iter().any(|p| p.len() != n) {
        return Err(Error::InvalidArgument(format!(
            "sampling: every input plane must hold {width}×{height} values"
        )));
    }
    let mut r = vec![0.0f32; n];
    reference::sample_priority::sample_priority(
        &params.push(width as u32, height as u32),
        inputs.error,
        inputs.dim,
        inputs.filtered,
        inputs.spp,
        &mut r,
    );
    Ok(r)
}

/// MAP-SMOOTH's twin: `r` smoothed over the valid pixels of `spp` when
/// σs > 0, else `r`.
fn smooth_cpu(
    width: usize,
    height: usize,
    r: Vec<f32>,
    spp: &[f32],
    params: &SamplingParams,
) -> Vec<f32> {
    if params.sigma_s <= 0.0 {
        return r;
    }
    let push = SmoothPush {
        width: width as u32,
        height: height as u32,
        radius: gauss_smooth::radius(params.sigma_s),
        sigma: params.sigma_s,
        ..Default::default()
    };
    let mut s = vec![0.0f32; width * height];
    reference::gauss_smooth::smooth(&push, &r, spp, &mut s);
    s
}

/// The twin of [`record_coarse_sample_map`]: the counts over the fine
/// `width × height` pixels (counts `spp`) of a map whose priority comes
/// from the coarse level's `coarse_inputs` (of [`coarse_size`]).
pub fn coarse_run_cpu(
    (width, height): (usize, usize),
    coarse_inputs: &CpuSampleInputs,
    spp: &[f32],
    budget: u32,
    params: &SamplingParams,
) -> Result<Vec<u32>> {
    let (cw, ch) = coarse_size(width, height);
    let coarse_r = raw_priority_cpu(cw, ch, coarse_inputs, params)?;
    let n = pixel_count(width, height)? as usize;
    if spp.len() != n {
        return Err(Error::InvalidArgument(format!(
            "sampling: spp must hold {width}×{height} values"
        )));
    }
    let push = upsample_push((width, height));
    let mut r = vec![0.0f32; n];
    reference::sample_upsample::sample_upsample(&push, &coarse_r, &mut r);
    let r = smooth_cpu(width, height, r, spp, params);
    allocate_cpu(width, height, &r, spp, budget, params.floor)
}

/// The twin of [`record_allocation`]: §9.1 sanitise and §9.2 ROUNDING of the
/// priority map `r`, bit-identical to the GPU result.
pub fn allocate_cpu(
    width: usize,
    height: usize,
    r: &[f32],
    spp: &[f32],
    budget: u32,
    floor: f32,
) -> Result<Vec<u32>> {
    let n = pixel_count(width, height)?;
    if r.len() != n as usize || spp.len() != n as usize {
        return Err(Error::InvalidArgument(format!(
            "sampling: r and spp must hold {width}×{height} values"
        )));
    }
    let layout = TreeLayout::new(n);
    let mut tree = vec![0u64; layout.entries as usize];
    let mut counts = vec![0u32; n as usize];
    for (scan, push) in layout.plan(budget, floor) {
        if scan {
            reference::sample_scan::sample_scan(&push, r, spp, &mut tree, &mut counts);
        } else {
            reference::sample_reduce::sample_reduce(&push, r, spp, &mut tree);
        }
    }
    Ok(counts)
}
