//! The benchmarks behind `mcdenoise bench`: a **quality** benchmark over a
//! folder of scenes with references, and a **timing** benchmark of whole
//! denoise calls. Both run every method through the [`Denoiser`] facade, the
//! same entry point as the CLI, so a method shows up here as soon as it is
//! in the registry ([`crate::methods::REGISTRY`]).
//!
//! # Cases and filters
//! Every measurement is a *case* with a dotted name:
//!
//! | benchmark | case name | example |
//! |---|---|---|
//! | quality | `method.scene.sppN` (`input.scene.sppN` for the noisy input) | `wlr.dof_checker.spp16` |
//! | timing | `method.inputs.WxH` | `none.synthetic.256x256` |
//!
//! The backend is a column of its own (the same case name can run on both).
//! A filter ([`case_matches`]) selects cases by substring; `a|b` selects the
//! cases matching either alternative.
//!
//! # Quality ([`run_quality`])
//! A folder laid out like `../shared/data/scenes/`: one subfolder per scene
//! holding `sppN.exr` render-statistics files and a `reference.exr` (a folder
//! that itself holds `sppN.exr` files is taken as a single scene). For every
//! scene × spp the noisy input's colour is scored (the `input` row), then
//! every method × backend (on the GPU, the first call of each method is
//! preceded by an untimed warm-up on a 32×32 crop, which builds the
//! pipelines): the denoise call's wall-clock time, its GPU time
//! (sum of the returned [`KernelTiming`]s) and the
//! [`Metrics`](crate::metrics::Metrics) of its colour against the reference. When the method returns an error estimate, the row
//! also holds [`error_correlation`] and [`naive_correlation`]. A file that is
//! missing or unreadable skips the cases that need it with a warning naming
//! the file; the rest of the table is still produced.
//!
//! # Timing ([`run_timing`])
//! One input (the deterministic [`synthetic`] frame, or a render-statistics
//! file, optionally centre-cropped) denoised by every method × backend: one
//! warm-up call (pipelines built, allocations made), then `runs` timed calls.
//! Reported per case: the median wall time, milliseconds per megapixel, and
//! the GPU time per kernel from the device's timestamp queries
//! ([`timings_per_kernel`](crate::gpu::timings_per_kernel)).
//!
//! # Output
//! Reports render as Markdown ([`QualityReport::to_markdown`],
//! [`TimingReport::to_markdown`]) and as JSON ([`QualityReport::to_json`],
//! [`TimingReport::to_json`], written with `serde_json`: non-finite numbers
//! become `null`, absent values are `null`).

// Every public item of the benchmark API is documented; keep it so.
#![warn(missing_docs)]

mod memory;
mod peak;
mod quality;
mod report;
mod scenes;
mod synthetic;
mod timing;

pub use memory::{peak_rss_bytes, reset_peak_rss};
pub use peak::{
    measure_peak, Peak, Spread, COPY_ROWS, COPY_WIDTH, FMA_ITERATIONS, FMA_ROWS, FMA_WIDTH,
};
pub use quality::{
    error_correlation, map_share, naive_correlation, pearson, run_quality, tile_means,
    QualityConfig, QualityReport, QualityRow, QualitySummary, VsWlr, CORRELATION_TILE,
    MAP_BUDGET_PER_PIXEL, WORST_TILE_FRACTION,
};
pub use report::write_text;
pub use scenes::{discover_scenes, Scene};
pub use synthetic::{synthetic, Synthetic, SYNTHETIC_SPP};
pub use timing::{
    inputs_name, run_timing, KernelRow, TimingConfig, TimingInput, TimingReport, TimingRow,
};

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::gpu::{GpuContext, KernelTiming};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::io;
use crate::methods::{Backend, Method};
use crate::{Config, Denoiser, Source};

/// The method called `name` ([`Method::from_name`]).
pub fn method_from_name(name: &str) -> Option<Method> {
    Method::from_name(name)
}

/// `"gpu"` or `"cpu"`: the backend column of the tables.
pub fn backend_name(b: Backend) -> &'static str {
    match b {
        Backend::Gpu => "gpu",
        Backend::Cpu => "cpu",
    }
}

