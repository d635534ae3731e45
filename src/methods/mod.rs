//! Sequences of kernels. Each method runs either on the GPU (the kernels) or
//! on the CPU (their scalar twins), selected by [`Backend`]; [`denoise`] is
//! the one entry point the CLI and the benchmarks use.

pub mod aos;
pub mod apr;
pub mod apr_window;
pub mod auto;
pub mod blend;
pub mod chain;
pub mod gbf;
pub mod lp;
pub mod none;
pub mod outliers;
pub mod prepare;
pub mod pyramid;
pub mod registry;
pub mod sampling;
pub mod stats;
pub mod temporal;
pub mod tiles;
pub mod wlr;

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::gpu::{GpuContext, KernelTiming, Precision};
use crate::image::{RgbImage, StatsImage};
use crate::options::Options;

pub use blend::InputBlend;
pub use outliers::Outliers;
pub use pyramid::Pyramid;
pub use registry::MethodInfo;
pub use temporal::{Temporal, TemporalState};

/// Where a method runs.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Backend {
    /// GPU kernels through Vulkan.
    #[default]
    Gpu,
    /// The scalar f64 twins (`crate::reference`).
    Cpu,
}

/// The reconstruction methods. What each one is, needs and defaults to is
/// its [`MethodInfo`] in the [`REGISTRY`] ([`Method::info`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Weighted local regression (§2).
    Wlr,
    /// Linear predictions (§3).
    Lp,
    /// Adaptive polynomial rendering (§4).
    Apr,
    /// Adaptive-order polynomial fitting (§5).
    Aos,
    /// No reconstruction: the sanitised input (§0.4).
    None,
    /// WLR, LP and APR blended per pixel by their error estimates (ours,
    /// AUTO-BLEND).
    Auto,
}

/// Every method's entry, in the order of [`Method`]'s variants (the order
/// the benchmarks run them in is [`Method::all`]'s).
pub static REGISTRY: [&MethodInfo; 6] = [
    &wlr::INFO,
    &lp::INFO,
    &apr::INFO,
    &aos::INFO,
    &none::INFO,
    &auto::INFO,
];

impl Method {
    /// The method's registry entry.
    pub fn info(self) -> &'static MethodInfo {
        REGISTRY[self as usize]
    }

    /// Lower-case name, as the CLI and error messages spell it (`wlr`, `lp`,
    /// `apr`, `aos`, `none`).
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// Every method: `none` first, then the reconstructions in registry
    /// order.
    pub fn all() -> impl Iterator<Item = Method> {
        let none = std::iter::once(Method::None);
        none.chain(
            REGISTRY
                .iter()
                .map(|i| i.method)
                .filter(|&m| m != Method::None),
        )
    }

    /// The methods a reconstruction by this one runs with `options`, in
    /// any pass: itself, and `auto`'s members.
    pub fn runs(self, options: &Options) -> Vec<Method> {
        let mut m = vec![self];
        if self == Method::Auto {
            for pass in [Pass::Final, Pass::Intermediate] {
                m.extend(auto::members(options, pass));
            }
        }
        m
    }

    /// The method called `name` (case-insensitive, surrounding blanks
    /// ignored).
    pub fn from_name(name: &str) -> Option<Method> {
        REGISTRY
            .iter()
            .find(|i| i.name.eq_ignore_ascii_case(name.trim()))
            .map(|i| i.method)
    }
}

/// Which pass of the adaptive loop a reconstruction serves (spec §9.3).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Pass {
    /// The final image (large windows).
    #[default]
    Final,
    /// An adaptive pass: error map for sampling (the spec's intermediate windows).
    Intermediate,
}

/// Receives the completed fraction of a GPU call (0..1, by estimated work)
/// and the kernel that last completed.
pub type ProgressCallback = Arc<dyn Fn(f64, &str) + Send + Sync>;

