//! The whole GPU chain of one configuration, with its buffers: statistics
//! finalisation (from a renderer's accumulation planes) or uploaded
//! statistics → sanitation (§0.4) → optional G-buffer prefilter (§6) → the
//! method (§2, §3, or none) → per-pixel error and local dimension → optional
//! sample map (§9). Allocated once per image size and configuration, recorded
//! call after call; nothing goes through the CPU between the stages.
//!
//! The public facade ([`crate::Denoiser`]) wraps this; [`super::denoise`]
//! uses it for the GPU backend, so there is one GPU chain.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::accum::AccumLayout;
use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::options::Options;

use super::blend::BlendStage;
use super::gbf::{self, GbfPlanes};
use super::outliers::{self, OutlierPlanes};
use super::prepare::{self, PrepareReport, PrepareScratch};
use super::pyramid::PyramidStage;
use super::registry::{GpuStage, StageArgs, StageRun};
use super::sampling::{self, SampleInputs, SamplingParams, SamplingPlanes};
use super::stats::{self, GpuStats};
use super::temporal::{FilterRecord, Temporal, TemporalScales, TemporalStage, TemporalState};
use super::tiles::{self, Rect};
use super::{Method, Pass, Prefilter};
use crate::kernels::lp_temporal::TemporalIn;
use crate::kernels::pyramid_merge::Level;
use crate::shared::TEMPORAL_SOURCE_NONE;

/// What the chain reads.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ChainInput {
    /// A renderer's accumulation planes ([`crate::accum`]), finalised on the
    /// GPU at every call.
    Accum(AccumLayout),
    /// Per-pixel statistics with these layers (as a render-statistics file
    /// holds them), uploaded into the chain ([`GpuChain::upload`]) before a call.
    Stats {
        /// Image width in pixels.
        width: usize,
        /// Image height in pixels.
        height: usize,
        /// The layers present.
        layers: Vec<Layer>,
    },
}

impl ChainInput {
    /// The statistics of `img`: its size and layers.
    pub fn of_image(img: &StatsImage) -> ChainInput {
        ChainInput::Stats {
            width: img.width,
            height: img.height,
            layers: img.layers().map(|(l, _)| l).collect(),
        }
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        match self {
            ChainInput::Accum(l) => (l.width, l.height),
            ChainInput::Stats { width, height, .. } => (*width, *height),
        }
    }

    /// The statistics layers the chain's input holds.
    pub fn layers(&self) -> Vec<Layer> {
        match self {
            ChainInput::Accum(l) => stats::finalized_layers(l),
            ChainInput::Stats { layers, .. } => layers.clone(),
        }
    }
}

/// The configuration of a chain (see [`crate::Config`], which mirrors it).
#[derive(Clone, Debug)]
pub struct ChainConfig {
    /// The reconstruction.
    pub method: Method,
    /// Final or intermediate windows (§9.3).
    pub pass: Pass,
    /// Kernel arithmetic.
    pub precision: Precision,
    /// The G-buffer prefilter (§6).
    pub prefilter: Prefilter,
    /// Whether the outlier stage (§4.4) runs.
    pub outliers: bool,
    /// Method options (`--opt`).
    pub options: Options,
    /// Whether some pixel may have `1 ≤ spp < 2` (runs §0.4 step 3). Always
    /// true for accumulation input; for uploaded statistics the caller knows.
    pub low_spp: bool,
    /// Whether the debug planes are read back: without them (and without
    /// `error`) LP's gather skips the planes nobody reads.
    pub debug: bool,
    /// Whether the error estimate and the local dimension are read back.
    pub error: bool,
    /// The temporal stage after the method (§10): its state lives in the
    /// chain from call to call.
    pub temporal: Temporal,
    /// The pyramid's low band after the method (PYRAMID-LOWBAND): the same
    /// method on the 2×2-pooled statistics in a second chain, merged by the
    /// error estimates.
    pub pyramid: bool,
    /// The input blend after the method (INPUT-BLEND): the method's colour
    /// weighed against the input by the two errors, into the stage's own
    /// planes, before the outlier stage's restoration.
    pub input_blend: bool,
    /// With `temporal` on an adaptive pass's chain ([`Pass::Intermediate`]):
    /// the final chain's state, whose factor scales the sample map's error
    /// (TEMPORAL-MAP).
    pub temporal_state: Option<TemporalState>,
    /// An adaptive pass's map from a half-resolution reconstruction
    /// (MAP-COARSE, [`Pass::Intermediate`] only): the method runs on the
    /// statistics pooled over 2×2 blocks in a second chain, and each fine
    /// pixel takes its block's §9.1 priority. The fine level runs no
    /// method: its outputs are the sanitised input's (as `none`'s).
    pub coarse_map: bool,
}

/// Where a chain's image lies in a larger image of which it is one tile
/// ([`super::tiles`]); the default is a whole image.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct Placement {
    /// The image pixel of the chain's pixel `(0, 0)` (LP's candidate grids
    /// keep the image's phase, §3.5).
    pub origin: (u32, u32),
    /// Margins (the halo) whose sanitation repairs are not counted,
    /// `[left | top << 16, right | bottom << 16]`
    /// ([`crate::shared::SanitizePush::skip_lo`]).
    pub skip: [u32; 2],
    /// The whole image's sample totals when the chain is a tile of it
    /// (APR-COUNT-CAP); `None`: the chain's image is the whole.
    pub totals: Option<ImageTotals>,
}

