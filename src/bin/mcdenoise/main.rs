//! `mcdenoise`: the command-line face of the library. One module per
//! subcommand under `commands/`; the options they share in `args`, the
//! helpers they share (device, progress, output checks) in `common`.

mod args;
mod commands;
mod common;
mod log;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use commands::{bench, compare, demo, denoise, info, inspect, prefilter, render};

#[derive(Parser)]
#[command(
    name = "mcdenoise",
    version,
    about = "Vulkan compute denoiser and adaptive sampler for Monte Carlo renders",
    long_about = "Vulkan compute denoiser and adaptive sampler for Monte Carlo renders.\n\n\
Input files are render-statistics EXRs (per-pixel mean and variance of colour, albedo, normal, \
depth, optionally position and visibility, and the sample count); see `mcdenoise inspect`.\n\n\
Examples:\n  mcdenoise info\n  mcdenoise inspect render.exr\n  mcdenoise compare out.exr reference.exr --heatmap err.png\n  \
mcdenoise denoise render.exr -o out.exr --png out.png --ref reference.exr"
)]
pub struct Cli {
    /// Vulkan device by index or name substring (see `mcdenoise info`); also MCDENOISE_DEVICE.
    #[arg(long, global = true)]
    device: Option<String>,
    /// Enable the Vulkan validation layer (needs vulkan-validationlayers).
    #[arg(long, global = true)]
    validation: bool,
    /// No progress output on stderr.
    #[arg(long, short, global = true)]
    quiet: bool,
    /// Pipeline cache file (a VkPipelineCache, read at start and written
    /// back when new pipelines were built): drivers that keep compiled
    /// kernels in it skip their compilation next time. Default:
    /// pipelines-<device>.bin in the cache folder (MCDENOISE_CACHE, else
    /// $XDG_CACHE_HOME/mcdenoise, else ~/.cache/mcdenoise).
    #[arg(long, global = true, value_name = "FILE")]
    pipeline_cache: Option<std::path::PathBuf>,
    /// Leave the device's shaderFloat64 and shaderInt64 disabled: run what a
    /// GPU without 64-bit types runs (WLR's steps 6-7 in double-float, AOS's
    /// fits in f32).
    #[arg(long = "no-64bit", global = true)]
    no_64bit: bool,
    /// Build pipelines without a pipeline cache file.
    #[arg(long, global = true, conflicts_with = "pipeline_cache")]
    no_pipeline_cache: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the built-in example (a 64x64 crop of a public 16-spp scene and its
    /// reference, compiled into the binary): inspect it, denoise it with WLR on
    /// the GPU, write the results and print the metrics against the reference.
    Demo(demo::Args),
    /// List Vulkan devices, which one would be used, and the limits that matter.
    Info,
    /// Validate a render-statistics EXR and print its layers, size, spp range,
    /// per-layer min/max/mean and NaN/Inf counts. Exits non-zero if unreadable.
    Inspect(inspect::Args),
    /// Compare an image with a reference: rMSE, relMSE, PSNR and SSIM.
    Compare(compare::Args),
    /// Denoise a render-statistics EXR, or a sequence of them (--frames).
    #[command(after_help = mcdenoise::help_table())]
    Denoise(denoise::Args),
    /// Sanitise a render-statistics EXR and replace its normal, albedo and
    /// depth layers (and their variances) by the G-buffer prefilter's output
    /// (spec §0.4, §6), so other denoisers can use the filtered features.
    /// Needs the position, position_variance and position_covariance layers.
    Prefilter(prefilter::Args),
    /// Render a scene with the built-in Vulkan path tracer, uniformly or
    /// through the adaptive loop (spec §9.3), and reconstruct it.
    #[command(after_help = render::AFTER_HELP)]
    Render(render::Args),
    /// Benchmark the methods: quality against references (--quality DIR) or
    /// the time of whole denoise calls (default).
    #[command(long_about = bench::LONG_ABOUT)]
    Bench(bench::Args),
}

/// Runs the subcommand: `Ok(false)` is exit status 1 (a bound exceeded, a
/// frame failed).
fn run(cli: &Cli) -> anyhow::Result<bool> {
    match &cli.command {
        Command::Demo(a) => demo::run(cli, a),
        Command::Info => info::run(cli).map(|_| true),
        Command::Inspect(a) => inspect::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Denoise(a) => denoise::run(cli, a),
        Command::Prefilter(a) => prefilter::run(cli, a),
        Command::Bench(a) => bench::run(cli, a),
        Command::Render(a) => render::run(cli, a),
    }
}

fn main() -> ExitCode {
    // `mcdenoise compare a b | head -1`: a closed pipe ends the process
    // quietly, as for every Unix filter, instead of a panic in println!.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to the default before any
    // thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // One malloc arena for the whole process: lavapipe's worker threads
    // allocate while they run our dispatches, and glibc gives each thread an
    // arena of its own whose freed pages stay resident (8-12 MB of LP's peak
    // at 1 MP; decision record ONE-ARENA).
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt before any thread is started; M_ARENA_MAX only limits
    // how many arenas the allocator makes.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
    let cli = Cli::parse();
    log::install(cli.quiet);
    match run(&cli) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(e) if matches!(e.downcast_ref(), Some(mcdenoise::Error::Interrupted)) => {
            eprintln!("mcdenoise: interrupted; the output in progress was not written (those finished before are kept)");
            ExitCode::from(130)
        }
        Err(e) => {
            eprintln!("mcdenoise: error: {}", common::error_text(e.as_ref()));
            ExitCode::from(2)
        }
    }
}
