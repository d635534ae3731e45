//! The public facade: [`Denoiser`]. See the crate documentation for the
//! object model and the synchronisation contract.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use ash::vk;

use crate::accum::AccumLayout;
use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuContext, KernelTiming, Precision, Recorded};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::methods::chain::{ChainConfig, ChainInput, GpuChain};
use crate::methods::prepare::PrepareReport;
use crate::methods::temporal::FilterRecord;
use crate::methods::tiles::{Choice, Tile, TiledChain};
use crate::methods::{
    self, Backend, DenoiseRequest, InputBlend, Method, Outliers, Pass, Prefilter, ProgressCallback,
    Pyramid, Temporal, TemporalState,
};
use crate::options::Options;

/// What a [`Denoiser`] is configured with. Everything that decides which
/// kernels run and which buffers exist; fixed for the denoiser's life.
#[derive(Clone, Debug)]
pub struct Config {
    /// The reconstruction method.
    pub method: Method,
    /// Final reconstruction or an adaptive pass's (spec §9.3 windows).
    pub pass: Pass,
    /// Kernel arithmetic (f64 needs `shaderFloat64`).
    pub precision: Precision,
    /// The G-buffer prefilter (§6).
    pub prefilter: Prefilter,
    /// The energy-preserving outlier stage (§4.4): `Auto` runs it for every
    /// reconstruction and not for `none`.
    pub outliers: Outliers,
    /// Method options, `key=value` as `mcdenoise denoise --help` lists them.
    pub options: Options,
    /// Keep the method's debug maps for [`Denoiser::read`].
    pub debug: bool,
    /// Download the error estimate into [`Frame::error`] and the local
    /// dimension into [`Frame::dim`] (the default). `false` skips the
    /// download of their four planes and leaves both empty; the sample map
    /// still reads them on the device.
    pub error: bool,
    /// Log progress (through `log`) for runs longer than about a second.
    pub progress: bool,
    /// Whether some pixel may have `1 <= spp < 2` (GPU backend). Spec §0.4
    /// step 3 gives such a pixel a variance from its neighbours, which costs
    /// one more pass over every channel (about 270 ms of a 256² call on
    /// lavapipe). `true` by default; a renderer that takes 0 or at least 2
    /// samples in every pixel sets `false` (the built-in adaptive loop does),
    /// and a caller holding the image on the host can use
    /// [`crate::has_low_spp`]. `false` with such pixels present leaves their
    /// one-sample variance (0) in place.
    pub low_spp: bool,
    /// Device memory cap in bytes for [`Source::Stats`] inputs: an image
    /// whose chain would need more is denoised in tiles that fit
    /// ([`crate::methods::tiles`]; bit-identical to a whole run). `None`:
    /// three quarters of the largest device-local heap.
    pub max_memory: Option<u64>,
    /// Tiles of at most this many pixels per side (plus their halo), even
    /// when the whole image would fit; `None` tiles only when needed.
    pub tile: Option<usize>,
    /// The pyramid's low band (PYRAMID-LOWBAND): the method also
    /// reconstructs the statistics pooled over 2×2 blocks, and the output
    /// takes its low band from that half-resolution reconstruction where
    /// the two error estimates say it is the better one — it removes
    /// low-frequency noise larger than the method's windows (light that
    /// arrives only indirectly). Costs 1.3–1.6× the GPU time and about a
    /// third more memory; the error estimate is the merged one, the sample
    /// map reads the method's. [`Pyramid::Auto`] (the default): on for
    /// `auto`'s final reconstruction ([`Pass::Final`]) of an image of at
    /// least 16×16 pixels, off otherwise; [`Pyramid::On`] needs a reconstruction (not `none`) and
    /// such an image. In tiles the halo doubles.
    pub pyramid: Pyramid,
    /// The input blend (INPUT-BLEND): the method's output and its input
    /// weighed per pixel and channel by the method's error estimate and
    /// the input's variance (floored by its mean over a small window
    /// without the window's largest values, BLEND-TRIM), so
    /// that where the method smooths across what its features do not show
    /// the output returns towards the input. The error estimate is the
    /// blend's, the sample map reads the method's. The method's error is
    /// read as at least what the residual `(f − y)²` shows beyond the
    /// input's variance (BLEND-RESIDUAL). [`InputBlend::Auto`] (the
    /// default): on in the final reconstruction ([`Pass::Final`]) of WLR,
    /// LP, APR and AOS, off for `auto` and in adaptive passes;
    /// [`InputBlend::On`] needs a reconstruction (not `none`). Parameters:
    /// `blend.radius`, `blend.k`, `blend.residual_radius`, `blend.z`.
    pub input_blend: InputBlend,
    /// A temporal stage after the method (spec §10): with
    /// [`Temporal::Lp`] every call filters the method's output with the
    /// history of the earlier calls (a sequence's frames, in order), kept
    /// on the GPU; [`Denoiser::reset`] at a cut. The colour outputs are
    /// the filtered ones; the error estimate and the sample map stay the
    /// method's. Needs the `position` and `depth` layers, the GPU and one
    /// chain (no tiles). [`Temporal::Apr`] is for a
    /// [`crate::SequenceDenoiser`]; a `Denoiser` refuses it.
    pub temporal: Temporal,
    /// For an adaptive pass's denoiser ([`Pass::Intermediate`]) with
    /// `temporal` set: the final denoiser's state
    /// ([`Denoiser::temporal_state`]). Its sample maps then weigh each
    /// pixel's error by what the temporal filter will make of the frame —
    /// less where a long history is reprojected, all of it where the pixel
    /// restarts (TEMPORAL-MAP) — and its colour is not filtered.
    pub temporal_state: Option<TemporalState>,
    /// For an adaptive pass's denoiser ([`Pass::Intermediate`]): make the
    /// sample map from a half-resolution reconstruction (MAP-COARSE). The
    /// method runs only on the statistics pooled over 2×2 blocks — about a
    /// quarter of its work — and each pixel takes its block's §9.1
    /// priority; MAP-SMOOTH and the allocation run at the full resolution.
    /// The colour and error outputs are then the sanitised input's and its
    /// variance (`none`'s): such a denoiser is for maps. Needs a method
    /// with a reconstruction (not `none`), an image of at least 16×16
    /// pixels, one chain (no tiles), and neither the pyramid, the input
    /// blend nor a temporal stage.
    pub coarse_map: bool,
}