/// An image's sample totals ([`crate::reference::spp_total::spp_total`]'s
/// words) at the full resolution and at the pyramid's coarse level
/// ([`ImageTotals::of`]).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct ImageTotals {
    /// The statistics' own.
    pub fine: [u32; 3],
    /// Their 2×2-pooled counts' (PYRAMID-LOWBAND).
    pub coarse: [u32; 3],
}

impl ImageTotals {
    /// The totals of a `width × height` image's sample counts.
    pub fn of(spp: &[f32], width: usize, height: usize) -> ImageTotals {
        let (cw, ch) = crate::reference::pyramid_pool::coarse_size(width, height);
        let mut pooled = vec![0.0f32; cw * ch];
        let push = super::pyramid::pool_push((width, height), crate::shared::PYRAMID_COUNT);
        crate::reference::pyramid_pool::pyramid_pool(&push, spp, spp, &mut pooled);
        ImageTotals {
            fine: crate::reference::spp_total::spp_total(spp),
            coarse: crate::reference::spp_total::spp_total(&pooled),
        }
    }
}

/// Whether the G-buffer prefilter runs for `method` with `prefilter` on an
/// input with `layers` ([`Prefilter::resolve`]: `none` and AOS prefilter
/// only when asked explicitly, as `mcdenoise prefilter` does for `none`).
pub fn prefilter_runs(method: Method, prefilter: Prefilter, layers: &[Layer]) -> Result<bool> {
    gbf::wanted(method, prefilter, |l| layers.contains(&l))
}

/// The GPU chain of one configuration. See the module documentation.
pub struct GpuChain {
    ctx: Arc<GpuContext>,
    input_kind: ChainInput,
    config: ChainConfig,
    /// The statistics: uploaded or finalised, then sanitised, filtered and
    /// prefiltered in place by every call (their planes are
    /// [`prepare::output_layers`] of the source's).
    stats: GpuStats,
    /// Whether `stats` holds an upload no call has consumed yet
    /// ([`ChainInput::Stats`]).
    uploaded: AtomicBool,
    scratch: PrepareScratch,
    gbf: Option<GbfPlanes>,
    outliers: Option<OutlierPlanes>,
    method: Box<dyn GpuStage>,
    /// The sample map's planes and parameters (every device has them).
    sampling: (SamplingPlanes, SamplingParams),
    /// The pyramid's coarse level and merge ([`ChainConfig::pyramid`]).
    pyramid: Option<PyramidStage>,
    /// The input blend ([`ChainConfig::input_blend`]).
    blend: Option<BlendStage>,
    /// The temporal stage ([`ChainConfig::temporal`]).
    temporal: Option<TemporalRole>,
    /// The half-resolution chain whose map this one's is
    /// ([`ChainConfig::coarse_map`]).
    coarse_map: Option<Box<GpuChain>>,
    /// `config` as the method sees it: with the error estimate computed
    /// when the temporal stage reads it.
    stage_config: ChainConfig,
}

/// What a chain does with a temporal stage.
enum TemporalRole {
    /// A final reconstruction: filters its output with the stage it owns.
    Filter(Arc<TemporalStage>),
    /// An adaptive pass: scales the sample map's error by the factor the
    /// final chain's stage gives (TEMPORAL-MAP), into these three planes.
    Gain(Arc<TemporalStage>, PlaneSet),
}

impl std::fmt::Debug for GpuChain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuChain")
            .field("input", &self.input_kind)
            .field("method", &self.config.method)
            .field("prefilter", &self.gbf.is_some())
            .field("outliers", &self.outliers.is_some())
            .field("pyramid", &self.pyramid.is_some())
            .field("input_blend", &self.blend.is_some())
            .field("temporal", &self.config.temporal)
            .field("coarse_map", &self.coarse_map.is_some())
            .finish()
    }
}

pub use super::registry::REGRESSION_LAYERS;

/// Checks that `layers` hold what `method` reads.
pub fn check_layers(method: Method, layers: &[Layer]) -> Result<()> {
    for l in method.info().needs {
        if !layers.contains(l) {
            return Err(Error::BadData(format!(
                "{} needs the {} layer",
                method.name().to_uppercase(),
                l.name()
            )));
        }
    }
    Ok(())
}

/// Bytes of arena the stages before the method need for a `n`-pixel image
/// (their lifetimes do not overlap): sanitation's, the prefilter's when
/// `with_gbf`, and the outlier stage's scratch from byte `outliers` when
/// given.
pub fn front_arena_bytes(n: usize, with_gbf: bool, outliers: Option<u64>) -> u64 {
    let gbf = if with_gbf {
        PlaneSet::bytes(n, gbf::PLANES)
    } else {
        0
    };
    let outliers = outliers.map_or(0, |at| at + PlaneSet::bytes(n, outliers::SCRATCH));
    PlaneSet::bytes(n, prepare::PLANES).max(gbf).max(outliers)
}