/// Whether the case `name` is selected by `filter`: no filter (or an empty
/// one) selects everything; otherwise the filter is split at `|` and the case
/// is selected if its name contains any of the alternatives (plain substring
/// matching, case-sensitive).
pub fn case_matches(name: &str, filter: Option<&str>) -> bool {
    match filter {
        None | Some("") => true,
        Some(f) => f.split('|').any(|alt| name.contains(alt)),
    }
}

/// Parses `WxH` (e.g. `256x256`; `X` accepted too) into `(width, height)`,
/// both ≥ 1 and within [`io::MAX_DIMENSION`].
pub fn parse_size(s: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::InvalidArgument(format!(
            "size `{s}`: expected WIDTHxHEIGHT, e.g. 256x256, each 1..={}",
            io::MAX_DIMENSION
        ))
    };
    let (w, h) = s.trim().split_once(['x', 'X']).ok_or_else(bad)?;
    let w: usize = w.trim().parse().map_err(|_| bad())?;
    let h: usize = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 || w > io::MAX_DIMENSION || h > io::MAX_DIMENSION {
        return Err(bad());
    }
    Ok((w, h))
}

/// Something a benchmark wants the user to see while it runs.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Note<'a> {
    /// Which case runs now (quiet runs drop these).
    Progress(&'a str),
    /// A case was skipped; also kept in the report.
    Warning(&'a str),
}

/// The methods to run: `requested` deduplicated in order (every method,
/// [`Method::all`], when empty).
fn select_methods(requested: &[Method]) -> Vec<Method> {
    if requested.is_empty() {
        Method::all().collect()
    } else {
        let mut v = Vec::new();
        for &m in requested {
            if !v.contains(&m) {
                v.push(m);
            }
        }
        v
    }
}

fn dedup_backends(b: &[Backend]) -> Vec<Backend> {
    let mut v = Vec::new();
    for &x in if b.is_empty() { &[Backend::Gpu][..] } else { b } {
        if !v.contains(&x) {
            v.push(x);
        }
    }
    v
}

fn check_context(ctx: Option<&Arc<GpuContext>>, backends: &[Backend]) -> Result<()> {
    if backends.contains(&Backend::Gpu) && ctx.is_none() {
        return Err(Error::InvalidArgument(
            "the GPU backend needs a Vulkan context".into(),
        ));
    }
    Ok(())
}

/// The benchmarks' front door: a [`Denoiser`] (the public facade) for
/// `img`'s size and layers with the method's defaults, on the GPU (`ctx`) or
/// on the CPU references, with the optional stages as `stages` says.
fn denoiser(
    ctx: Option<&Arc<GpuContext>>,
    img: &StatsImage,
    method: Method,
    backend: Backend,
    stages: &Stages,
) -> Result<Denoiser> {
    let source = Source::of_image(img);
    let config = config(img, method, stages);
    match backend {
        Backend::Gpu => {
            let ctx = ctx.ok_or_else(|| {
                Error::InvalidArgument("the GPU backend needs a Vulkan context".into())
            })?;
            Denoiser::new(ctx, source, config)
        }
        Backend::Cpu => Denoiser::new_cpu(source, config),
    }
}

/// The configuration of a benchmarked call on `img`: the method's defaults
/// with `stages`.
fn config(img: &StatsImage, method: Method, stages: &Stages) -> Config {
    let mut config = Config::new(method);
    config.outliers = stages.outliers;
    config.prefilter = stages.prefilter;
    config.options = stages.options.clone();
    config.temporal = stages.temporal;
    config.pyramid = stages.pyramid;
    config.input_blend = stages.input_blend;
    config.low_spp = crate::has_low_spp(img);
    config
}

/// The optional stages and method options of every benchmarked call.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stages {
    /// The outlier stage (§4.4).
    pub outliers: crate::Outliers,
    /// The G-buffer prefilter (§6).
    pub prefilter: crate::Prefilter,
    /// `--opt KEY=VALUE` method options (those of other methods are ignored
    /// by a method, as in `denoise`).
    pub options: crate::options::Options,
    /// The temporal stage (§10) after the method: the timed calls are
    /// consecutive frames (of the same statistics) for it.
    pub temporal: crate::Temporal,
    /// The pyramid's low band (PYRAMID-LOWBAND) after the method (`Auto`:
    /// after `auto` only).
    pub pyramid: crate::Pyramid,
    /// The input blend (INPUT-BLEND) after the method (`Auto`: after
    /// AOS).
    pub input_blend: crate::InputBlend,
}