impl Config {
    /// The factor a stop rule multiplies this configuration's estimated
    /// rMSE by on a `width × height` image: the method's
    /// [`crate::MethodInfo::error_scale`], or its `pyramid_error_scale`
    /// where the pyramid's low band runs (PYRAMID-ERROR-SCALE).
    pub fn error_scale(&self, width: usize, height: usize) -> f64 {
        let pyramid = self
            .pyramid
            .resolve(self.method, self.pass, (width, height));
        self.method.info().error_scale_with(pyramid)
    }

    /// `method` with defaults: final pass, f32, prefilter `auto`, no options.
    pub fn new(method: Method) -> Config {
        Config {
            method,
            pass: Pass::Final,
            precision: Precision::F32,
            prefilter: Prefilter::Auto,
            outliers: Outliers::Auto,
            options: Options::default(),
            debug: false,
            error: true,
            progress: false,
            low_spp: true,
            max_memory: None,
            tile: None,
            pyramid: Pyramid::Auto,
            input_blend: InputBlend::Auto,
            temporal: Temporal::Off,
            temporal_state: None,
            coarse_map: false,
        }
    }

    fn chain(&self, low_spp: bool, size: (usize, usize)) -> ChainConfig {
        ChainConfig {
            method: self.method,
            pass: self.pass,
            precision: self.precision,
            prefilter: self.prefilter,
            outliers: self.outliers.resolve(self.method),
            options: self.options.clone(),
            low_spp,
            debug: self.debug,
            error: self.error,
            pyramid: self.pyramid.resolve(self.method, self.pass, size),
            input_blend: self.input_blend.resolve(self.method, self.pass),
            temporal: self.temporal,
            temporal_state: self.temporal_state.clone(),
            coarse_map: self.coarse_map,
        }
    }

    /// `Err` unless this configuration can denoise `width × height` images
    /// (what [`Denoiser::new`] would refuse for the size alone: the
    /// pyramid's and a coarse map's method and smallest image), for a
    /// caller that wants to know before it renders.
    pub fn check_size(&self, width: usize, height: usize) -> Result<()> {
        if self.pyramid == Pyramid::On {
            methods::pyramid::check(self.method, (width, height))?;
        }
        if self.input_blend == InputBlend::On {
            methods::blend::check(self.method)?;
        }
        if self.coarse_map {
            methods::chain::check_coarse_size(self.method, (width, height))?;
        }
        Ok(())
    }

    /// `Err` if this is a coarse-map configuration ([`Config::coarse_map`])
    /// that [`Denoiser::new`] would refuse for `width × height` images:
    /// not an adaptive pass's, with the pyramid, the input blend or a
    /// temporal filter, or on too small an image (MAP-COARSE); for a caller
    /// that wants to know before it renders. `Ok` without a coarse map.
    pub fn check_coarse_map(&self, width: usize, height: usize) -> Result<()> {
        if !self.coarse_map {
            return Ok(());
        }
        let size = (width, height);
        methods::chain::check_coarse_map(&self.chain(self.low_spp, size), size)
    }