/// `Err` unless `config` can make a coarse map (MAP-COARSE) of a `size`
/// image: an adaptive pass's chain of a method with a reconstruction on a
/// large enough image ([`check_coarse_size`]), without the stages of a
/// final reconstruction or a temporal stage.
pub fn check_coarse_map(config: &ChainConfig, size: (usize, usize)) -> Result<()> {
    let refuse = |why: &str| {
        Err(Error::InvalidArgument(format!(
            "a coarse sample map (MAP-COARSE) {why}"
        )))
    };
    if config.pass != Pass::Intermediate {
        return refuse("is an adaptive pass's (Pass::Intermediate)");
    }
    if config.pyramid || config.input_blend {
        return refuse(
            "runs neither the pyramid nor the input blend (final reconstructions' stages)",
        );
    }
    if config.temporal != Temporal::Off {
        return refuse("does not read the temporal filter's state");
    }
    check_coarse_size(config.method, size)
}

/// `Err` unless `method` can make a coarse map (MAP-COARSE) of a `size`
/// image ([`super::pyramid::check_level`]).
pub fn check_coarse_size(method: Method, size: (usize, usize)) -> Result<()> {
    super::pyramid::check_level("a coarse sample map (MAP-COARSE)", method, size)
}

/// The checks every chain makes before it allocates: `precision` on this
/// device, and a non-empty image.
pub fn check_device(ctx: &GpuContext, precision: Precision, (w, h): (usize, usize)) -> Result<()> {
    if precision == Precision::F64 && !ctx.supports_f64() {
        return Err(Error::InvalidArgument(
            "f64 kernels need shaderFloat64, which this device does not enable".into(),
        ));
    }
    if w == 0 || h == 0 {
        return Err(Error::InvalidArgument(format!("empty image ({w}x{h})")));
    }
    Ok(())
}

