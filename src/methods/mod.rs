//! Sequences of kernels. Each method runs either on the GPU (the kernels) or
//! on the CPU (their scalar twins), selected by [`Backend`]; [`denoise`] is
//! the one entry point the CLI and the benchmarks use.

pub mod prepare;
pub mod stats;

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
        matches!(self, Method::None)
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
            "method {} is not in this build yet: only `none` (sanitised input) is",
            req.method.name()
        )));
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
            Ok(DenoiseOutput {
                color: prepare::colour_of(&clean),
                error: None,
                debug,
                report,
                timings: Vec::new(),
            })
        }
        _ => unreachable!("checked by Method::available"),
    }
}