    fn request(&self, backend: Backend, size: (usize, usize)) -> DenoiseRequest {
        let mut r = DenoiseRequest::new(self.method);
        r.backend = backend;
        r.pass = self.pass;
        r.precision = self.precision;
        r.prefilter = self.prefilter;
        r.outliers = self.outliers;
        r.options = self.options.clone();
        r.error = self.error;
        r.debug = self.debug;
        r.pyramid = self.pyramid.resolve(self.method, self.pass, size);
        r.input_blend = self.input_blend.resolve(self.method, self.pass);
        r.progress = self.progress;
        r.coarse_map = self.coarse_map;
        r
    }
}

/// The device memory cap a [`Denoiser`] on `device` uses when
/// [`Config::max_memory`] is `None` (three quarters of its largest
/// device-local heap).
pub fn default_memory_cap(device: &crate::gpu::DeviceInfo) -> u64 {
    crate::methods::tiles::default_cap(device)
}

/// What a [`Denoiser`] reads at each call.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    /// A renderer's accumulation planes on the GPU (layout in
    /// [`crate::accum`]): Σx and Σx² per scalar channel, the position cross
    /// products, the sample count.
    Accum(AccumLayout),
    /// Per-pixel statistics in host memory or a file, with these layers
    /// ([`Denoiser::denoise`] uploads them; [`Denoiser::upload`] before each
    /// [`Denoiser::run`] or recording).
    Stats {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// The layers present.
        layers: Vec<Layer>,
    },
}

impl Source {
    /// The source matching a statistics image.
    pub fn of_image(img: &StatsImage) -> Source {
        Source::Stats {
            width: img.width,
            height: img.height,
            layers: img.layers().map(|(l, _)| l).collect(),
        }
    }

    fn chain(&self) -> ChainInput {
        match self {
            Source::Accum(l) => ChainInput::Accum(*l),
            Source::Stats {
                width,
                height,
                layers,
            } => ChainInput::Stats {
                width: *width,
                height: *height,
                layers: layers.clone(),
            },
        }
    }
}

/// The GPU-resident outputs of a [`Denoiser`]: planes of `width × height`
/// values in row-major order, owned by the denoiser and valid while it
/// lives; overwritten by every call. A host binds them in its own shaders
/// (the renderer's next pass reads `samples`).
#[derive(Copy, Clone, Debug)]
pub struct Outputs {
    /// Reconstructed colour R, G, B (f32).
    pub color: [BufferSlice; 3],
    /// Estimated MSE `E_i` per channel (f32; §9.1).
    pub error: [BufferSlice; 3],
    /// Next pass's samples per pixel (u32), valid after a call with a
    /// budget; `Some` on every device (the allocation's 64-bit integers are
    /// pairs of 32-bit words: no `shaderInt64` needed).
    pub samples: Option<BufferSlice>,
}

/// The host copy of a call's results.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The reconstruction, clamped to ≥ 0 (spec §0.4 step 5).
    pub color: RgbImage,
    /// Estimated MSE `E_i` per pixel and channel (§9.1): WLR's shared
    /// estimate in all three channels; for `none` the variance of the mean.
    /// Empty (0×0) when [`Config::error`] is `false`.
    pub error: RgbImage,
    /// The local dimension `d_i` per pixel (§9.1): the TSVD rank for WLR,
    /// the covering centres' mean rank for LP, 0 for `none`. Empty when
    /// [`Config::error`] is `false`.
    pub dim: Vec<f32>,
    /// Samples per pixel for the next pass (§9.2), when a budget was given;
    /// they sum to exactly the budget.
    pub samples: Option<Vec<u32>>,
    /// The method's debug maps (when [`Config::debug`]).
    pub debug: Vec<(String, Vec<f32>)>,
    /// What sanitation repaired (§0.4).
    pub report: PrepareReport,
    /// GPU time per dispatch (empty on the CPU).
    pub timings: Vec<KernelTiming>,
    /// Named scalar statistics (LP: `centre_fraction`, `centre_flops`, `covering`, [`crate::methods::lp::Census`]).
    pub stats: Vec<(String, f64)>,
}

impl Frame {
    /// A frame with nothing in it (0×0 images, no maps).
    pub fn empty() -> Frame {
        Frame {
            color: RgbImage::new(0, 0),
            error: RgbImage::new(0, 0),
            dim: Vec::new(),
            samples: None,
            debug: Vec::new(),
            report: PrepareReport::default(),
            timings: Vec::new(),
            stats: Vec::new(),
        }
    }
}