impl GpuChain {
    /// Allocates every buffer of the chain and checks the configuration.
    pub fn new(ctx: &Arc<GpuContext>, input: ChainInput, config: ChainConfig) -> Result<GpuChain> {
        let (w, h) = input.size();
        check_device(ctx, config.precision, (w, h))?;
        config.temporal.refuse_window()?;
        let layers = input.layers();
        check_layers(config.method, &layers)?;
        let config = ChainConfig {
            options: (config.method.info().options_for)(&config.options, &layers),
            ..config
        };
        if let Some(l) = config.temporal.needs().iter().find(|l| !layers.contains(l)) {
            return Err(Error::BadData(format!(
                "the temporal filter ({:?}) needs the {} layer",
                config.temporal,
                l.name()
            )));
        }
        if config.coarse_map {
            check_coarse_map(&config, (w, h))?;
        }
        // One set of planes: the source's statistics are sanitised in place
        // (prepare::record_prepare), with room for the variances it estimates.
        let stats = GpuStats::new(ctx, "chain.stats", w, h, &prepare::output_layers(&layers))?;
        // Stage scratch whose lifetimes do not overlap shares one arena:
        // sanitation's, the outlier stage's (before the prefilter, and again
        // after the method), the prefilter's, LP's state plane 0, queue and
        // packed features, WLR's scratch. LP's first state plane is read
        // after the run, so the outlier scratch starts after it (and
        // overlaps LP's queue and packed features, dead by then).
        let n = w * h;
        let method_gbf = prefilter_runs(config.method, config.prefilter, &layers)?;
        // With a coarse map the method runs at half resolution only: the
        // fine level is `none`'s, without the prefilter or outlier stage.
        let with_gbf = method_gbf && !config.coarse_map;
        let fine_method = match config.coarse_map {
            true => Method::None,
            false => config.method,
        };
        // The temporal filter (TEMPORAL-INFLATE), the pyramid's merge and
        // the input blend read the method's error estimate: the method
        // computes it even when it is not downloaded.
        let stage_config = ChainConfig {
            method: fine_method,
            outliers: config.outliers && !config.coarse_map,
            error: config.error
                || config.temporal != Temporal::Off
                || config.pyramid
                || config.input_blend,
            ..config.clone()
        };
        let info = fine_method.info();
        let keep = (info.arena_kept)(n);
        let arena_bytes = [
            front_arena_bytes(n, with_gbf, stage_config.outliers.then_some(keep)),
            (info.arena_bytes)(&stage_config, (w, h)),
        ];
        let arena = match arena_bytes.iter().max() {
            Some(&b) if b > 0 => Some(Arc::new(GpuBuffer::new(ctx, "chain.arena", b)?)),
            _ => None,
        };
        let scratch = PrepareScratch::new(ctx, &stats, arena.as_ref())?;
        let gbf = if with_gbf {
            Some(GbfPlanes::new(
                ctx,
                w,
                h,
                arena.as_ref(),
                gbf::GbfSettings::new(&config.options, config.method, config.pass)?,
            )?)
        } else {
            None
        };
        let outliers = if stage_config.outliers {
            Some(OutlierPlanes::new(
                ctx,
                w,
                h,
                outliers::Detection::of(&config.options)?,
                outliers::wide_fraction(&config.options)?,
                arena.as_ref().map(|a| (a, keep)),
            )?)
        } else {
            None
        };
        let method = (info.gpu)(&StageArgs {
            ctx,
            config: &stage_config,
            size: (w, h),
            arena: arena.as_ref(),
        })?;
        let params = SamplingParams::with_options(config.method, &config.options)?;
        let sampling = (SamplingPlanes::new(ctx, w, h)?, params);
        let temporal = match (config.temporal, config.pass, &config.temporal_state) {
            (Temporal::Off, _, _) => None,
            (Temporal::Apr | Temporal::LpSmooth, _, _) => unreachable!("refused above"),
            (Temporal::Lp, Pass::Final, None) => {
                let stage = TemporalStage::new(ctx, w, h)?;
                let info = config.method.info();
                let inflate = config.options.number::<f64>("temporal.inflate")?;
                stage.set_scales(TemporalScales {
                    error: info.error_scale_with(config.pyramid) as f32,
                    inflate: inflate.unwrap_or(info.inflate_scale) as f32,
                });
                Some(TemporalRole::Filter(Arc::new(stage)))
            }
            (Temporal::Lp, Pass::Intermediate, Some(TemporalState(stage))) => {
                if stage.size() != (w, h) {
                    return Err(Error::InvalidArgument(format!(
                        "the temporal state is of {:?} pixels, the image {w}x{h}",
                        stage.size()
                    )));
                }
                let scaled = PlaneSet::new(ctx, "chain.temporal_error", w * h, 3)?;
                Some(TemporalRole::Gain(stage.clone(), scaled))
            }
            (Temporal::Lp, Pass::Final, Some(_)) => {
                return Err(Error::InvalidArgument(
                    "a final reconstruction owns its temporal state: temporal_state is for an adaptive pass's denoiser".into(),
                ))
            }
            (Temporal::Lp, Pass::Intermediate, None) => {
                return Err(Error::InvalidArgument(
                    "an adaptive pass's temporal stage reads the final denoiser's state: set temporal_state (Denoiser::temporal_state)".into(),
                ))
            }
        };
        let pyramid = if config.pyramid {
            Some(PyramidStage::new(ctx, (w, h), &layers, &config, with_gbf)?)
        } else {
            None
        };
        let blend = if config.input_blend {
            Some(BlendStage::new(
                ctx,
                (w, h),
                config.method,
                &config.options,
            )?)
        } else {
            None
        };
        let coarse_map = if config.coarse_map {
            let (cw, ch) = crate::reference::pyramid_pool::coarse_size(w, h);
            let coarse_config = ChainConfig {
                coarse_map: false,
                prefilter: if method_gbf {
                    Prefilter::On
                } else {
                    Prefilter::Off
                },
                debug: false,
                error: true,
                ..config.clone()
            };
            let input = ChainInput::Stats {
                width: cw,
                height: ch,
                layers: prepare::output_layers(&layers),
            };
            Some(Box::new(GpuChain::new(ctx, input, coarse_config)?))
        } else {
            None
        };
        let chain = GpuChain {
            ctx: ctx.clone(),
            input_kind: input,
            config,
            stats,
            uploaded: AtomicBool::new(false),
            scratch,
            gbf,
            outliers,
            method,
            sampling,
            pyramid,
            blend,
            temporal,
            coarse_map,
            stage_config,
        };
        // Every pipeline of a run is built now (a counting batch records
        // nothing but builds them), while the chain's device memory is
        // untouched: lavapipe compiles with LLVM, whose transient heap would
        // otherwise add to the run's peak (BUILD-FIRST). So a kernel the
        // device cannot run (64-bit types, shared memory, bindings) is an
        // error here, never part-way through a recording. A renderer's
        // chain builds the sample map's kernels too; its accumulation
        // buffer is a stand-in the counting batch never binds.
        match chain.input_kind {
            ChainInput::Stats { .. } => chain.work(None, None)?,
            ChainInput::Accum(layout) => {
                let budget = Some(1);
                let accum = BufferSlice::placeholder(layout.bytes());
                chain.work(budget, Some(accum))?
            }
        };
        Ok(chain)
    }

    /// Bytes of the chain's buffers that grow with the width of a
    /// `width × height` image rather than its area (the rings of rows of LP
    /// and WLR), for the tiler's memory model.
    pub fn ring_bytes(config: &ChainConfig, width: usize, height: usize) -> u64 {
        if config.coarse_map {
            let (cw, ch) = crate::reference::pyramid_pool::coarse_size(width, height);
            let coarse = ChainConfig {
                coarse_map: false,
                ..config.clone()
            };
            return Self::ring_bytes(&coarse, cw, ch);
        }
        let own = (config.method.info().ring_bytes)(config, (width, height));
        if config.pyramid {
            let (cw, ch) = crate::reference::pyramid_pool::coarse_size(width, height);
            let coarse = ChainConfig {
                pyramid: false,
                ..config.clone()
            };
            own + Self::ring_bytes(&coarse, cw, ch)
        } else {
            own
        }
    }

