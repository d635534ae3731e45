//! `mcdenoise bench`: the quality and timing benchmarks of
//! [`mcdenoise::bench`], printed as Markdown and written as files.

use std::path::PathBuf;

use anyhow::bail;
use clap::ValueEnum;
use mcdenoise::bench::{self as b, Note};
use mcdenoise::{Backend, Method, Options};

use crate::args::{
    method_parser, parse_size, BlendArg, OutliersArg, PrefilterArg, PyramidArg, TemporalArg,
};
use crate::common::{check_outputs, context};
use crate::Cli;

/// The long help of `mcdenoise bench`.
pub const LONG_ABOUT: &str = "Benchmark the methods through the same API as `denoise`.\n\n\
With --quality DIR: for every scene folder of DIR (sppN.exr inputs and a reference.exr, laid out \
like ../shared/data/scenes/), every spp, method and backend: rMSE, relMSE, PSNR, SSIM against the \
reference, wall and GPU time, and, for methods with an error estimate, the correlation of the \
estimate with the actual error (8x8 tile means; `naive corr` uses the input's colour variance \
instead). Cases are named method.scene.sppN; an `input` row scores the noisy input. Missing or \
unreadable files skip their cases with a warning.\n\n\
Without --quality: times cases named method.inputs.WxH on a synthetic 16-spp frame or --input \
FILE: one warm-up call, then --runs timed calls; median wall time, ms per megapixel and GPU time \
per kernel from timestamp queries.\n\n\
Output: a Markdown table on stdout; --json / --markdown also write it to files.\n\n\
Examples:\n  mcdenoise bench --quality ../shared/data/scenes --methods none\n  \
mcdenoise bench --quality ../shared/data/scenes --filter spp16 --json q.json\n  \
mcdenoise bench --size 512x512 --runs 5\n  mcdenoise bench --input scene/spp16.exr --backend both";

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum BenchBackendArg {
    /// Vulkan compute kernels.
    Gpu,
    /// The scalar f64 reference implementation.
    Cpu,
    /// Both, one row each.
    Both,
}

#[derive(clap::Args)]
pub struct Args {
    /// Quality benchmark over this scenes folder (instead of the timing benchmark).
    #[arg(long, value_name = "DIR")]
    quality: Option<PathBuf>,
    /// The outlier stage (spec §4.4) for every method.
    #[arg(long, value_enum, default_value = "auto")]
    outliers: OutliersArg,
    /// The G-buffer prefilter (spec §6) for every method.
    #[arg(long, value_enum, default_value = "auto")]
    prefilter: PrefilterArg,
    /// The pyramid's low band after every method (auto: after --method auto
    /// only): the method also reconstructs the statistics pooled 2x2, and
    /// the output takes its low-frequency part from that half-resolution
    /// reconstruction where the error estimates favour it. `--pyramid`
    /// alone is `--pyramid=on`
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, require_equals = true, default_missing_value = "on")]
    pyramid: PyramidArg,
    /// The input blend after the method (auto: after every method but
    /// auto, in final reconstructions): each pixel's output is the
    /// method's and the input's, weighed by the method's error estimate,
    /// read as at least the residual's excess over the input's variance,
    /// and the input's variance (--opt blend.radius, blend.k,
    /// blend.residual_radius, blend.z). `--input-blend` alone is
    /// `--input-blend=on`
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, require_equals = true, default_missing_value = "on")]
    input_blend: BlendArg,
    /// A temporal stage (spec §10); the timed calls are its consecutive
    /// frames (for apr, APR's window with --methods apr: each call a full
    /// window's push, one frame's whole work). GPU only.
    #[arg(long, value_enum, default_value = "off")]
    temporal: TemporalArg,
    /// Methods to run, comma-separated [default: every method].
    #[arg(long, value_parser = method_parser(), value_delimiter = ',')]
    methods: Vec<Method>,
    /// Where to run each method.
    #[arg(long, value_enum, default_value = "gpu")]
    backend: BenchBackendArg,
    /// Run only the cases whose name contains this (`a|b`: either).
    #[arg(long)]
    filter: Option<String>,
    /// Also write the results as JSON here.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Also write the Markdown report here.
    #[arg(long, value_name = "FILE")]
    markdown: Option<PathBuf>,
    /// Timing: a render-statistics file instead of the synthetic frame.
    #[arg(long, value_name = "FILE", conflicts_with = "quality")]
    input: Option<PathBuf>,
    /// Timing: frame size; with --input, a centred crop [default: 256x256, or the file's size].
    #[arg(long, value_name = "WxH", conflicts_with = "quality", value_parser = parse_size)]
    size: Option<(usize, usize)>,
    /// Timing: timed runs per case (after one warm-up run).
    #[arg(long, default_value_t = 3, conflicts_with = "quality")]
    runs: usize,
    /// Only the device's limits: FMA GFLOP/s (f32, f64) and copy GB/s,
    /// min/median/max over --runs (the timing benchmark measures them too).
    #[arg(long, conflicts_with_all = ["quality", "input", "size", "methods"])]
    peak: bool,
    /// Method option key=value for every case (repeatable); see
    /// `mcdenoise denoise --help`.
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
}