/// Side of the image [`Denoiser::warm_up`] builds a chain for: small, and a
/// multiple of 4 like most real widths (`sanitize_quads`; other widths use
/// `sanitize`, built by the denoiser itself).
const WARM_UP_SIZE: usize = 16;

/// Pipelines being built by [`Denoiser::warm_up`]. Dropping it (or
/// [`WarmUp::wait`]) waits until the thread is done.
#[must_use = "dropping a WarmUp waits for its pipelines"]
#[derive(Debug)]
pub struct WarmUp(Option<std::thread::JoinHandle<()>>);

impl WarmUp {
    /// Waits for the pipelines to be built.
    pub fn wait(mut self) {
        self.join();
    }

    fn join(&mut self) {
        if let Some(h) = self.0.take() {
            // A panic there is the caller's Denoiser::new's to report.
            let _ = h.join();
        }
    }
}

impl Drop for WarmUp {
    fn drop(&mut self) {
        self.join();
    }
}

enum Engine {
    Gpu(Box<GpuChain>),
    Tiled(Box<TiledChain>),
    Cpu(Source),
}

/// One configuration of the denoiser for one image size and input layout:
/// owns its pipelines' use, its scratch and output buffers (allocated once,
/// reused call after call, freed on drop — after any recorded work that
/// binds them, see [`Recorded`]).
///
/// Three ways to call it:
/// - [`record_into`](Self::record_into) (`unsafe`): records the whole chain
///   into the host's command buffer, reading the host's accumulation buffer;
///   outputs stay on the GPU ([`outputs`](Self::outputs)). Submits nothing.
/// - [`run`](Self::run): the same on mcdenoise's own command buffer, submitted
///   and waited for.
/// - [`denoise`](Self::denoise): statistics in host memory in, a [`Frame`]
///   out (uploads, runs, downloads; also the CPU reference backend).
pub struct Denoiser {
    engine: Engine,
    config: Config,
    progress: Option<ProgressCallback>,
    /// Whether the last call computed a sample map.
    sampled: AtomicBool,
    /// The device copy of accumulation sums handed over in host memory
    /// ([`run_host_accum`](Self::run_host_accum)), kept for the next call.
    host_accum: std::sync::Mutex<Option<Box<crate::gpu::GpuBuffer>>>,
}

impl std::fmt::Debug for Denoiser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Denoiser")
            .field("config", &self.config)
            .field(
                "backend",
                &match self.engine {
                    Engine::Gpu(_) => "gpu",
                    Engine::Tiled(_) => "gpu, tiled",
                    Engine::Cpu(_) => "cpu",
                },
            )
            .finish()
    }
}

impl Denoiser {
    /// A denoiser on a GPU context (mcdenoise's own device, or a host's
    /// through the `unsafe` [`GpuContext::from_raw`]). Allocates every buffer,
    /// checks the configuration against the source's layers, and builds the
    /// pipelines of every kernel its calls will record: a device that lacks
    /// what one needs (`shaderFloat64` for `Precision::F64`; a limit) is
    /// an [`Error::Limit`] here, never part-way through a recording.
    ///
    /// Statistics ([`Source::Stats`]) whose chain does not fit — a binding
    /// over `maxStorageBufferRange`, or more device memory than
    /// [`Config::max_memory`] — or with [`Config::tile`] set are denoised
    /// in tiles by [`denoise`](Self::denoise) (see [`Denoiser::tiles`]); such
    /// a denoiser has no GPU-resident outputs. An accumulation source that
    /// does not fit is an [`Error::Limit`].
    pub fn new(ctx: &Arc<GpuContext>, source: Source, config: Config) -> Result<Denoiser> {
        config.temporal.refuse_window()?;
        let low_spp = config.low_spp;
        let input = source.chain();
        let size = input.size();
        let engine = match TiledChain::choose(
            ctx,
            input,
            config.chain(low_spp, size),
            config.max_memory,
            config.tile,
        )? {
            Choice::Whole(c) => Engine::Gpu(c),
            Choice::Tiled(t) => Engine::Tiled(t),
        };
        Ok(Denoiser {
            engine,
            config,
            progress: None,
            sampled: AtomicBool::new(false),
            host_accum: std::sync::Mutex::new(None),
        })
    }