/// The G-buffer prefilter of normal, albedo and depth (spec §6) before the
/// method (§1).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Prefilter {
    /// When the input has `position`, `position_variance` and
    /// `position_covariance` (the default), for WLR, LP, APR and auto; never for
    /// `none` and AOS ([`Prefilter::resolve`]).
    #[default]
    Auto,
    /// Always; an error without those layers.
    On,
    /// Never.
    Off,
}

impl Prefilter {
    /// What `self` means for `method`. `Auto` is `Off` for `none` (its
    /// output is the Monte Carlo mean) and for AOS.
    ///
    /// Decision AOS-NO-GBF (ours): AOS then runs its own NL-means on every
    /// feature (§5.2) instead of only on visibility (PREFILTER-STACK, §1):
    /// its fixed bandwidth fits those features better than the smoother but
    /// biased G-buffer ones.
    pub fn resolve(self, method: Method) -> Prefilter {
        match self {
            Prefilter::Auto if !method.info().prefilter_auto => Prefilter::Off,
            p => p,
        }
    }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct DenoiseRequest {
    /// The reconstruction method (§2–§5, or `none`).
    pub method: Method,
    /// The G-buffer prefilter (ignored by `none`).
    pub prefilter: Prefilter,
    /// The outlier stage (§4.4); `auto` is the method's default.
    pub outliers: Outliers,
    /// GPU kernels or the CPU f64 reference.
    pub backend: Backend,
    /// Compute precision of the GPU kernels (spec §0.3); ignored by the CPU
    /// backend, which is f64 throughout.
    pub precision: Precision,
    /// Final or intermediate pass: selects the window sizes (§9.3).
    pub pass: Pass,
    /// Method options (`--opt key=value`).
    pub options: Options,
    /// Compute the per-pixel error estimate, and return it with the local
    /// dimension (without it [`DenoiseOutput::dim`] is empty).
    pub error: bool,
    /// Keep the method's debug maps.
    pub debug: bool,
    /// The pyramid's low band after the method (PYRAMID-LOWBAND).
    pub pyramid: bool,
    /// The input blend after the method (INPUT-BLEND).
    pub input_blend: bool,
    /// Report progress on stderr for runs longer than about a second.
    pub progress: bool,
    /// Samples to distribute for the next pass: computes the sample map
    /// (§9).
    pub budget: Option<u32>,
    /// The map from a half-resolution reconstruction (MAP-COARSE,
    /// [`chain::ChainConfig::coarse_map`]): an adaptive pass's only.
    pub coarse_map: bool,
}

impl DenoiseRequest {
    /// A request for `method` with the defaults: GPU backend in f32, final pass,
    /// automatic prefilter, default options, no error map, debug maps, progress
    /// or sample map.
    pub fn new(method: Method) -> Self {
        DenoiseRequest {
            method,
            prefilter: Prefilter::Auto,
            outliers: Outliers::Auto,
            backend: Backend::Gpu,
            precision: Precision::F32,
            pass: Pass::Final,
            options: Options::default(),
            error: false,
            debug: false,
            pyramid: false,
            input_blend: false,
            progress: false,
            budget: None,
            coarse_map: false,
        }
    }
}

/// A scalar statistic of a run over the pixels it counts (LP's
/// [`lp::Census`]): its value per pixel is `sum / pixels`. A tiled run adds
/// its tiles' sums and pixels and divides once, so it equals the whole
/// run's exactly where the sums are whole numbers (below 2⁵³).
#[derive(Clone, Debug, PartialEq)]
pub struct Tally {
    /// The statistic's name.
    pub name: String,
    /// Σ over the counted pixels.
    pub sum: f64,
    /// The pixels counted.
    pub pixels: usize,
}

impl Tally {
    /// `tallies`' names prefixed with `prefix` and a dot (`auto`'s members).
    pub fn prefixed(prefix: &str, tallies: impl IntoIterator<Item = Tally>) -> Vec<Tally> {
        tallies
            .into_iter()
            .map(|t| Tally {
                name: format!("{prefix}.{}", t.name),
                ..t
            })
            .collect()
    }