    /// The context the chain's buffers live on.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        self.input_kind.size()
    }

    /// What the chain reads.
    pub fn input_kind(&self) -> &ChainInput {
        &self.input_kind
    }

    /// The configuration.
    pub fn config(&self) -> &ChainConfig {
        &self.config
    }

    /// Whether the G-buffer prefilter runs.
    pub fn prefiltered(&self) -> bool {
        self.gbf.is_some()
    }

    /// Uploads the statistics of one call ([`ChainInput::Stats`]; `img` has
    /// the chain's size and layers). Every call consumes its upload: the
    /// chain sanitises and prefilters the statistics in place.
    pub fn upload(&self, img: &StatsImage) -> Result<()> {
        self.ctx.check_alive()?;
        if self.input_kind != ChainInput::of_image(img) {
            return Err(Error::InvalidArgument(format!(
                "this denoiser was made for {:?}; the image is {}x{} with other layers",
                self.input_kind, img.width, img.height
            )));
        }
        self.uploaded.store(false, Ordering::SeqCst);
        self.stats.upload_image(img)?;
        self.uploaded.store(true, Ordering::SeqCst);
        Ok(())
    }

    /// The sanitised (and prefiltered) statistics after a run.
    pub fn clean(&self) -> &GpuStats {
        &self.stats
    }

    /// Records the chain. `accum` is the renderer's accumulation range for
    /// [`ChainInput::Accum`] (checked against the layout) and must be `None`
    /// for [`ChainInput::Stats`]. With a `budget`, the chain ends with the
    /// sample map of §9 for that many samples ([`GpuChain::samples`]).
    pub fn record(
        &self,
        batch: &mut Batch,
        accum: Option<BufferSlice>,
        budget: Option<u32>,
    ) -> Result<()> {
        self.record_method(batch, accum, Placement::default(), budget.is_some())?;
        if let Some(t) = budget {
            let (planes, params) = &self.sampling;
            let p = self.config.precision;
            match &self.coarse_map {
                Some(coarse) => sampling::record_coarse_sample_map(
                    batch,
                    p,
                    &coarse.sample_inputs(),
                    &coarse.sampling.0,
                    self.stats.plane(Layer::Spp, 0),
                    planes,
                    t,
                    params,
                )?,
                None => {
                    let inputs = self.sample_inputs();
                    sampling::record_sample_map(batch, p, &inputs, planes, t, params)?
                }
            }
        }
        Ok(())
    }

    /// Estimated floating-point operations of one [`record`](Self::record)
    /// (recorded into a counting batch: nothing runs).
    pub fn work(&self, budget: Option<u32>, accum: Option<BufferSlice>) -> Result<f64> {
        let mut b = Batch::counting(&self.ctx);
        self.record(&mut b, accum, budget)?;
        Ok(b.flops())
    }

    /// A batch progress hook that reports the completed fraction of a
    /// [`record`](Self::record) with these arguments to `f`.
    pub fn progress_fn(
        &self,
        budget: Option<u32>,
        accum: Option<BufferSlice>,
        f: super::ProgressCallback,
    ) -> Result<crate::gpu::ProgressFn> {
        let total = self.work(budget, accum)?.max(1.0);
        Ok(Arc::new(move |p: &crate::gpu::Progress| {
            f((p.done_flops / total).min(1.0), &p.kernel)
        }))
    }

    /// What the sample map reads (§9.1).
    fn sample_inputs(&self) -> SampleInputs {
        SampleInputs {
            error: self.sampling_error(),
            dim: self.dim_source().0,
            filtered: self.color(),
            spp: self.stats.plane(Layer::Spp, 0),
        }
    }

    /// What the sample map reads as `E` (§9.1): ΔMSE for LP, `MSE_c`
    /// without AOS-FEATNOISE for AOS, else `E_i`.
    fn sampling_error(&self) -> [BufferSlice; 3] {
        match &self.temporal {
            Some(TemporalRole::Gain(_, scaled)) => {
                [scaled.plane(0), scaled.plane(1), scaled.plane(2)]
            }
            _ => self.method.sampling_error(&self.stats),
        }
    }

    /// The sample counts (u32 per pixel) of the last run with a budget.
    pub fn samples(&self) -> Option<BufferSlice> {
        Some(self.sampling.0.counts.slice())
    }

    /// Downloads the sample counts of the last run with a budget.
    pub fn download_samples(&self) -> Result<Vec<u32>> {
        sampling::download(&self.sampling.0)
    }

    /// Records the chain as one tile of a larger image ([`super::tiles`]):
    /// no sample map allocation, but with `priority` the §9.1 priority map
    /// ([`download_priority_in`](Self::download_priority_in)), whose
    /// allocation runs over the whole image. Uploaded statistics only.
    pub fn record_tile(&self, batch: &mut Batch, at: Placement, priority: bool) -> Result<()> {
        if self.coarse_map.is_some() {
            return Err(Error::InvalidArgument(
                "a coarse map (MAP-COARSE) is made by one chain, not in tiles".into(),
            ));
        }
        self.record_method(batch, None, at, priority)?;
        if priority {
            let (planes, params) = &self.sampling;
            let inputs = self.sample_inputs();
            sampling::record_priority(batch, self.config.precision, &inputs, planes, params)?;
        }
        Ok(())
    }

    /// The priority map of the last [`record_tile`](Self::record_tile) with
    /// `priority`, cropped to `rect`.
    pub fn download_priority_in(&self, rect: Rect) -> Result<Vec<f32>> {
        let (planes, params) = &self.sampling;
        let (w, h) = self.size();
        let all = read(&self.ctx, planes.priority(params), w * h)?;
        Ok(tiles::crop(&all, w, rect))
    }

    /// The chain up to the method's outputs; `maps`: the sample map or its
    /// priority reads them after.
    fn record_method(
        &self,
        batch: &mut Batch,
        accum: Option<BufferSlice>,
        at: Placement,
        maps: bool,
    ) -> Result<()> {
        let p = self.config.precision;
        match (&self.input_kind, accum) {
            (ChainInput::Accum(layout), Some(a)) => {
                stats::record_finalize(batch, p, layout, a, &self.stats)?
            }
            (ChainInput::Stats { .. }, None) => {
                // A counting batch runs nothing, so it neither needs nor
                // consumes an upload; a real run consumes the one it reads.
                if !batch.is_counting() && !self.uploaded.swap(false, Ordering::SeqCst) {
                    return Err(Error::InvalidArgument(
                        "no statistics uploaded for this call: every call sanitises its upload in place, so upload the statistics again before each call (Denoiser::upload, or Denoiser::denoise)".into(),
                    ));
                }
            }
            (ChainInput::Accum(_), None) => {
                return Err(Error::InvalidArgument(
                    "this chain reads accumulation planes: pass the buffer".into(),
                ))
            }
            (ChainInput::Stats { .. }, Some(_)) => {
                return Err(Error::InvalidArgument(
                    "this chain reads uploaded statistics, not accumulation planes".into(),
                ))
            }
        }
        prepare::record_prepare(
            batch,
            p,
            &self.input_kind.layers(),
            &self.stats,
            &self.scratch,
            self.config.low_spp,
            at.skip,
        )?;
        if let Some(py) = &self.pyramid {
            py.record_coarse(
                batch,
                p,
                &self.stats,
                at.origin,
                at.totals.map(|t| t.coarse),
            )?;
        }
        // The coarse level is for the map only: a call without a budget
        // reads nothing of it.
        if let (Some(coarse), true) = (&self.coarse_map, maps) {
            super::pyramid::record_pool(batch, p, self.size(), &self.stats, coarse.clean())?;
            coarse.record_pooled(batch, (0, 0), None, maps)?;
        }
        if let Some(o) = &self.outliers {
            outliers::record_remove(batch, p, &self.stats, o)?;
        }
        let run = |prefiltered| StageRun {
            precision: p,
            stats: &self.stats,
            config: &self.stage_config,
            maps,
            origin: at.origin,
            prefiltered,
            spp_total: at.totals.map(|t| t.fine),
            visibility: None,
        };
        if let Some(g) = &self.gbf {
            self.method.record_unfiltered(batch, &run(false))?;
            gbf::record_gbf(batch, p, &self.stats, g)?;
        }
        self.method.record(batch, &run(self.gbf.is_some()))?;
        if let Some(b) = &self.blend {
            let error = self.method.error(&self.stats);
            b.record(batch, p, self.method_color(), error, &self.stats)?;
        }
        let spp = self.stats.plane(Layer::Spp, 0);
        if let Some(o) = &self.outliers {
            outliers::record_restore(batch, p, spp, self.fine_color(), o)?;
        }
        if let Some(py) = &self.pyramid {
            let fine = Level {
                color: self.fine_color(),
                error: self.fine_error(),
                spp,
            };
            py.record_merge(batch, p, &fine)?;
        }
        match &self.temporal {
            Some(TemporalRole::Filter(t)) => t.record(batch, p, &self.temporal_in())?,
            Some(TemporalRole::Gain(t, scaled)) if maps => {
                let error = self.method.sampling_error(&self.stats);
                let to = [scaled.plane(0), scaled.plane(1), scaled.plane(2)];
                t.record_gain(batch, p, &self.temporal_in(), error, to)?
            }
            _ => {}
        }
        Ok(())
    }

    /// Records the coarse level of a pyramid ([`PyramidStage`]) after its
    /// statistics were pooled into [`clean`](Self::clean): the chain up to
    /// its method's outputs.
    /// `origin`: the coarse image pixel of its pixel `(0, 0)` (a tile's).
    /// `total`: the whole coarse image's sample total when this is a tile.
    /// `maps`: its sample map's inputs are read after
    /// ([`ChainConfig::coarse_map`]).
    pub(super) fn record_pooled(
        &self,
        batch: &mut Batch,
        origin: (u32, u32),
        total: Option<[u32; 3]>,
        maps: bool,
    ) -> Result<()> {
        if !batch.is_counting() {
            self.uploaded.store(true, Ordering::SeqCst);
        }
        let at = Placement {
            origin,
            skip: [0, 0],
            totals: total.map(|fine| ImageTotals {
                fine,
                coarse: [0; 3],
            }),
        };
        self.record_method(batch, None, at, maps)
    }

    /// What the temporal stage reads: the spatial reconstruction and the
    /// statistics' planes.
    fn temporal_in(&self) -> TemporalIn {
        let three = |l| std::array::from_fn(|k| self.stats.plane(l, k));
        TemporalIn {
            color: self.spatial_color(),
            position: three(Layer::Position),
            position_variance: three(Layer::PositionVariance),
            depth: self.stats.plane(Layer::Depth, 0),
            spp: self.stats.plane(Layer::Spp, 0),
            error: self.spatial_error(),
        }
    }

    /// The handle on the temporal stage's state of a final chain with
    /// one, for an adaptive pass's chain ([`ChainConfig::temporal_state`]).
    pub fn temporal_state(&self) -> Option<TemporalState> {
        match &self.temporal {
            Some(TemporalRole::Filter(t)) => Some(TemporalState(t.clone())),
            _ => None,
        }
    }

    /// The host copy of what the temporal filter read and made on the last
    /// call (TEMPORAL-SMOOTH); `None` without a filter.
    pub fn temporal_record(&self) -> Result<Option<FilterRecord>> {
        match &self.temporal {
            Some(TemporalRole::Filter(t)) => {
                Ok(Some(t.download_record(&self.ctx, &self.temporal_in())?))
            }
            _ => Ok(None),
        }
    }

    /// Forgets the temporal stage's history (a cut): the next call
    /// reinitialises every pixel. Nothing without a temporal stage.
    pub fn reset_temporal(&self) {
        if let Some(TemporalRole::Filter(t)) = &self.temporal {
            t.reset();
        }
    }

    /// Whether the outlier stage runs.
    pub fn removes_outliers(&self) -> bool {
        self.outliers.is_some()
    }

    /// The reconstruction's colour planes R, G, B (method `none`: the
    /// sanitised input, not yet clamped): the temporal stage's output when
    /// there is one.
    pub fn color(&self) -> [BufferSlice; 3] {
        match &self.temporal {
            Some(TemporalRole::Filter(t)) => t.color(),
            _ => self.spatial_color(),
        }
    }

    /// The spatial reconstruction's colour: the pyramid's merge when there
    /// is one, else [`fine_color`](Self::fine_color).
    pub fn spatial_color(&self) -> [BufferSlice; 3] {
        match &self.pyramid {
            Some(py) => py.color(),
            None => self.fine_color(),
        }
    }

    /// The full-resolution reconstruction after the outlier stage: the
    /// input blend's when it runs, else the method's.
    pub fn fine_color(&self) -> [BufferSlice; 3] {
        match &self.blend {
            Some(b) => b.color(),
            None => self.method_color(),
        }
    }

    /// The error estimate of [`spatial_color`](Self::spatial_color).
    fn spatial_error(&self) -> [BufferSlice; 3] {
        match &self.pyramid {
            Some(py) => py.error(),
            None => self.fine_error(),
        }
    }

    /// The error estimate of [`fine_color`](Self::fine_color).
    fn fine_error(&self) -> [BufferSlice; 3] {
        match &self.blend {
            Some(b) => b.error(),
            None => self.method.error(&self.stats),
        }
    }

    /// The method's colour planes (after the outlier stage unless the
    /// input blend runs), before the input blend, the pyramid's merge and
    /// any temporal stage.
    pub fn method_color(&self) -> [BufferSlice; 3] {
        self.method.color(&self.stats)
    }

    /// The per-pixel error estimate `E_i` per channel (§9.1): WLR's shared
    /// MSE three times, LP's per-channel estimate, and for `none` the
    /// variance of the mean (the MSE of the unfiltered input); the input
    /// blend's when it runs, and the pyramid's merged estimate when that
    /// runs.
    pub fn error(&self) -> [BufferSlice; 3] {
        self.spatial_error()
    }

    /// The plane the local dimension `d_i` (§9.1) is read from and how:
    /// `(plane, true)` when it is WLR's `kflags` (rank in `value mod 16`).
    pub fn dim_source(&self) -> (BufferSlice, bool) {
        self.method.dim()
    }

    /// Sanitation counters and the invalid pixels (`spp < 1`, §0.2) of the
    /// last completed run (§0.4).
    pub fn report(&self) -> Result<PrepareReport> {
        let counters = self.counters()?;
        let (w, h) = self.size();
        let spp = read(&self.ctx, self.stats.plane(Layer::Spp, 0), w * h)?;
        let invalid = spp
            .iter()
            .filter(|&&s| crate::reference::finalize_stats::spp_of(s) < 1.0)
            .count();
        Ok(PrepareReport {
            counters,
            estimated: Layer::WITH_VARIANCE
                .into_iter()
                .filter(|l| {
                    let layers = self.input_kind.layers();
                    layers.contains(l) && !layers.contains(&l.variance().unwrap())
                })
                .collect(),
            invalid_pixels: invalid,
            timings: Vec::new(),
        })
    }

    /// The sanitation counters of the last completed run (§0.4; a tile's
    /// skip its halo).
    pub fn counters(&self) -> Result<[u64; 4]> {
        self.scratch.read_counters()
    }

    /// Downloads the outputs of a completed run: the debug planes only with
    /// [`ChainConfig::debug`], the error estimate only with
    /// [`ChainConfig::error`] (else [`ChainOutput::error`] is empty, 0×0) —
    /// the kernels skip the planes the configuration does not read.
    pub fn download(&self) -> Result<ChainOutput> {
        self.download_whole(None)
    }

    /// [`download`](Self::download), every plane cropped to `rect` (a tile's
    /// interior) and the statistics computed over it.
    pub fn download_in(&self, rect: Option<Rect>) -> Result<ChainOutput> {
        let out = self.download_whole(rect)?;
        let Some(r) = rect else {
            return Ok(out);
        };
        let (w, h) = self.size();
        let c = |p: &[f32]| tiles::crop(p, w, r);
        let rgb = |i: &RgbImage| i.crop(r.x0, r.y0, r.width(), r.height());
        let mut debug_planes = Vec::with_capacity(out.debug.len());
        for (name, p) in &out.debug {
            if p.len() != w * h {
                return Err(Error::Limit(format!(
                    "the debug layer {name} is not one value per pixel: it cannot be tiled"
                )));
            }
            debug_planes.push((name.clone(), c(p)));
        }
        Ok(ChainOutput {
            color: rgb(&out.color),
            error: if self.config.error {
                rgb(&out.error)
            } else {
                RgbImage::new(0, 0)
            },
            dim: if self.config.error {
                c(&out.dim)
            } else {
                Vec::new()
            },
            debug: debug_planes,
            stats: out.stats,
        })
    }

    /// The whole planes; the statistics over `rect` (all pixels if `None`).
    fn download_whole(&self, rect: Option<Rect>) -> Result<ChainOutput> {
        let (debug, error) = (self.config.debug, self.config.error);
        let (w, h) = self.size();
        let rgb = |p: [BufferSlice; 3]| -> Result<RgbImage> {
            Ok(RgbImage::from_planes(
                w,
                h,
                [
                    read(&self.ctx, p[0], w * h)?,
                    read(&self.ctx, p[1], w * h)?,
                    read(&self.ctx, p[2], w * h)?,
                ],
            ))
        };
        // The local dimension comes with the error estimate (what a
        // caller of the sample map's inputs reads): not downloaded without
        // it, as the output is at its peak of host memory here.
        let (dim_plane, kflags) = self.dim_source();
        let mut dim = if error {
            read(&self.ctx, dim_plane, w * h)?
        } else {
            Vec::new()
        };
        if kflags {
            for v in &mut dim {
                *v = (*v as u32 % 16) as f32;
            }
        }
        let mut out = ChainOutput {
            color: rgb(self.color())?,
            error: if error {
                rgb(self.error())?
            } else {
                RgbImage::new(0, 0)
            },
            dim,
            debug: Vec::new(),
            stats: Vec::new(),
        };
        // `out.color` is the temporal stage's colour when there is one; a
        // method's download may replace it (`none` fills invalid pixels on
        // the host), which is kept only where the filter passed through.
        let filtered = match &self.temporal {
            Some(TemporalRole::Filter(_)) => Some(out.color.clone()),
            _ => None,
        };
        self.method
            .download(&self.stats, (w, h), rect, debug, &mut out)?;
        if let (true, Some(o)) = (debug, &self.outliers) {
            out.debug
                .extend(outliers::debug_layers(&outliers::download_excess(o)?));
        }
        if let (Some(TemporalRole::Filter(t)), Some(filtered)) = (&self.temporal, filtered) {
            let source = read(&self.ctx, t.source(), w * h)?;
            for (c, plane) in out.color.planes.iter_mut().enumerate() {
                for (i, v) in plane.iter_mut().enumerate() {
                    if source[i] != TEMPORAL_SOURCE_NONE {
                        *v = filtered.planes[c][i];
                    }
                }
            }
            if debug {
                out.debug.extend(t.debug_layers(source)?);
            }
        }
        if !error {
            out.error = RgbImage::new(0, 0);
        }
        Ok(out)
    }
}