    /// Starts building, on a thread of its own, the compute pipelines a
    /// denoiser of `config` on `source` will use (its chain on a 16×16
    /// image with the same layers, and with `sample_map` — the calls will
    /// pass a budget — the sample map's kernels when the device can
    /// compute one), and returns at once. A caller overlaps this
    /// with work of its own (reading its input, building its scene): on
    /// lavapipe, creating LP's pipelines takes about half a second of one
    /// core (`lp_centres` alone 0.44 s), which [`Denoiser::new`] would
    /// otherwise spend before anything runs. A later [`Denoiser::new`] on
    /// the same context takes the built pipelines, or waits for the one
    /// being built. A hint only: a pipeline that fails to build here is
    /// built again, and its error reported, by [`Denoiser::new`] or the
    /// first call. Every pipeline built stays in the context (on lavapipe
    /// each holds its machine code, 1–3 MB of resident memory), so a
    /// warm-up builds only what the calls will use.
    ///
    /// The returned [`WarmUp`] holds a reference to `ctx` and waits for the
    /// thread when dropped: with a context made by
    /// [`GpuContext::from_raw`], drop it before destroying the device.
    pub fn warm_up(
        ctx: &Arc<GpuContext>,
        source: &Source,
        config: &Config,
        sample_map: bool,
    ) -> WarmUp {
        let ctx = ctx.clone();
        let mut config = config.clone();
        config.progress = false;
        config.max_memory = None;
        config.tile = None;
        if config.temporal_state.is_some() {
            // The state belongs to an image of the real size: the small
            // chain builds everything but the temporal gain's kernel.
            config.temporal = Temporal::Off;
            config.temporal_state = None;
        }
        let source = match source {
            Source::Accum(layout) => Source::Accum(AccumLayout {
                width: WARM_UP_SIZE,
                height: WARM_UP_SIZE,
                ..*layout
            }),
            Source::Stats { layers, .. } => Source::Stats {
                width: WARM_UP_SIZE,
                height: WARM_UP_SIZE,
                layers: layers.clone(),
            },
        };
        let spawned = std::thread::Builder::new()
            .name("mcdenoise-warm-up".into())
            // As much stack as a main thread: a driver's compiler may recurse.
            .stack_size(8 << 20)
            .spawn(move || {
                let _ = Denoiser::warm_up_chain(&ctx, source, config, sample_map);
            });
        WarmUp(spawned.ok())
    }

    /// [`warm_up`](Self::warm_up)'s thread: a chain builds every pipeline
    /// of its run when it is made (counting its work records every kernel
    /// into a batch that runs nothing, which asks the context for, and so
    /// builds, each pipeline); a statistics chain counts the sample map's
    /// kernels too when asked.
    fn warm_up_chain(
        ctx: &Arc<GpuContext>,
        source: Source,
        config: Config,
        sample_map: bool,
    ) -> Result<()> {
        let stats = matches!(source, Source::Stats { .. });
        let d = Denoiser::new(ctx, source, config)?;
        if stats && sample_map {
            d.chain()?.work(Some(1), None)?;
        }
        Ok(())
    }

