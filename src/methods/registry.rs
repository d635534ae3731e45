//! The method registry: everything the chain, the tiler, the sampler, the
//! schedule, the benchmarks and the CLI need to know of a reconstruction
//! method, in one [`MethodInfo`] per method.
//!
//! A method is one module that defines its [`MethodInfo`] (its layers,
//! defaults, sampling parameters, halo, memory model, its GPU stage behind
//! [`GpuStage`] and its CPU path) plus one line in
//! [`REGISTRY`](super::REGISTRY). Nothing else in the crate matches on the
//! method.

use std::sync::Arc;

use super::chain::{ChainConfig, ChainOutput};
use super::sampling::SamplingParams;
use super::stats::GpuStats;
use super::tiles::Rect;
use super::{Method, Pass};
use crate::error::Result;
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::options::Options;

/// The layers every regression method reads (§0.1); their variances are
/// estimated when missing (§0.4 step 4).
pub const REGRESSION_LAYERS: [Layer; 5] = [
    Layer::Color,
    Layer::Albedo,
    Layer::Normal,
    Layer::Depth,
    Layer::Spp,
];

/// One method's entry in the registry.
#[derive(Debug)]
pub struct MethodInfo {
    /// The method this entry describes.
    pub method: Method,
    /// Lower-case name, as the CLI, the benchmarks and messages spell it.
    pub name: &'static str,
    /// One line for `--help`.
    pub about: &'static str,
    /// The statistics layers it reads; a missing one is an error naming it.
    pub needs: &'static [Layer],
    /// Whether `--prefilter auto` runs the G-buffer prefilter (§6) before it
    /// when the input has the position layers.
    pub prefilter_auto: bool,
    /// Whether `--outliers auto` runs the outlier stage (§4.4) around it.
    pub outliers_auto: bool,
    /// Whether `--pyramid auto` runs the pyramid's low band
    /// (PYRAMID-LOWBAND) after it.
    pub pyramid_auto: bool,
    /// The input blend's defaults (INPUT-BLEND): whether `--input-blend
    /// auto` runs it after the method, and its parameters.
    pub blend: super::blend::BlendDefaults,
    /// The method whose reconstruction and error estimate make the
    /// adaptive loop's sample maps when this method makes the final image,
    /// with that method's `passes` and `sampling` (MAP-WLR, AUTO-MAPS: WLR
    /// for LP, APR, AOS and `auto`; itself otherwise).
    pub map_method: Method,
    /// Adaptive passes after the uniform pass 0 (§9.3 `N_pass`).
    pub passes: u32,
    /// The adaptive loop's default per-pass cap, as a multiple of the pass's
    /// mean samples per pixel (`None`: no cap).
    pub pass_cap: Option<f64>,
    /// Whether, when another method makes the adaptive maps, this method's
    /// own error estimate decides how much of each pass follows the map
    /// and how much is spread evenly (MAP-CHECK; the adaptive loop's
    /// default `map_check`).
    pub map_check: bool,
    /// Its parameters of §9.1 (before `sampling.smooth`).
    pub sampling: SamplingParams,
    /// The factor by which its estimated rMSE (mean `E_i / (f̂_i² + 0.01)`)
    /// is scaled where a stop rule judges the reconstruction against a
    /// target: the geometric mean of true over estimated rMSE on the
    /// tuning scenes (ERROR-SCALE). Its `E_i` and sample maps do not use
    /// it; the temporal filter's TEMPORAL-MISREG term does.
    pub error_scale: f64,
    /// The factor in place of `error_scale` where the pyramid's low band
    /// (PYRAMID-LOWBAND) ran ([`crate::Config::error_scale`]): the merged
    /// estimate falls about twice as far as the true error does
    /// (PYRAMID-ERROR-SCALE).
    pub pyramid_error_scale: f64,
    /// The factor on its error estimate in the temporal filter's colour test
    /// (TEMPORAL-INFLATE), in its default configuration: the variance of
    /// its output between renders of independent seeds over its estimate,
    /// relative to WLR's, on which the test's threshold was set, where both
    /// sets of scenes measured put that far from 1 (LP); else 1
    /// (TEMPORAL-TEST-SCALE; `--opt temporal.inflate` in its place).
    pub inflate_scale: f64,
    /// The multiple of which a tile's first column and row must be so that
    /// its grid keeps the image's phase (1: no grid).
    pub align: usize,
    /// The method's own reach in pixels for a configuration (its chain of
    /// windows), which the tiler adds to the other stages' halos.
    pub halo: fn(&ChainConfig) -> Result<usize>,
    /// Bytes of scratch the method takes from the chain's arena for a
    /// `(width, height)` image (0: none; the arena is shared with the other
    /// stages' scratch, whose lifetimes do not overlap).
    pub arena_bytes: fn(&ChainConfig, (usize, usize)) -> u64,
    /// Bytes at the start of its arena scratch that must outlive the
    /// outlier stage's restoration (read back after the run) for `n` pixels.
    pub arena_kept: fn(usize) -> u64,
    /// Bytes of its buffers that grow with the width rather than the area
    /// (rings of rows), for the tiler's memory model.
    pub ring_bytes: fn(&ChainConfig, (usize, usize)) -> u64,
    /// Its options for statistics with these layers: the given ones, or
    /// what the method makes of them (AUTO-VIS: `auto`'s WLR member drops
    /// the visibility feature where the statistics have none).
    pub options_for: fn(&Options, &[Layer]) -> Options,
    /// Allocates its GPU stage.
    pub gpu: fn(&StageArgs) -> Result<Box<dyn GpuStage>>,
    /// Runs it on the CPU (the scalar twins) on sanitised statistics, with
    /// [`CpuArgs::options`] as [`options_for`](Self::options_for) resolved
    /// them (the CPU path resolves them before it calls this).
    pub cpu: fn(&StatsImage, &CpuArgs) -> Result<CpuResult>,
}