/// `options` with the skip bit of every `(read, bit)` whose planes nobody
/// reads back.
pub(crate) fn skip_bits(options: u32, skip: &[(bool, u32)]) -> u32 {
    skip.iter()
        .filter(|(read, _)| !read)
        .fold(options, |o, (_, bit)| o | bit)
}

/// Reads `count` f32 values of a slice owned by mcdenoise.
fn read(ctx: &Arc<GpuContext>, s: BufferSlice, count: usize) -> Result<Vec<f32>> {
    crate::gpu::buffer::read_slice(ctx, s, count)
}

/// The host copy of a chain's outputs.
#[derive(Clone, Debug)]
pub struct ChainOutput {
    /// The reconstruction, clamped to ≥ 0 (spec §0.4 step 5).
    pub color: RgbImage,
    /// `E_i` per channel (§9.1); empty (0×0) when not downloaded.
    pub error: RgbImage,
    /// `d_i` (§9.1); empty when not downloaded (with the error estimate).
    pub dim: Vec<f32>,
    /// Named debug planes (when asked).
    pub debug: Vec<(String, Vec<f32>)>,
    /// Scalar statistics over the pixels downloaded (LP: `centre_fraction`,
    /// `centre_flops`, `covering`, [`crate::methods::lp::Census`]).
    pub stats: Vec<super::Tally>,
}