    /// A denoiser running the scalar f64 references on the CPU (slow; for
    /// checking). Only [`denoise`](Self::denoise) works on it.
    pub fn new_cpu(source: Source, config: Config) -> Result<Denoiser> {
        config.temporal.refuse_window()?;
        if config.temporal != Temporal::Off {
            return Err(Error::InvalidArgument(
                "the temporal filter keeps its state on the GPU: use a GPU denoiser".into(),
            ));
        }

        if let Source::Stats {
            width,
            height,
            layers,
        } = &source
        {
            methods::chain::check_layers(config.method, layers)?;
            config.check_coarse_map(*width, *height)?;
        }
        Ok(Denoiser {
            engine: Engine::Cpu(source),
            config,
            progress: None,
            sampled: AtomicBool::new(false),
            host_accum: std::sync::Mutex::new(None),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The handle on this final denoiser's temporal state, for the
    /// configuration of the adaptive passes' denoiser of the same frames
    /// ([`Config::temporal_state`]); `None` without a temporal filter.
    pub fn temporal_state(&self) -> Option<TemporalState> {
        match &self.engine {
            Engine::Gpu(c) => c.temporal_state(),
            _ => None,
        }
    }

    /// Forgets the temporal stage's history ([`Config::temporal`]): the
    /// next call reinitialises every pixel, as at the first frame. Call it
    /// at a cut, or before a sequence that does not continue the last one.
    /// Nothing without a temporal stage.
    pub fn reset(&self) {
        if let Engine::Gpu(c) = &self.engine {
            c.reset_temporal();
        }
    }

    /// Reports progress of [`run`](Self::run) and [`denoise`](Self::denoise)
    /// on the GPU: `f(fraction, kernel)` after each submit completes, the
    /// fraction by estimated work (0..1). Recording into a host's command
    /// buffer reports nothing (the host submits).
    pub fn set_progress(&mut self, f: Option<ProgressCallback>) {
        self.progress = f;
    }

    /// Whether the G-buffer prefilter runs (GPU; the CPU decides per image).
    pub fn prefiltered(&self) -> bool {
        match &self.engine {
            Engine::Gpu(c) => c.prefiltered(),
            Engine::Tiled(t) => {
                let (c, layers) = (t.config(), t.layers());
                crate::methods::chain::prefilter_runs(c.method, c.prefilter, layers)
                    .unwrap_or(false)
            }
            Engine::Cpu(_) => false,
        }
    }

    /// The tiles (interior and the part of the image each reads) when this
    /// denoiser works in tiles, and the halo in pixels; `None` for a whole
    /// image.
    pub fn tiles(&self) -> Option<(&[Tile], usize)> {
        match &self.engine {
            Engine::Tiled(t) => Some((t.tiles(), t.halo().total())),
            _ => None,
        }
    }

    fn chain(&self) -> Result<&GpuChain> {
        match &self.engine {
            Engine::Gpu(c) => Ok(c),
            Engine::Tiled(t) => {
                let (w, h) = t.size();
                Err(Error::Limit(format!(
                    "this denoiser works in {} tiles ({w}x{h} does not fit one chain, or tiles were asked for): it has no GPU-resident outputs; use denoise()",
                    t.tiles().len()
                )))
            }
            Engine::Cpu(_) => Err(Error::InvalidArgument(
                "a CPU denoiser has no GPU buffers: use denoise()".into(),
            )),
        }
    }

    /// The host copy of what the temporal filter of a denoiser with one on
    /// one chain read and made on the last call ([`crate::Smoother`]);
    /// `None` without one.
    pub(crate) fn temporal_record(&self) -> Result<Option<FilterRecord>> {
        match &self.engine {
            Engine::Gpu(c) => c.temporal_record(),
            _ => Ok(None),
        }
    }

    /// The GPU-resident outputs. An error on a CPU denoiser.
    pub fn outputs(&self) -> Result<Outputs> {
        let c = self.chain()?;
        Ok(Outputs {
            color: c.color(),
            error: c.error(),
            samples: c.samples(),
        })
    }

    /// Records the whole chain into the host's command buffer `cmd`, allocated
    /// from a pool of queue family `queue_family`: finalisation of `accum` (for [`Source::Accum`]; `None` for
    /// [`Source::Stats`], whose statistics must already be uploaded),
    /// sanitation, prefilter, method, error, and the sample map when
    /// `budget` is given. Nothing is submitted.
    ///
    /// The recorded work begins with a barrier after all earlier commands of
    /// `cmd` and ends with one before all later commands (see
    /// [`Batch::record_into`]), so the host needs no barrier of its own
    /// between its writes of `accum` and this work, or between this work and
    /// its reads of [`outputs`](Self::outputs).
    ///
    /// # Errors
    /// `queue_family` other than the context's
    /// ([`GpuContext::queue_family`]) is an error before anything is
    /// recorded: the denoiser's buffers belong to that family (exclusive
    /// sharing), so work on another family's queue would see undefined
    /// contents. On any other `Err`, part of the chain may already be in `cmd`, referring to
    /// descriptor sets that are released with the error: the host must
    /// discard `cmd` (reset or free it) and never submit it. The denoiser
    /// and its context stay usable.
    ///
    /// # Safety
    /// - `cmd` belongs to the denoiser's device, comes from a pool of queue
    ///   family `queue_family`, is recording, and is outside a render pass;
    /// - `accum` (made with [`BufferSlice::from_raw`]) satisfies that
    ///   function's contract and is not written by other work while this work
    ///   runs;
    /// - the returned [`Recorded`] is dropped only after the submission of
    ///   `cmd` has completed (or `cmd` is never submitted); until then no
    ///   other call on this denoiser's buffers runs concurrently on the GPU
    ///   (two recordings of one denoiser in one command buffer run in order).
    pub unsafe fn record_into(
        &self,
        cmd: vk::CommandBuffer,
        queue_family: u32,
        accum: Option<BufferSlice>,
        budget: Option<u32>,
    ) -> Result<Recorded> {
        let chain = self.chain()?;
        let family = chain.context().queue_family();
        if queue_family != family {
            return Err(Error::InvalidArgument(format!(
                "the command buffer's queue family {queue_family} is not the context's \
                 ({family}), which owns the denoiser's buffers"
            )));
        }
        // SAFETY: forwarded to the caller (see above).
        let mut batch = unsafe { Batch::record_into(chain.context(), cmd) };
        batch.progress = false;
        chain.record(&mut batch, accum, budget)?;
        self.sampled.store(budget.is_some(), Ordering::SeqCst);
        batch.finish_recording()
    }

    /// Records the whole chain (as [`record_into`](Self::record_into)) into a
    /// [`Batch`] of the denoiser's context: the safe way for a client on the
    /// same context (the built-in renderer) to put its own passes and the
    /// denoiser's into one submission sequence, with a barrier between every
    /// dispatch. [`read`](Self::read) after `batch.finish()`.
    pub fn record(
        &self,
        batch: &mut Batch,
        accum: Option<BufferSlice>,
        budget: Option<u32>,
    ) -> Result<()> {
        let chain = self.chain()?;
        if !Arc::ptr_eq(batch.context(), chain.context()) {
            return Err(Error::InvalidArgument(
                "the batch belongs to another context than the denoiser".into(),
            ));
        }
        chain.record(batch, accum, budget)?;
        self.sampled.store(budget.is_some(), Ordering::SeqCst);
        Ok(())
    }

    /// Records the chain on mcdenoise's own command buffer, submits it to the
    /// context's queue (split into submits of about a second on slow
    /// devices) and waits. Returns the GPU time per dispatch.
    ///
    /// `accum` as for [`record_into`](Self::record_into). A host buffer passed
    /// here must not be in use by the host's queue meanwhile.
    pub fn run(
        &self,
        accum: Option<BufferSlice>,
        budget: Option<u32>,
    ) -> Result<Vec<KernelTiming>> {
        let chain = self.chain()?;
        let mut batch = Batch::new(chain.context())?;
        batch.progress = self.config.progress;
        if let Some(p) = &self.progress {
            batch.on_progress = Some(chain.progress_fn(budget, accum, p.clone())?);
        }
        chain.record(&mut batch, accum, budget)?;
        let t = batch.finish()?;
        self.sampled.store(budget.is_some(), Ordering::SeqCst);
        Ok(t)
    }

    /// [`run`](Self::run) on accumulation sums in host memory: `sums` holds
    /// the planes of the denoiser's [`Source::Accum`] layout exactly as a
    /// device buffer would ([`AccumLayout::bytes`] long, planes
    /// [`AccumLayout::plane_stride`] apart), for a renderer that
    /// accumulates on the CPU. They are copied to a device buffer the
    /// denoiser keeps for its next call; the results are bit-identical to
    /// [`run`](Self::run) on a device buffer with the same bytes.
    /// [`read`](Self::read) after.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a denoiser of another source or sums
    /// of another length; as [`run`](Self::run) otherwise.
    pub fn run_host_accum(&self, sums: &[u8], budget: Option<u32>) -> Result<Vec<KernelTiming>> {
        let chain = self.chain()?;
        let ChainInput::Accum(layout) = chain.input_kind() else {
            return Err(Error::InvalidArgument(
                "run_host_accum needs a denoiser made for an accumulation layout (Source::Accum)"
                    .into(),
            ));
        };
        if sums.len() as u64 != layout.bytes() {
            return Err(Error::InvalidArgument(format!(
                "the accumulation sums are {} bytes, the layout's {}x{} planes {}",
                sums.len(),
                layout.width,
                layout.height,
                layout.bytes()
            )));
        }
        let mut kept = self
            .host_accum
            .lock()
            .map_err(|_| Error::InvalidArgument("an earlier call panicked".into()))?;
        if kept.is_none() {
            *kept = Some(Box::new(crate::gpu::GpuBuffer::new(
                chain.context(),
                "host.accum",
                layout.bytes(),
            )?));
        }
        let buffer = kept.as_ref().expect("just made");
        buffer.upload(0, sums)?;
        self.run(Some(buffer.slice()), budget)
    }

    /// Downloads the outputs of the last completed call.
    pub fn read(&self) -> Result<Frame> {
        let chain = self.chain()?;
        let out = chain.download()?;
        let samples = if self.sampled.load(Ordering::SeqCst) {
            Some(chain.download_samples()?)
        } else {
            None
        };
        Ok(Frame {
            color: out.color,
            error: out.error,
            dim: out.dim,
            samples,
            debug: out.debug,
            report: chain.report()?,
            timings: Vec::new(),
            stats: crate::methods::Tally::means(&out.stats),
        })
    }

    /// The sanitised (§0.4) and, when the prefilter runs, prefiltered (§6)
    /// statistics of the last completed GPU call on one chain. A tiled
    /// denoiser keeps none: [`denoise_with_statistics`](Self::denoise_with_statistics)
    /// gathers them from its tiles.
    pub fn statistics(&self) -> Result<StatsImage> {
        self.chain()?.clean().download()
    }

    /// Uploads statistics in host memory for the next GPU call
    /// ([`run`](Self::run), [`record`](Self::record),
    /// [`record_into`](Self::record_into)) of a denoiser made for
    /// [`Source::Stats`] of their size and layers. Every call consumes its
    /// upload: the chain sanitises and prefilters the statistics in place
    /// (one copy of them on the device, not two), so a call without a new
    /// upload is an error.
    pub fn upload(&self, img: &StatsImage) -> Result<()> {
        self.chain()?.upload(img)
    }

    /// Denoises statistics in host memory (a file's, see [`crate::io`]): on
    /// the GPU (upload, [`run`](Self::run), [`read`](Self::read)) or with the
    /// CPU references. `img` must match the denoiser's [`Source::Stats`].
    pub fn denoise(&self, img: &StatsImage, budget: Option<u32>) -> Result<Frame> {
        self.denoise_image(Image::Borrowed(img), budget)
    }

    /// [`denoise`](Self::denoise), freeing `img` as soon as it is uploaded
    /// (when the denoiser works on one GPU chain), so the host's copy of the
    /// statistics is not held while the GPU works: what a tool that reads a
    /// file and denoises it wants.
    pub fn denoise_owned(&self, img: StatsImage, budget: Option<u32>) -> Result<Frame> {
        self.denoise_image(Image::Owned(img), budget)
    }

    /// [`denoise`](Self::denoise), also returning the statistics the method
    /// read: sanitised (§0.4) and, when the prefilter ran, with its normal,
    /// albedo and depth (and their variances). On one GPU chain they are
    /// [`statistics`](Self::statistics) after the call; a tiled denoiser
    /// gathers every tile's interior as it goes. Not on the CPU backend.
    pub fn denoise_with_statistics(
        &self,
        img: &StatsImage,
        budget: Option<u32>,
    ) -> Result<(Frame, StatsImage)> {
        if let Engine::Cpu(_) = self.engine {
            return Err(Error::InvalidArgument(
                "the CPU backend does not keep the statistics it denoised: use the GPU".into(),
            ));
        }
        let (frame, stats) = self.denoise_kept(Image::Borrowed(img), budget, true)?;
        let stats = match stats {
            Some(s) => s,
            None => self.statistics()?,
        };
        Ok((frame, stats))
    }

    fn denoise_image(&self, img: Image<'_>, budget: Option<u32>) -> Result<Frame> {
        Ok(self.denoise_kept(img, budget, false)?.0)
    }

    /// The denoise call; with `statistics`, a tiled denoiser also returns
    /// the statistics of its tiles' interiors.
    fn denoise_kept(
        &self,
        img: Image<'_>,
        budget: Option<u32>,
        statistics: bool,
    ) -> Result<(Frame, Option<StatsImage>)> {
        let size = (img.get().width, img.get().height);
        let req = |b| {
            let mut r = self.config.request(b, size);
            r.budget = budget;
            r
        };
        let mut kept = None;
        let out = match &self.engine {
            Engine::Gpu(chain) => {
                let report = methods::prepare::base_report(img.get());
                chain.upload(img.get())?;
                drop(img);
                methods::run_uploaded(chain, report, &req(Backend::Gpu), self.progress.as_ref())?
            }
            Engine::Tiled(t) => {
                let (out, stats) = t.denoise(
                    img.get(),
                    budget,
                    statistics,
                    self.config.progress,
                    self.progress.as_ref(),
                )?;
                kept = stats;
                out
            }
            Engine::Cpu(source) => {
                let img = img.get();
                if source != &Source::of_image(img) {
                    return Err(Error::InvalidArgument(format!(
                        "this denoiser was made for {source:?}; the image is {}x{} with other layers",
                        img.width, img.height
                    )));
                }
                methods::denoise(None, img, &req(Backend::Cpu))?
            }
        };
        if let Engine::Gpu(_) | Engine::Tiled(_) = self.engine {
            self.sampled.store(budget.is_some(), Ordering::SeqCst);
        }
        let frame = Frame {
            color: out.color,
            error: out.error.unwrap_or_else(|| RgbImage::new(0, 0)),
            dim: out.dim,
            samples: out.samples,
            debug: out.debug,
            report: out.report,
            timings: out.timings,
            stats: out.stats,
        };
        Ok((frame, kept))
    }
}

/// The statistics a denoise call reads: the caller's, or given to the call
/// (freed after the upload).
enum Image<'a> {
    Borrowed(&'a StatsImage),
    Owned(StatsImage),
}

impl Image<'_> {
    fn get(&self) -> &StatsImage {
        match self {
            Image::Borrowed(i) => i,
            Image::Owned(i) => i,
        }
    }
}