impl MethodInfo {
    /// Its [`error_scale`](Self::error_scale), or its
    /// [`pyramid_error_scale`](Self::pyramid_error_scale) where the
    /// pyramid's low band ran.
    pub fn error_scale_with(&self, pyramid: bool) -> f64 {
        if pyramid {
            self.pyramid_error_scale
        } else {
            self.error_scale
        }
    }
}

/// What a method's [`MethodInfo::gpu`] constructor gets.
pub struct StageArgs<'a> {
    /// The device.
    pub ctx: &'a Arc<GpuContext>,
    /// The chain's configuration.
    pub config: &'a ChainConfig,
    /// `(width, height)`.
    pub size: (usize, usize),
    /// The chain's arena (at least [`MethodInfo::arena_bytes`] long), if any.
    pub arena: Option<&'a Arc<GpuBuffer>>,
}

/// What one recording of a stage needs to know of the run.
pub struct StageRun<'a> {
    /// Kernel arithmetic.
    pub precision: Precision,
    /// The sanitised (outlier-cleaned) statistics, prefiltered when
    /// `prefiltered` says so (not yet in [`GpuStage::record_unfiltered`]).
    pub stats: &'a GpuStats,
    /// The chain's configuration.
    pub config: &'a ChainConfig,
    /// Whether the sample map or its priority reads the error planes after.
    pub maps: bool,
    /// The image pixel of the chain's pixel `(0, 0)` (a tile's origin).
    pub origin: (u32, u32),
    /// Whether the G-buffer prefilter ran before the method (false in
    /// [`GpuStage::record_unfiltered`], which runs before it).
    pub prefiltered: bool,
    /// The whole image's sample total ([`crate::reference::spp_total`]'s
    /// words) when the chain runs one tile of it; `None`: the chain's
    /// statistics are the image (APR-COUNT-CAP counts them).
    pub spp_total: Option<[u32; 3]>,
    /// The visibility and its variance as WLR-VIS filters them, when the
    /// caller recorded that filter for several stages (`auto`): a stage
    /// that filters the visibility (WLR-VIS, APR-VIS) reads these planes
    /// instead of filtering it again. `None`: each filters its own.
    pub visibility: Option<[BufferSlice; 2]>,
}