/// Prints `markdown`, writes it and `json` where asked.
fn emit(
    a: &Args,
    markdown: &str,
    json: impl FnOnce() -> anyhow::Result<String>,
) -> anyhow::Result<()> {
    print!("{markdown}");
    if let Some(path) = &a.json {
        b::write_text(path, &json()?)?;
    }
    if let Some(path) = &a.markdown {
        b::write_text(path, markdown)?;
    }
    Ok(())
}

pub fn run(cli: &Cli, a: &Args) -> anyhow::Result<bool> {
    let backends = match a.backend {
        BenchBackendArg::Gpu => vec![Backend::Gpu],
        BenchBackendArg::Cpu => vec![Backend::Cpu],
        BenchBackendArg::Both => vec![Backend::Gpu, Backend::Cpu],
    };
    let stages = b::Stages {
        outliers: a.outliers.get(),
        prefilter: a.prefilter.get(),
        options: Options::parse(&a.opts)?,
        temporal: a.temporal.get(),
        pyramid: a.pyramid.get(),
        input_blend: a.input_blend.get(),
    };
    let outputs = || {
        [&a.json, &a.markdown]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
    };
    check_outputs(
        outputs(),
        &a.input.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    if let Some(dir) = &a.quality {
        // Every file of the quality folder may be an input.
        if let Ok(dir) = dir.canonicalize() {
            for out in outputs() {
                if out.canonicalize().is_ok_and(|o| o.starts_with(&dir)) {
                    bail!(
                        "{}: refusing to overwrite a file of the --quality folder",
                        out.display()
                    );
                }
            }
        }
    }
    let ctx = if backends.contains(&Backend::Gpu) {
        Some(context(cli)?)
    } else {
        None
    };
    let quiet = cli.quiet;
    let mut note = |n: Note| match n {
        Note::Progress(s) if !quiet => eprintln!("bench: {s}"),
        Note::Progress(_) => {}
        Note::Warning(s) => eprintln!("bench: warning: {s}"),
    };
    if a.peak {
        let ctx = context(cli)?;
        let p = b::measure_peak(&ctx, a.runs)?;
        let markdown = format!(
            "Device: {}\n\nDevice limits ({} runs after a warm-up):\n\n{}",
            ctx.info().name,
            p.runs,
            p.to_markdown()
        );
        emit(
            a,
            &markdown,
            || Ok(serde_json::to_string_pretty(&p)? + "\n"),
        )?;
        return Ok(true);
    }
    let methods = a.methods.clone();
    let (markdown, json, empty) = if let Some(dir) = &a.quality {
        let report = b::run_quality(
            ctx.as_ref(),
            &b::QualityConfig {
                dir: dir.clone(),
                methods,
                backends,
                filter: a.filter.clone(),
                stages,
            },
            &mut note,
        )?;
        (
            report.to_markdown(),
            report.to_json(),
            report.rows.is_empty(),
        )
    } else {
        let report = b::run_timing(
            ctx.as_ref(),
            &b::TimingConfig {
                methods,
                backends,
                input: match &a.input {
                    Some(p) => b::TimingInput::File(p.clone()),
                    None => b::TimingInput::Synthetic,
                },
                size: a.size,
                runs: a.runs,
                filter: a.filter.clone(),
                stages,
            },
            &mut note,
        )?;
        (
            report.to_markdown(),
            report.to_json(),
            report.rows.is_empty(),
        )
    };
    emit(a, &markdown, || Ok(json))?;
    if empty {
        bail!(
            "no benchmark case ran{}",
            a.filter
                .as_ref()
                .map_or(String::new(), |f| format!(" (--filter {f:?})"))
        );
    }
    Ok(true)
}
