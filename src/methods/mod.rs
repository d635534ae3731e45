//! Sequences of kernels. Each method runs either on the GPU (the kernels) or
//! on the CPU (their scalar twins), selected by [`Backend`]; [`denoise`] is
//! the one entry point the CLI and the benchmarks use.

pub mod gbf;
pub mod lp;
pub mod prepare;
pub mod sampling;
pub mod stats;
pub mod wlr;

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::gpu::{GpuContext, KernelTiming, Precision};
use crate::image::{RgbImage, StatsImage};
use crate::options::Options;

/// Where a method runs.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Backend {
    /// GPU kernels through Vulkan.
    #[default]
    Gpu,
    /// The scalar f64 twins (`crate::reference`).
    Cpu,
}

/// The reconstruction methods of the spec.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
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
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Wlr => "wlr",
            Method::Lp => "lp",
            Method::Apr => "apr",
            Method::Aos => "aos",
            Method::None => "none",
        }
    }

    /// Methods built into this version.
    pub fn available(self) -> bool {
        matches!(self, Method::None | Method::Wlr | Method::Lp)
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

/// What to run.
#[derive(Clone, Debug)]
pub struct DenoiseRequest {
    pub method: Method,
    pub backend: Backend,
    pub precision: Precision,
    pub pass: Pass,
    pub options: Options,
    /// Compute the per-pixel error estimate.
    pub error: bool,
    /// Keep the method's debug maps.
    pub debug: bool,
    /// Report progress on stderr for runs longer than about a second.
    pub progress: bool,
}

impl DenoiseRequest {
    pub fn new(method: Method) -> Self {
        DenoiseRequest {
            method,
            backend: Backend::Gpu,
            precision: Precision::F32,
            pass: Pass::Final,
            options: Options::default(),
            error: false,
            debug: false,
            progress: false,
        }
    }
}

/// What a method returns.
#[derive(Clone, Debug)]
pub struct DenoiseOutput {
    /// The reconstruction, clamped to ≥ 0 (spec §0.4 step 5).
    pub color: RgbImage,
    /// Estimated MSE per pixel and channel, when requested and the method has one.
    pub error: Option<RgbImage>,
    /// Named debug planes.
    pub debug: Vec<(String, Vec<f32>)>,
    /// What sanitation repaired.
    pub report: prepare::PrepareReport,
    /// GPU time per dispatch (empty on the CPU backend).
    pub timings: Vec<KernelTiming>,
    /// Named scalar statistics of the run (LP: `centre_fraction`).
    pub stats: Vec<(String, f64)>,
}

/// Sanitises `img` and reconstructs it with `req.method`. The GPU backend
/// needs `ctx`.
pub fn denoise(
    ctx: Option<&Arc<GpuContext>>,
    img: &StatsImage,
    req: &DenoiseRequest,
) -> Result<DenoiseOutput> {
    if !req.method.available() {
        return Err(Error::InvalidArgument(format!(
            "method {} is not in this build yet: `wlr`, `lp` and `none` (sanitised input) are",
            req.method.name()
        )));
    }
    if req.method == Method::Wlr {
        let params = wlr::WlrParams::new(req.pass, &req.options)?;
        let (result, report, timings) = match req.backend {
            Backend::Cpu => {
                let (clean, report) = clean_cpu(img, req)?;
                (
                    wlr::run_cpu_with_progress(&clean, params, req.progress)?,
                    report,
                    Vec::new(),
                )
            }
            Backend::Gpu => {
                let ctx = gpu_ctx(ctx)?;
                wlr_gpu(ctx, req.precision, img, params, &req.options, req.progress)?
            }
        };
        let mse = result.mse.clone();
        return Ok(DenoiseOutput {
            color: result.color.clone(),
            error: req.error.then(|| {
                RgbImage::from_planes(img.width, img.height, [mse.clone(), mse.clone(), mse])
            }),
            debug: if req.debug {
                result.debug_layers()
            } else {
                Vec::new()
            },
            report,
            timings,
            stats: Vec::new(),
        });
    }
    if req.method == Method::Lp {
        let params = lp::LpParams::new(&req.options)?;
        let (result, report, timings) = match req.backend {
            Backend::Cpu => {
                let (clean, report) = clean_cpu(img, req)?;
                (
                    lp::run_cpu(&clean, params, req.progress)?,
                    report,
                    Vec::new(),
                )
            }
            Backend::Gpu => {
                let ctx = gpu_ctx(ctx)?;
                lp_gpu(ctx, req.precision, img, params, &req.options, req.progress)?
            }
        };
        return Ok(DenoiseOutput {
            color: result.color.clone(),
            error: req.error.then(|| result.error.clone()),
            debug: if req.debug {
                result.debug_layers()
            } else {
                Vec::new()
            },
            report,
            timings,
            stats: vec![("centre_fraction".into(), result.centre_fraction())],
        });
    }
    let (clean, report) = prepare::prepare(ctx, req.backend, req.precision, img)?;
    match req.method {
        Method::None => {
            let mut debug = Vec::new();
            if req.debug {
                let var = clean.get(crate::image::Layer::ColorVariance).unwrap();
                for (c, name) in ["R", "G", "B"].iter().enumerate() {
                    debug.push((format!("color_variance.{name}"), var[c].clone()));
                }
            }
            let timings = report.timings.clone();
            Ok(DenoiseOutput {
                color: prepare::colour_of(&clean),
                error: None,
                debug,
                report,
                timings,
                stats: Vec::new(),
            })
        }
        _ => unreachable!("checked by Method::available"),
    }
}

/// The CPU path's input of WLR and LP: sanitised statistics, prefiltered
/// when `req.options` want it (§1).
fn clean_cpu(
    img: &StatsImage,
    req: &DenoiseRequest,
) -> Result<(StatsImage, prepare::PrepareReport)> {
    use crate::image::Layer;
    if !img.has(Layer::Color) || !img.has(Layer::Spp) {
        return Err(Error::BadData(format!(
            "{} needs the color and spp layers",
            req.method.name().to_uppercase()
        )));
    }
    let (mut clean, report) = prepare::prepare_cpu(img);
    if gbf::wanted(&req.options, |l| clean.has(l))? {
        gbf::run_cpu(&mut clean)?;
    }
    Ok((clean, report))
}

fn gpu_ctx(ctx: Option<&Arc<GpuContext>>) -> Result<&Arc<GpuContext>> {
    ctx.ok_or_else(|| Error::InvalidArgument("the GPU backend needs a context".into()))
}

/// The layers WLR and LP read.
const REGRESSION_LAYERS: [crate::image::Layer; 5] = [
    crate::image::Layer::Color,
    crate::image::Layer::Albedo,
    crate::image::Layer::Normal,
    crate::image::Layer::Depth,
    crate::image::Layer::Spp,
];

/// Uploads `img`, records sanitation, the G-buffer prefilter when `options`
/// want it (§1; the GPU twin of [`clean_cpu`]) and then
/// `record(batch, clean)` in one GPU batch, runs it, and returns the
/// sanitation report and the timings. The caller downloads its outputs
/// afterwards.
fn gpu_chain(
    ctx: &Arc<GpuContext>,
    precision: Precision,
    img: &StatsImage,
    method: Method,
    options: &Options,
    progress: bool,
    record: impl FnOnce(&mut crate::gpu::Batch, &stats::GpuStats) -> Result<()>,
) -> Result<(prepare::PrepareReport, Vec<KernelTiming>)> {
    use crate::image::Layer;
    for l in REGRESSION_LAYERS {
        if !img.has(l) {
            return Err(Error::BadData(format!(
                "{} needs the {} layer",
                method.name().to_uppercase(),
                l.name()
            )));
        }
    }
    let input = stats::GpuStats::upload(ctx, "input", img)?;
    let layers: Vec<Layer> = img.layers().map(|(l, _)| l).collect();
    let clean = stats::GpuStats::new(
        ctx,
        "clean",
        img.width,
        img.height,
        &prepare::output_layers(&layers),
    )?;
    let scratch = prepare::PrepareScratch::new(ctx, &input)?;
    let low_spp = prepare::has_low_spp(img);
    let mut batch = crate::gpu::Batch::new(ctx)?;
    batch.progress = progress;
    prepare::record_prepare(&mut batch, precision, &input, &clean, &scratch, low_spp)?;
    let prefilter = if gbf::wanted(options, |l| img.has(l))? {
        Some(gbf::GbfPlanes::new(ctx, img.width, img.height)?)
    } else {
        None
    };
    if let Some(g) = &prefilter {
        gbf::record_gbf(&mut batch, precision, &clean, g)?;
    }
    record(&mut batch, &clean)?;
    let timings = batch.finish()?;
    let mut report = prepare::base_report(img);
    report.counters = scratch.read_counters()?;
    Ok((report, timings))
}

/// Sanitation and WLR in one GPU batch: one upload, one download.
fn wlr_gpu(
    ctx: &Arc<GpuContext>,
    precision: Precision,
    img: &StatsImage,
    params: wlr::WlrParams,
    options: &Options,
    progress: bool,
) -> Result<(wlr::WlrResult, prepare::PrepareReport, Vec<KernelTiming>)> {
    let planes = wlr::WlrPlanes::new(ctx, img.width, img.height)?;
    let (report, timings) = gpu_chain(
        ctx,
        precision,
        img,
        Method::Wlr,
        options,
        progress,
        |b, clean| wlr::record_wlr(b, precision, clean, &planes, params),
    )?;
    Ok((
        wlr::download(&planes, img.width, img.height)?,
        report,
        timings,
    ))
}

/// Sanitation and LP in one GPU batch: one upload, one download.
fn lp_gpu(
    ctx: &Arc<GpuContext>,
    precision: Precision,
    img: &StatsImage,
    params: lp::LpParams,
    options: &Options,
    progress: bool,
) -> Result<(lp::LpResult, prepare::PrepareReport, Vec<KernelTiming>)> {
    let planes = lp::LpPlanes::new(ctx, img.width, img.height)?;
    let (report, timings) = gpu_chain(
        ctx,
        precision,
        img,
        Method::Lp,
        options,
        progress,
        |b, clean| lp::record_lp(b, precision, clean, &planes, params),
    )?;
    Ok((
        lp::download(&planes, img.width, img.height)?,
        report,
        timings,
    ))
}