/// A method's GPU stage: its buffers and how to record it. Outputs stay on
/// the GPU until [`GpuStage::download`].
pub trait GpuStage: Send + Sync {
    /// Records the method on `run.stats`.
    fn record(&self, batch: &mut Batch, run: &StageRun) -> Result<()>;
    /// Records what reads the statistics before the G-buffer prefilter
    /// changes their features in place; the chain calls it, before the
    /// prefilter, only when the prefilter runs. Nothing by default; `auto`
    /// records its members that read unprefiltered features (AOS,
    /// AUTO-AOS).
    fn record_unfiltered(&self, _batch: &mut Batch, _run: &StageRun) -> Result<()> {
        Ok(())
    }
    /// The reconstruction's colour planes R, G, B.
    fn color(&self, stats: &GpuStats) -> [BufferSlice; 3];
    /// The per-pixel error estimate `E_i` per channel (§9.1).
    fn error(&self, stats: &GpuStats) -> [BufferSlice; 3];
    /// What the sample map reads as `E` (§9.1); the exported error unless
    /// the method says otherwise.
    fn sampling_error(&self, stats: &GpuStats) -> [BufferSlice; 3] {
        self.error(stats)
    }
    /// The plane the local dimension `d_i` is read from, and whether it is
    /// WLR's `kflags` (rank in `value mod 16`).
    fn dim(&self) -> (BufferSlice, bool);
    /// Adds its debug planes (with `debug`) and run statistics to `out`
    /// after a completed run; `rect` crops the statistics to a tile's
    /// interior.
    fn download(
        &self,
        stats: &GpuStats,
        size: (usize, usize),
        rect: Option<Rect>,
        debug: bool,
        out: &mut ChainOutput,
    ) -> Result<()>;
}

/// What a method's CPU path gets besides the statistics.
#[derive(Clone, Debug)]
pub struct CpuArgs {
    /// Final or intermediate windows.
    pub pass: Pass,
    /// Method options.
    pub options: Options,
    /// Progress lines on stderr for long runs.
    pub progress: bool,
    /// Whether the debug maps are wanted.
    pub debug: bool,
    /// Whether the G-buffer prefilter ran.
    pub prefiltered: bool,
    /// When it ran and a member of `auto` reads unprefiltered features
    /// (AOS, AUTO-AOS): the statistics before it (sanitised,
    /// outlier-cleaned).
    pub unfiltered: Option<std::sync::Arc<StatsImage>>,
}

/// A method's CPU output.
#[derive(Clone, Debug)]
pub struct CpuResult {
    /// The reconstruction.
    pub color: RgbImage,
    /// `E_i` per channel.
    pub error: RgbImage,
    /// `d_i` per pixel.
    pub dim: Vec<f32>,
    /// Named debug planes (empty unless asked).
    pub debug: Vec<(String, Vec<f32>)>,
    /// Scalar statistics of the run.
    pub stats: Vec<super::Tally>,
    /// What the sample map reads as `E` when it is not `error`.
    pub map_error: Option<RgbImage>,
}

/// A [`MethodInfo::arena_bytes`], [`MethodInfo::ring_bytes`] for methods
/// that have none.
pub fn no_bytes(_: &ChainConfig, _: (usize, usize)) -> u64 {
    0
}

/// A [`MethodInfo::options_for`] for methods whose options do not depend
/// on the layers.
pub fn same_options(options: &Options, _: &[Layer]) -> Options {
    options.clone()
}

/// A [`MethodInfo::arena_kept`] for methods that keep nothing in the arena.
pub fn nothing_kept(_: usize) -> u64 {
    0
}