impl Stages {
    /// One line for the reports: `outliers auto, prefilter auto`, the
    /// temporal stage when there is one, and the options given, `key=value` in key order.
    pub fn describe(&self) -> String {
        let mut s = format!(
            "outliers {:?}, prefilter {:?}",
            self.outliers, self.prefilter
        )
        .to_lowercase();
        if self.pyramid != crate::Pyramid::Auto {
            s.push_str(&format!(", pyramid {:?}", self.pyramid).to_lowercase());
        }
        if self.input_blend != crate::InputBlend::Auto {
            s.push_str(&format!(", input blend {:?}", self.input_blend).to_lowercase());
        }
        if self.temporal != crate::Temporal::Off {
            s.push_str(&format!(", temporal {:?}", self.temporal).to_lowercase());
        }
        let mut keys: Vec<&str> = self.options.keys().collect();
        keys.sort_unstable();
        for k in keys {
            s.push_str(&format!(", {k}={}", self.options.get(k)));
        }
        s
    }
}

/// The budget of the quality benchmark's sample maps: [`MAP_BUDGET_PER_PIXEL`]
/// samples per pixel (the benchmark scores where the map sends them; for
/// `none` the map of §9.1 with `E = v`, `d = 0`, the plain Monte Carlo
/// baseline).
fn map_budget(pixels: usize) -> u32 {
    (pixels as u64 * MAP_BUDGET_PER_PIXEL as u64).min(u32::MAX as u64) as u32
}

/// Sum of the GPU times in milliseconds; `None` when nothing was timed (the
/// CPU backend, or a method that reports no timings).
fn gpu_ms(t: &[KernelTiming]) -> Option<f64> {
    (!t.is_empty()).then(|| t.iter().map(|k| k.nanoseconds).sum::<f64>() / 1e6)
}

/// The colour layer of a statistics image, as stored (no sanitation).
fn colour_layer(img: &StatsImage) -> Option<RgbImage> {
    let c = img.get(Layer::Color)?;
    Some(RgbImage::from_planes(
        img.width,
        img.height,
        [c[0].clone(), c[1].clone(), c[2].clone()],
    ))
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_describe_the_settings() {
        assert_eq!(
            Stages::default().describe(),
            "outliers auto, prefilter auto"
        );
        let s = Stages {
            outliers: crate::Outliers::Off,
            prefilter: crate::Prefilter::On,
            options: crate::options::Options::parse(&["aos.variance=sandwich", "aos.residual=off"])
                .unwrap(),
            temporal: crate::Temporal::Off,
            pyramid: crate::Pyramid::Auto,
            input_blend: crate::InputBlend::Auto,
        };
        assert_eq!(
            s.describe(),
            "outliers off, prefilter on, aos.residual=off, aos.variance=sandwich"
        );
    }

    #[test]
    fn filters_and_sizes() {
        assert!(case_matches("none.dof_checker.spp16", None));
        assert!(case_matches("none.dof_checker.spp16", Some("")));
        assert!(case_matches("none.dof_checker.spp16", Some("spp16")));
        assert!(case_matches("none.dof_checker.spp16", Some("wlr|dof")));
        assert!(!case_matches("none.dof_checker.spp16", Some("spp4")));
        assert_eq!(parse_size("256x128").unwrap(), (256, 128));
        assert_eq!(parse_size(" 3X5 ").unwrap(), (3, 5));
        for bad in ["256", "0x4", "ax4", "4x", "99999999x1"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(method_from_name("WLR"), Some(Method::Wlr));
        assert_eq!(method_from_name("x"), None);
    }
}