    /// Adds `more` into `into`, statistic by statistic (sums and pixels).
    pub fn merge(into: &mut Vec<Tally>, more: impl IntoIterator<Item = Tally>) {
        for t in more {
            match into.iter_mut().find(|s| s.name == t.name) {
                Some(s) => {
                    s.sum += t.sum;
                    s.pixels += t.pixels;
                }
                None => into.push(t),
            }
        }
    }

    /// Each statistic per pixel, by name (0 over no pixels).
    pub fn means(tallies: &[Tally]) -> Vec<(String, f64)> {
        tallies
            .iter()
            .map(|t| (t.name.clone(), t.sum / t.pixels.max(1) as f64))
            .collect()
    }
}

/// What a method returns.
#[derive(Clone, Debug)]
pub struct DenoiseOutput {
    /// The reconstruction, clamped to ≥ 0 (spec §0.4 step 5).
    pub color: RgbImage,
    /// Estimated MSE per pixel and channel, when requested and the method has one.
    pub error: Option<RgbImage>,
    /// The local dimension `d_i` per pixel (§9.1; 0 for `none`); empty
    /// without the error estimate (`error`).
    pub dim: Vec<f32>,
    /// The next pass's samples per pixel (§9.2) when `budget` was set.
    pub samples: Option<Vec<u32>>,
    /// Named debug planes.
    pub debug: Vec<(String, Vec<f32>)>,
    /// What sanitation repaired.
    pub report: prepare::PrepareReport,
    /// GPU time per dispatch (empty on the CPU backend).
    pub timings: Vec<KernelTiming>,
    /// Named scalar statistics of the run (LP: `centre_fraction`, `centre_flops`, `covering`, [`crate::methods::lp::Census`]).
    pub stats: Vec<(String, f64)>,
}

/// Sanitises `img` and reconstructs it with `req.method`. The GPU backend
/// needs `ctx` and runs the one GPU chain ([`chain::GpuChain`]); the CPU
/// backend chains the scalar twins.
pub fn denoise(
    ctx: Option<&Arc<GpuContext>>,
    img: &StatsImage,
    req: &DenoiseRequest,
) -> Result<DenoiseOutput> {
    let layers: Vec<crate::image::Layer> = img.layers().map(|(l, _)| l).collect();
    chain::check_layers(req.method, &layers)?;
    match req.backend {
        Backend::Gpu => denoise_gpu(gpu_ctx(ctx)?, img, req),
        Backend::Cpu => denoise_cpu(img, req),
    }
}

fn denoise_gpu(
    ctx: &Arc<GpuContext>,
    img: &StatsImage,
    req: &DenoiseRequest,
) -> Result<DenoiseOutput> {
    let chain = chain::GpuChain::new(
        ctx,
        chain::ChainInput::of_image(img),
        chain::ChainConfig {
            method: req.method,
            pass: req.pass,
            precision: req.precision,
            prefilter: req.prefilter,
            outliers: req.outliers.resolve(req.method),
            options: req.options.clone(),
            low_spp: prepare::has_low_spp(img),
            debug: req.debug,
            error: req.error,
            pyramid: req.pyramid,
            input_blend: req.input_blend,
            temporal: Temporal::Off,
            temporal_state: None,
            coarse_map: req.coarse_map,
        },
    )?;
    denoise_with_chain(&chain, img, req, None)
}

/// Runs an existing chain (made for [`chain::ChainInput::Stats`] of `img`'s
/// size and layers) on `img`: upload, record, submit, wait, download.
/// `req`'s method, pass, precision, prefilter, `error` and `debug` are the
/// chain's ([`chain::ChainConfig`] decides what is downloaded); its
/// `budget` and `progress` apply.
/// `progress` receives the completed fraction (0..1, by estimated work) and
/// the last kernel after each submit.
pub fn denoise_with_chain(
    chain: &chain::GpuChain,
    img: &StatsImage,
    req: &DenoiseRequest,
    progress: Option<&ProgressCallback>,
) -> Result<DenoiseOutput> {
    chain.upload(img)?;
    run_uploaded(chain, prepare::base_report(img), req, progress)
}

/// [`denoise_with_chain`] after [`chain::GpuChain::upload`]: record, submit,
/// wait, download. `report` is [`prepare::base_report`] of the uploaded
/// image (the caller may have freed it).
pub fn run_uploaded(
    chain: &chain::GpuChain,
    mut report: prepare::PrepareReport,
    req: &DenoiseRequest,
    progress: Option<&ProgressCallback>,
) -> Result<DenoiseOutput> {
    let mut batch = crate::gpu::Batch::new(chain.context())?;
    batch.progress = req.progress;
    if let Some(p) = progress {
        batch.on_progress = Some(chain.progress_fn(req.budget, None, p.clone())?);
    }
    chain.record(&mut batch, None, req.budget)?;
    let timings = batch.finish()?;
    let out = chain.download()?;
    let samples = match req.budget {
        Some(_) => Some(chain.download_samples()?),
        None => None,
    };
    report.counters = chain.counters()?;
    if req.method == Method::None {
        report.timings = timings.clone();
    }
    Ok(DenoiseOutput {
        color: out.color,
        error: req.error.then_some(out.error),
        dim: out.dim,
        samples,
        debug: out.debug,
        report,
        timings,
        stats: Tally::means(&out.stats),
    })
}

fn denoise_cpu(img: &StatsImage, req: &DenoiseRequest) -> Result<DenoiseOutput> {
    if req.coarse_map {
        return coarse_map_cpu(img, req);
    }
    Ok(denoise_cpu_parts(img, req)?.0)
}

/// The CPU path without a coarse map: the output, and the error estimate
/// the sample map reads when it is not the output's (the method's own
/// before the input blend or the pyramid, LP's ΔMSE).
fn denoise_cpu_parts(
    img: &StatsImage,
    req: &DenoiseRequest,
) -> Result<(DenoiseOutput, Option<RgbImage>)> {
    if req.pyramid {
        pyramid::check(req.method, (img.width, img.height))?;
    }
    if req.input_blend {
        blend::check(req.method)?;
    }
    let CleanCpu {
        clean,
        report,
        removed,
        prefiltered,
        unfiltered,
        pooled,
    } = clean_cpu(img, req)?;
    let (w, h) = (img.width, img.height);
    let layers: Vec<crate::image::Layer> = clean.layers().map(|(l, _)| l).collect();
    let registry::CpuResult {
        mut color,
        mut error,
        dim,
        mut debug,
        stats,
        map_error: mut map_e,
    } = (req.method.info().cpu)(
        &clean,
        &registry::CpuArgs {
            pass: req.pass,
            options: (req.method.info().options_for)(&req.options, &layers),
            progress: req.progress,
            debug: req.debug,
            prefiltered,
            unfiltered,
        },
    )?;
    // The sample map reads the method's own estimate, as on the GPU.
    if req.input_blend {
        let params = blend::params(req.method, &req.options)?;
        let (c, e) = blend::run_cpu(&clean, &color, &error, params)?;
        color = c;
        map_e = map_e.or(Some(std::mem::replace(&mut error, e)));
    }
    if let Some(r) = &removed {
        let spp = &clean.get(crate::image::Layer::Spp).unwrap()[0];
        let wide = outliers::wide_fraction(&req.options)?;
        outliers::restore_cpu(w, h, spp, r, wide, &mut color.planes);
        if req.debug {
            debug.extend(outliers::debug_layers(&r.excess_f32()));
        }
    }
    // The sample map reads the method's own estimate, as on the GPU.
    if let Some(pooled) = &pooled {
        let method_error = std::mem::replace(&mut error, RgbImage::new(0, 0));
        let spp = &clean.get(crate::image::Layer::Spp).unwrap()[0];
        let fine = (&color, &method_error, spp.as_slice());
        (color, error) = pyramid::run_cpu(pooled, fine, req, prefiltered)?;
        map_e = map_e.or(Some(method_error));
    }
    let samples = match req.budget {
        Some(t) => {
            let mut params = sampling::SamplingParams::with_options(req.method, &req.options)?;
            // The CPU path passes the decoded rank, not WLR's kflags.
            params.dim = sampling::DimSource::Plain;
            let e = map_e.as_ref().unwrap_or(&error).plane_slices();
            let spp = &clean.get(crate::image::Layer::Spp).unwrap()[0];
            let inputs = sampling::CpuSampleInputs {
                error: e,
                dim: &dim,
                filtered: color.plane_slices(),
                spp,
            };
            Some(sampling::run_cpu(w, h, &inputs, t, &params)?)
        }
        None => None,
    };
    let out = DenoiseOutput {
        color,
        error: req.error.then_some(error),
        // As the GPU path: the local dimension comes with the error estimate.
        dim: if req.error { dim } else { Vec::new() },
        samples,
        debug,
        report,
        timings: Vec::new(),
        stats: Tally::means(&stats),
    };
    Ok((out, map_e))
}

/// The CPU path of a coarse map (MAP-COARSE), as the GPU chain runs it:
/// the fine level is `none`'s (the sanitised input and its variance), the
/// request's method reconstructs the sanitised statistics pooled over 2×2
/// blocks, and the map takes its priority from that reconstruction.
fn coarse_map_cpu(img: &StatsImage, req: &DenoiseRequest) -> Result<DenoiseOutput> {
    let size = (img.width, img.height);
    chain::check_coarse_map(
        &chain::ChainConfig {
            method: req.method,
            pass: req.pass,
            precision: req.precision,
            prefilter: req.prefilter,
            outliers: false,
            options: req.options.clone(),
            low_spp: true,
            debug: false,
            error: true,
            pyramid: req.pyramid,
            input_blend: req.input_blend,
            temporal: Temporal::Off,
            temporal_state: None,
            coarse_map: true,
        },
        size,
    )?;
    // As on the GPU, the fine level runs neither the outlier stage nor
    // the prefilter.
    let fine_req = DenoiseRequest {
        method: Method::None,
        outliers: Outliers::Off,
        prefilter: Prefilter::Off,
        coarse_map: false,
        budget: None,
        ..req.clone()
    };
    let mut out = denoise_cpu(img, &fine_req)?;
    let Some(budget) = req.budget else {
        return Ok(out);
    };
    let (clean, _) = prepare::prepare_cpu(img);
    let layers: Vec<crate::image::Layer> = img.layers().map(|(l, _)| l).collect();
    let prefiltered = gbf::wanted(req.method, req.prefilter, |l| layers.contains(&l))?;
    let pooled = pyramid::pool_cpu(&clean);
    let coarse_req = DenoiseRequest {
        coarse_map: false,
        budget: None,
        error: true,
        debug: false,
        prefilter: if prefiltered {
            Prefilter::On
        } else {
            Prefilter::Off
        },
        ..req.clone()
    };
    let (coarse, map_error) = denoise_cpu_parts(&pooled, &coarse_req)?;
    let mut params = sampling::SamplingParams::with_options(req.method, &req.options)?;
    params.dim = sampling::DimSource::Plain;
    let coarse_error = map_error
        .as_ref()
        .or(coarse.error.as_ref())
        .ok_or_else(|| Error::InvalidArgument("the coarse level has no error estimate".into()))?;
    let inputs = sampling::CpuSampleInputs {
        error: coarse_error.plane_slices(),
        dim: &coarse.dim,
        filtered: coarse.color.plane_slices(),
        spp: &pooled.get(crate::image::Layer::Spp).unwrap()[0],
    };
    let spp = &clean.get(crate::image::Layer::Spp).unwrap()[0];
    out.samples = Some(sampling::coarse_run_cpu(
        size, &inputs, spp, budget, &params,
    )?);
    Ok(out)
}

/// The CPU path's input of every method ([`clean_cpu`]).
struct CleanCpu {
    /// Sanitised statistics, without outliers when `req.outliers` wants
    /// it, prefiltered when `req.prefilter` wants it (§1).
    clean: StatsImage,
    /// What sanitation repaired.
    report: prepare::PrepareReport,
    /// What the outlier stage removed.
    removed: Option<outliers::Removed>,
    /// Whether the prefilter ran.
    prefiltered: bool,
    /// With `req.pyramid`: the sanitised statistics pooled 2×2 (before the
    /// outlier stage and the prefilter, as on the GPU).
    pooled: Option<StatsImage>,
    /// When the prefilter ran and a member of `auto` reads the features
    /// from before it (AUTO-AOS): the statistics before it.
    unfiltered: Option<std::sync::Arc<StatsImage>>,
}

fn clean_cpu(img: &StatsImage, req: &DenoiseRequest) -> Result<CleanCpu> {
    let (mut clean, report) = prepare::prepare_cpu(img);
    let pooled = req.pyramid.then(|| pyramid::pool_cpu(&clean));
    let removed = req
        .outliers
        .resolve(req.method)
        .then(|| outliers::Detection::of(&req.options))
        .transpose()?
        .map(|detection| outliers::remove_cpu(&mut clean, detection));
    let prefiltered = gbf::wanted(req.method, req.prefilter, |l| clean.has(l))?;
    let keep =
        prefiltered && req.method == Method::Auto && auto::reads_unfiltered(&req.options, req.pass);
    let unfiltered = keep.then(|| std::sync::Arc::new(clean.clone()));
    if prefiltered {
        gbf::run_cpu(
            &mut clean,
            gbf::GbfSettings::new(&req.options, req.method, req.pass)?,
        )?;
    }
    Ok(CleanCpu {
        clean,
        report,
        removed,
        prefiltered,
        unfiltered,
        pooled,
    })
}

fn gpu_ctx(ctx: Option<&Arc<GpuContext>>) -> Result<&Arc<GpuContext>> {
    ctx.ok_or_else(|| Error::InvalidArgument("the GPU backend needs a context".into()))
}

/// The names of the methods, for error messages.
pub fn available_names() -> String {
    REGISTRY
        .iter()
        .map(|i| i.name)
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registry_is_indexed_by_the_enum_and_names_are_unique() {
        for (i, info) in REGISTRY.iter().enumerate() {
            assert_eq!(info.method as usize, i, "{} is out of place", info.name);
            assert_eq!(Method::from_name(info.name), Some(info.method));
            assert_eq!(
                Method::from_name(&format!(" {} ", info.name.to_uppercase())),
                Some(info.method)
            );
            assert!(info.passes >= 1 && info.align >= 1, "{}", info.name);
        }
        let mut names: Vec<&str> = REGISTRY.iter().map(|i| i.name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), REGISTRY.len());
        assert_eq!(Method::all().count(), REGISTRY.len());
        assert_eq!(Method::all().next(), Some(Method::None));
        assert_eq!(Method::from_name("nope"), None);
    }

    /// Tiles' tallies add up to the whole image's (names prefixed as
    /// `auto` prefixes its members'), and their mean is the whole run's
    /// bit for bit.
    #[test]
    fn tallies_of_tiles_are_the_whole_runs() {
        let tally = |name: &str, sum: f64, pixels: usize| Tally {
            name: name.into(),
            sum,
            pixels,
        };
        // 3117 centres over a 1024x16 strip, in tiles of 200, 200, 200, 200, 224 columns.
        let (centres, widths) = (
            [611.0, 640.0, 598.0, 603.0, 665.0],
            [200, 200, 200, 200, 224],
        );
        let whole = Tally::means(&[tally("c", centres.iter().sum(), 1024 * 16)]);
        let mut merged = Vec::new();
        for (c, w) in centres.iter().zip(widths) {
            Tally::merge(&mut merged, Tally::prefixed("lp", [tally("c", *c, w * 16)]));
        }
        assert_eq!(merged.len(), 1);
        assert_eq!(merged[0].pixels, 1024 * 16);
        let tiled = Tally::means(&merged);
        assert_eq!(tiled[0].0, "lp.c");
        assert_eq!(tiled[0].1.to_bits(), whole[0].1.to_bits());
    }
}
