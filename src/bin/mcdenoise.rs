//! `mcdenoise`: the command-line face of the library.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{bail, Context};
use clap::{Parser, Subcommand, ValueEnum};

use mcdenoise::io;
use mcdenoise::metrics;
use mcdenoise::{
    colour_of, has_low_spp, help_table, Backend, Config, ContextOptions, Denoiser, GpuContext,
    Method, Options, Outliers, Pass, Precision, Prefilter, PrepareReport, Source, StatsImage,
    Validation,
};

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
struct Cli {
    /// Vulkan device by index or name substring (see `mcdenoise info`); also MCDENOISE_DEVICE.
    #[arg(long, global = true)]
    device: Option<String>,
    /// Enable the Vulkan validation layer (needs vulkan-validationlayers).
    #[arg(long, global = true)]
    validation: bool,
    /// No progress output on stderr.
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
enum MethodArg {
    /// Weighted local regression (spec §2).
    Wlr,
    /// Linear predictions at sparse centres (spec §3).
    Lp,
    /// Adaptive polynomial rendering: per-block polynomial order (spec §4).
    Apr,
    /// Adaptive-order polynomial fitting in feature space: per-pixel order 1 or 3 (spec §5).
    Aos,
    /// No reconstruction: the sanitised input colour (spec §0.4), for checking
    /// inputs, the pipeline and the metrics.
    None,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
enum BackendArg {
    /// Vulkan compute kernels.
    Gpu,
    /// The scalar f64 reference implementation (slow, for checking).
    Cpu,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
enum PassArg {
    /// The final reconstruction (large windows).
    Final,
    /// An adaptive pass's reconstruction (the spec's intermediate windows).
    Intermediate,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
enum PrecisionArg {
    F32,
    F64,
}

impl PrecisionArg {
    fn get(self) -> Precision {
        match self {
            PrecisionArg::F32 => Precision::F32,
            PrecisionArg::F64 => Precision::F64,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
enum PrefilterArg {
    /// The G-buffer prefilter when the input has position, position_variance
    /// and position_covariance, for wlr, lp and apr; none otherwise, and
    /// none for aos (its own NL-means prefilter does better there).
    Auto,
    /// G-buffer prefilter with world positions and SURE (spec §6); an error
    /// without the position layers.
    Gbf,
    /// No prefilter.
    None,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
enum OutliersArg {
    /// On for every reconstruction, off for `--method none`.
    Auto,
    /// Remove bright spikes before the method and put their energy back
    /// around them after it (spec §4.4).
    On,
    /// Keep spikes in the input.
    Off,
}

impl OutliersArg {
    fn get(self) -> Outliers {
        match self {
            OutliersArg::Auto => Outliers::Auto,
            OutliersArg::On => Outliers::On,
            OutliersArg::Off => Outliers::Off,
        }
    }
}

impl PrefilterArg {
    fn get(self) -> Prefilter {
        match self {
            PrefilterArg::Auto => Prefilter::Auto,
            PrefilterArg::Gbf => Prefilter::On,
            PrefilterArg::None => Prefilter::Off,
        }
    }
}

impl MethodArg {
    fn get(self) -> Method {
        match self {
            MethodArg::Wlr => Method::Wlr,
            MethodArg::Lp => Method::Lp,
            MethodArg::Apr => Method::Apr,
            MethodArg::Aos => Method::Aos,
            MethodArg::None => Method::None,
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Run the built-in example (a 64x64 crop of a public 16-spp scene and its
    /// reference, compiled into the binary): inspect it, denoise it with WLR on
    /// the GPU, write the results and print the metrics against the reference.
    Demo {
        /// Folder for the example's files and outputs.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
    },
    /// List Vulkan devices, which one would be used, and the limits that matter.
    Info,
    /// Validate a render-statistics EXR and print its layers, size, spp range,
    /// per-layer min/max/mean and NaN/Inf counts. Exits non-zero if unreadable.
    Inspect { file: PathBuf },
    /// Compare an image with a reference: rMSE, relMSE, PSNR and SSIM.
    Compare {
        image: PathBuf,
        reference: PathBuf,
        /// Write a per-pixel rMSE picture (PNG).
        #[arg(long)]
        heatmap: Option<PathBuf>,
        /// Exit with status 1 if rMSE exceeds this.
        #[arg(long)]
        max_error: Option<f64>,
    },
    /// Denoise a render-statistics EXR, or a sequence of them (--frames).
    #[command(after_help = help_table())]
    Denoise {
        #[arg(required_unless_present = "frames")]
        input: Option<PathBuf>,
        /// Output EXR (color.R/G/B, plus error.*, samples.Y, debug.* on request);
        /// with --frames, a pattern such as out/frame_####.exr.
        #[arg(short, long)]
        output: PathBuf,
        /// Denoise every existing frame of a sequence, such as
        /// 'dir/frame_####.exr' (the #s: the zero-padded frame number), into
        /// the --output pattern, with one device and one set of pipelines. A
        /// bad frame is reported and skipped; the exit status is 1 if any
        /// frame failed.
        #[arg(long, value_name = "PATTERN", conflicts_with_all = ["input", "sample_map", "png", "reference"])]
        frames: Option<PathBuf>,
        /// With --frames: skip frames whose output exists and reads as a
        /// complete image.
        #[arg(long)]
        resume: bool,
        #[arg(long, value_enum, default_value = "wlr")]
        method: MethodArg,
        #[arg(long, value_enum, default_value = "gpu")]
        backend: BackendArg,
        /// Kernel arithmetic on the GPU (f64 where the device supports it).
        #[arg(long, value_enum, default_value = "f32")]
        precision: PrecisionArg,
        #[arg(long, value_enum, default_value = "final")]
        pass: PassArg,
        /// Feature prefilter before the method (spec §1, §6).
        #[arg(long, value_enum, default_value = "auto")]
        prefilter: PrefilterArg,
        /// Energy-preserving firefly removal around the method (spec §4.4).
        #[arg(long, value_enum, default_value = "auto")]
        outliers: OutliersArg,
        /// Add the estimated per-pixel MSE as error.R/G/B (method none: the
        /// variance of the mean).
        #[arg(long)]
        error: bool,
        /// Write the next pass's samples per pixel (spec §9) to this EXR, as
        /// a u32 channel samples.Y summing to exactly --budget (also added to
        /// the output as samples.Y).
        #[arg(long, value_name = "MAP.exr", requires = "budget")]
        sample_map: Option<PathBuf>,
        /// Samples to distribute for the next pass (0 ..= 4294967295).
        #[arg(long, requires = "sample_map")]
        budget: Option<u32>,
        /// Add the method's debug maps as debug.* layers.
        #[arg(long)]
        debug_layers: bool,
        /// Also write a tone-mapped PNG preview here.
        #[arg(long)]
        png: Option<PathBuf>,
        /// Reference image: print compare's metrics after denoising.
        #[arg(long = "ref")]
        reference: Option<PathBuf>,
        /// With --ref: exit with status 1 if rMSE exceeds this.
        #[arg(long, requires = "reference")]
        max_error: Option<f64>,
        /// Method option key=value (repeatable); the list is below.
        #[arg(long = "opt", value_name = "KEY=VALUE")]
        opts: Vec<String>,
        /// Device memory cap in MB (GPU): an image whose chain needs more is
        /// denoised in tiles that fit, each with the halo its method's
        /// windows need; the output is bit-identical to a whole run.
        /// Default: three quarters of the device's largest local heap.
        #[arg(long, value_name = "MB", value_parser = clap::value_parser!(u64).range(1..))]
        max_memory: Option<u64>,
        /// Denoise in tiles of at most N×N pixels (plus halo) even when the
        /// whole image fits (GPU).
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        tile: Option<u64>,
    },
    /// Sanitise a render-statistics EXR and replace its normal, albedo and
    /// depth layers (and their variances) by the G-buffer prefilter's output
    /// (spec §0.4, §6), so other denoisers can use the filtered features.
    /// Needs the position, position_variance and position_covariance layers.
    Prefilter {
        input: PathBuf,
        /// Output render-statistics EXR.
        #[arg(short, long)]
        output: PathBuf,
        /// Kernel arithmetic on the GPU.
        #[arg(long, value_enum, default_value = "f32")]
        precision: PrecisionArg,
        /// Device memory cap in MB: an image whose chain needs more is
        /// prefiltered in tiles that fit, each with the halo the windows
        /// need; the output is bit-identical to a whole run. Default: three
        /// quarters of the device's largest local heap.
        #[arg(long, value_name = "MB", value_parser = clap::value_parser!(u64).range(1..))]
        max_memory: Option<u64>,
        /// Prefilter in tiles of at most N×N pixels (plus halo) even when the
        /// whole image fits.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        tile: Option<u64>,
    },
    /// Render a scene with the built-in Vulkan path tracer, uniformly or
    /// through the adaptive loop (spec §9.3), and reconstruct it.
    #[command(after_help = "Examples:\n  mcdenoise render --list-scenes\n  \
mcdenoise render --scene cornell --spp 16 --adaptive -o out.exr --png out.png --reference 1024\n  \
mcdenoise render --scene my_scene.toml --spp 64 --method lp --save-stats stats.exr -o out.exr")]
    Render(RenderArgs),
    /// Benchmark the methods: quality against references (--quality DIR) or
    /// the time of whole denoise calls (default).
    #[command(long_about = BENCH_LONG_ABOUT)]
    Bench(BenchArgs),
}

/// A progress bar on stderr for a GPU denoiser when stderr is a terminal and
/// not --quiet (nothing otherwise: logs and pipes stay clean).
fn progress_bar(cli: &Cli, denoiser: &mut Denoiser) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    if cli.quiet || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] [{wide_bar}] {percent:>3}% {msg}",
        )
        .ok()?,
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let b = bar.clone();
    denoiser.set_progress(Some(Arc::new(move |fraction: f64, kernel: &str| {
        b.set_position((fraction * 1000.0) as u64);
        b.set_message(kernel.to_string());
    })));
    Some(bar)
}

fn context(cli: &Cli) -> anyhow::Result<Arc<GpuContext>> {
    let ctx = GpuContext::new(&ContextOptions {
        device: cli.device.clone(),
        validation: if cli.validation {
            Validation::Required
        } else {
            Validation::Off
        },
    })?;
    Ok(Arc::new(ctx))
}

fn info(cli: &Cli) -> anyhow::Result<()> {
    let devices = mcdenoise::enumerate_devices()?;
    let chosen = mcdenoise::choose_device(&devices, cli.device.as_deref()).ok();
    if devices.is_empty() {
        bail!("the Vulkan loader found no device; for the software device: apt-get install mesa-vulkan-drivers");
    }
    for d in &devices {
        let mark = if Some(d.index) == chosen { "*" } else { " " };
        println!(
            "{mark} [{}] {} ({:?}, Vulkan {}.{}.{}, driver {})",
            d.index, d.name, d.kind, d.api_version.0, d.api_version.1, d.api_version.2, d.driver
        );
        println!(
            "      maxStorageBufferRange      {} bytes ({} MiB)",
            d.max_storage_buffer_range,
            d.max_storage_buffer_range / (1 << 20)
        );
        println!(
            "      storage buffers per stage  {}",
            d.max_per_stage_storage_buffers
        );
        println!(
            "      device-local heap          {} MiB (default memory cap {} MiB)",
            d.device_local_heap >> 20,
            mcdenoise::default_memory_cap(d) >> 20
        );
        println!(
            "      shaderFloat64              {}",
            if d.shader_float64 { "yes" } else { "no" }
        );
        println!(
            "      shaderInt64                {}",
            if d.shader_int64 { "yes" } else { "no" }
        );
        println!("      subgroup size              {}", d.subgroup_size);
        println!(
            "      shared memory              {} bytes",
            d.max_shared_memory
        );
        println!(
            "      push constants             {} bytes",
            d.max_push_constants_size
        );
        println!(
            "      timestamp period           {} ns",
            d.timestamp_period_ns
        );
        println!(
            "      compute queue              {}",
            if d.has_compute_queue { "yes" } else { "no" }
        );
    }
    if chosen.is_none() {
        bail!("no usable device among these");
    }
    println!("* = would be used (override with --device or MCDENOISE_DEVICE)");
    Ok(())
}

fn print_metrics(m: &metrics::Metrics) {
    println!("rMSE    {:.5}", m.rmse);
    println!("relMSE  {:.5}", m.relmse);
    println!("PSNR    {:.2} dB", m.psnr);
    println!("SSIM    {:.4}", m.ssim);
}

/// Reads the colour of `path`: a render-statistics file or a plain RGB image.
fn read_colour(path: &Path) -> anyhow::Result<mcdenoise::image::RgbImage> {
    Ok(io::read_rgb(path)?)
}

fn check_error(rmse: f64, max: Option<f64>) -> anyhow::Result<bool> {
    if let Some(max) = max {
        if rmse.is_nan() || rmse > max {
            eprintln!("rMSE {rmse:.5} exceeds --max-error {max}");
            return Ok(false);
        }
    }
    Ok(true)
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

fn run(cli: Cli) -> anyhow::Result<bool> {
    match &cli.command {
        Command::Demo { out } => demo(&cli, out),
        Command::Info => info(&cli).map(|_| true),
        Command::Inspect { file } => {
            let img = io::read_stats(file)?;
            println!("{}", io::format_report(file, &img).trim_end());
            Ok(true)
        }
        Command::Compare {
            image,
            reference,
            heatmap,
            max_error,
        } => {
            let x = read_colour(image)?;
            let r = read_colour(reference)?;
            let m = metrics::compare(&x, &r)
                .with_context(|| format!("{} vs {}", image.display(), reference.display()))?;
            print_metrics(&m);
            if let Some(h) = heatmap {
                let map = metrics::rmse_heatmap(&x, &r)?;
                let mut sorted: Vec<f32> = map.iter().copied().filter(|v| v.is_finite()).collect();
                sorted.sort_by(|a, b| a.total_cmp(b));
                let p99 = sorted
                    .get(sorted.len() * 99 / 100)
                    .copied()
                    .unwrap_or(1.0)
                    .max(1e-8);
                io::write_heatmap_png(h, x.width, x.height, &map, p99)?;
                eprintln!(
                    "heat map: {} (scale 0..{p99:.4}, the 99th percentile)",
                    h.display()
                );
            }
            check_error(m.rmse, *max_error)
        }
        Command::Denoise {
            input,
            output,
            frames,
            resume,
            method,
            backend,
            precision,
            pass,
            prefilter,
            outliers,
            error,
            sample_map,
            budget,
            debug_layers,
            png,
            reference,
            max_error,
            opts,
            max_memory,
            tile,
        } => {
            let options = Options::parse(opts)?;
            let method = method.get();
            if (max_memory.is_some() || tile.is_some()) && matches!(backend, BackendArg::Cpu) {
                bail!("--max-memory and --tile apply to the GPU backend");
            }
            // Everything but what only the pixels tell (low_spp).
            let base_config = || {
                let mut config = Config::new(method);
                config.precision = precision.get();
                config.pass = match pass {
                    PassArg::Final => Pass::Final,
                    PassArg::Intermediate => Pass::Intermediate,
                };
                config.prefilter = prefilter.get();
                config.outliers = outliers.get();
                config.options = options.clone();
                config.debug = *debug_layers;
                // The error estimate comes back only when it is written.
                config.error = *error;
                config.progress = !cli.quiet;
                config.max_memory = max_memory.map(|mb| mb.saturating_mul(1 << 20));
                config.tile = tile.map(|t| t as usize);
                config
            };
            let config_for = |img: &StatsImage| {
                let mut config = base_config();
                config.low_spp = has_low_spp(img);
                config
            };
            // The warm-up's, before the pixels are read: as if every pixel
            // had 2 samples or more (the usual render), so the spp < 2
            // stage's pipeline (resident memory for the process's life) is
            // built only by a call whose pixels need it.
            let warm_config = || {
                let mut config = base_config();
                config.low_spp = false;
                config
            };
            let Some(input) = input else {
                let frames = frames.as_ref().expect("clap: input or --frames");
                return denoise_frames(
                    &cli,
                    frames,
                    output,
                    *resume,
                    *backend,
                    *error,
                    &warm_config(),
                    &config_for,
                );
            };
            if *resume {
                // clap's `requires` does not hold a flag back here.
                bail!("--resume needs --frames");
            }
            for path in [Some(output), png.as_ref(), sample_map.as_ref()]
                .into_iter()
                .flatten()
            {
                if same_file(path, input) || reference.as_ref().is_some_and(|r| same_file(path, r))
                {
                    bail!("{}: refusing to overwrite an input file", path.display());
                }
            }
            // The pipelines build while the file is read (from its headers'
            // layers); a file whose headers do not read goes straight to
            // read_stats, whose error names the problem.
            let hint = match backend {
                BackendArg::Gpu => io::read_stats_layers(input).ok(),
                BackendArg::Cpu => None,
            };
            let (mut ctx, mut warm) = (None, None);
            if let Some((width, height, layers)) = hint {
                let c = context(&cli)?;
                let source = Source::Stats {
                    width,
                    height,
                    layers,
                };
                warm = Some(Denoiser::warm_up(
                    &c,
                    &source,
                    &warm_config(),
                    budget.is_some(),
                ));
                ctx = Some(c);
            }
            let img = io::read_stats(input)?;
            let config = config_for(&img);
            let source = Source::of_image(&img);
            let mut denoiser = match backend {
                BackendArg::Gpu => {
                    let ctx = match ctx {
                        Some(c) => c,
                        None => context(&cli)?,
                    };
                    Denoiser::new(&ctx, source, config)?
                }
                BackendArg::Cpu => Denoiser::new_cpu(source, config)?,
            };
            drop(warm);
            let bar = progress_bar(&cli, &mut denoiser);
            let t0 = std::time::Instant::now();
            let (width, height) = (img.width, img.height);
            // The host's copy of the statistics goes once they are uploaded.
            let result = denoiser.denoise_owned(img, *budget);
            if let Some(b) = bar {
                b.finish_and_clear();
            }
            let result = result.with_context(|| input.display().to_string())?;
            if !cli.quiet {
                print_report(&result.report, input);
                let tiles = match denoiser.tiles() {
                    Some((t, halo)) => format!(", {} tiles with a halo of {halo} px", t.len()),
                    None => String::new(),
                };
                eprintln!(
                    "{} ({:?}{}{tiles}) in {:.2} s",
                    method.name(),
                    backend,
                    if denoiser.prefiltered() {
                        ", G-buffer prefilter"
                    } else {
                        ""
                    },
                    t0.elapsed().as_secs_f64()
                );
            }
            // The device memory goes before the writer needs its own.
            drop(denoiser);
            let out = io::OutputImage {
                color: result.color,
                error: error.then_some(result.error),
                samples: result
                    .samples
                    .as_ref()
                    .map(|s| s.iter().map(|&v| v as f32).collect()),
                debug: result.debug,
            };
            io::write_output(output, &out)?;
            if let (Some(path), Some(s)) = (sample_map, &result.samples) {
                io::write_samples(path, width, height, s)?;
                if !cli.quiet {
                    let max = s.iter().max().copied().unwrap_or(0);
                    let zero = s.iter().filter(|&&v| v == 0).count();
                    eprintln!(
                        "{}: {} samples (budget {}), max {max} per pixel, {zero} pixels get none",
                        path.display(),
                        s.iter().map(|&v| v as u64).sum::<u64>(),
                        budget.unwrap_or(0)
                    );
                }
            }
            if let Some(p) = png {
                io::write_png_preview(p, &out.color)?;
            }
            if let Some(r) = reference {
                let r = read_colour(r)?;
                let m = metrics::compare(&out.color, &r)?;
                print_metrics(&m);
                return check_error(m.rmse, *max_error);
            }
            Ok(true)
        }
        Command::Prefilter {
            input,
            output,
            precision,
            max_memory,
            tile,
        } => {
            if same_file(output, input) {
                bail!("{}: refusing to overwrite an input file", output.display());
            }
            let img = io::read_stats(input)?;
            let mut config = Config::new(Method::None);
            config.prefilter = Prefilter::On;
            config.precision = precision.get();
            config.low_spp = has_low_spp(&img);
            config.max_memory = max_memory.map(|mb| mb.saturating_mul(1 << 20));
            config.tile = tile.map(|t| t as usize);
            let denoiser = Denoiser::new(&context(&cli)?, Source::of_image(&img), config)
                .with_context(|| input.display().to_string())?;
            // Tiled when the image does not fit one chain: the statistics
            // then come from the tiles' interiors.
            let (result, stats) = denoiser.denoise_with_statistics(&img, None)?;
            drop(img);
            if !cli.quiet {
                print_report(&result.report, input);
            }
            io::write_stats(output, &stats)?;
            if !cli.quiet {
                eprintln!(
                    "{}: sanitised statistics with G-buffer-prefiltered normal, albedo and depth",
                    output.display()
                );
            }
            Ok(true)
        }
        Command::Bench(args) => bench(&cli, args),
        Command::Render(args) => render(&cli, args),
    }
}

/// `denoise --frames`: every existing frame of `pattern` into `output`'s
/// pattern, on one device; a denoiser is reused while the frames keep their
/// size and layers. A frame that fails is reported and skipped; the summary
/// lists them, and the result is `false` (exit status 1) if any failed.
fn denoise_frames(
    cli: &Cli,
    pattern: &Path,
    output: &Path,
    resume: bool,
    backend: BackendArg,
    error: bool,
    warm_config: &Config,
    config_for: &dyn Fn(&StatsImage) -> Config,
) -> anyhow::Result<bool> {
    let inp = io::frames::FramePattern::parse(pattern)?;
    let outp = io::frames::FramePattern::parse(output)?;
    let frames = inp.list()?;
    // Every input frame, resolved, so that no output (of any frame number)
    // lands on an input, through a symbolic link either.
    let inputs: std::collections::HashSet<PathBuf> = frames
        .iter()
        .filter_map(|f| f.path.canonicalize().ok())
        .collect();
    if frames
        .iter()
        .any(|f| inputs.contains(&outp.path(f.number).canonicalize().unwrap_or_default()))
    {
        bail!(
            "{}: refusing to overwrite input frames ({} names them)",
            output.display(),
            pattern.display()
        );
    }
    let ctx = match backend {
        BackendArg::Gpu => Some(context(cli)?),
        BackendArg::Cpu => None,
    };
    // The pipelines build while the first frame that needs them is read.
    let mut warm: Option<mcdenoise::WarmUp> = None;
    let mut warmed = false;
    let mut cached: Option<(Source, bool, Denoiser)> = None;
    let (mut done, mut skipped) = (0usize, 0usize);
    let mut failed: Vec<(u64, String)> = Vec::new();
    let t0 = std::time::Instant::now();
    for frame in &frames {
        let out = outp.path(frame.number);
        if resume && out.exists() && io::read_rgb(&out).is_ok() {
            skipped += 1;
            continue;
        }
        let mut attempt = || -> anyhow::Result<()> {
            if let (false, Some(ctx)) = (warmed, &ctx) {
                warmed = true;
                if let Ok((width, height, layers)) = io::read_stats_layers(&frame.path) {
                    let source = Source::Stats {
                        width,
                        height,
                        layers,
                    };
                    warm = Some(Denoiser::warm_up(ctx, &source, warm_config, false));
                }
            }
            let img = io::read_stats(&frame.path)?;
            let source = Source::of_image(&img);
            let low_spp = has_low_spp(&img);
            let reuse = matches!(&cached, Some((s, l, _)) if *s == source && *l == low_spp);
            if !reuse {
                // The previous chain's buffers go before the next one's.
                cached = None;
                let config = config_for(&img);
                let d = match &ctx {
                    Some(ctx) => Denoiser::new(ctx, source.clone(), config)?,
                    None => Denoiser::new_cpu(source.clone(), config)?,
                };
                cached = Some((source, low_spp, d));
                warm.take();
            }
            let denoiser = &cached.as_ref().expect("just set").2;
            let result = denoiser.denoise_owned(img, None)?;
            if !cli.quiet {
                print_report(&result.report, &frame.path);
            }
            io::write_output(
                &out,
                &io::OutputImage {
                    color: result.color,
                    error: error.then_some(result.error),
                    samples: None,
                    debug: result.debug,
                },
            )?;
            Ok(())
        };
        match attempt() {
            Ok(()) => {
                done += 1;
                if !cli.quiet {
                    eprintln!(
                        "frame {}: {} -> {}",
                        frame.number,
                        frame.path.display(),
                        out.display()
                    );
                }
            }
            Err(e) => {
                let msg = format!("{e:#}");
                eprintln!(
                    "frame {}: {} failed: {msg}",
                    frame.number,
                    frame.path.display()
                );
                failed.push((frame.number, msg));
            }
        }
    }
    eprintln!(
        "{} frames in {:.1} s: {done} denoised, {skipped} skipped (output complete, --resume), {} failed",
        frames.len(),
        t0.elapsed().as_secs_f64(),
        failed.len()
    );
    for (n, msg) in &failed {
        eprintln!("  failed frame {n}: {msg}");
    }
    Ok(failed.is_empty())
}

/// The built-in example: `tests/fixtures/dof_checker_64_*.exr`.
const DEMO_INPUT: &[u8] = include_bytes!("../../tests/fixtures/dof_checker_64_spp16.exr");
const DEMO_REFERENCE: &[u8] = include_bytes!("../../tests/fixtures/dof_checker_64_ref.exr");

fn demo(cli: &Cli, out: &Path) -> anyhow::Result<bool> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let input = out.join("input.exr");
    let reference = out.join("reference.exr");
    std::fs::write(&input, DEMO_INPUT).with_context(|| input.display().to_string())?;
    std::fs::write(&reference, DEMO_REFERENCE).with_context(|| reference.display().to_string())?;
    let img = io::read_stats(&input)?;
    println!("{}", io::format_report(&input, &img).trim_end());
    println!();
    let ctx = context(cli)?;
    println!("device: {}", ctx.info().name);
    let r = io::read_rgb(&reference)?;
    let input_metrics = metrics::compare(&colour_of(&img), &r)?;
    let mut config = Config::new(Method::Wlr);
    config.debug = true;
    config.low_spp = has_low_spp(&img);
    let denoiser = Denoiser::new(&ctx, Source::of_image(&img), config)?;
    let t0 = std::time::Instant::now();
    let result = denoiser.denoise(&img, None)?;
    let secs = t0.elapsed().as_secs_f64();
    print_report(&result.report, &input);
    let output = out.join("output.exr");
    let preview = out.join("output.png");
    let input_preview = out.join("input.png");
    io::write_output(
        &output,
        &io::OutputImage {
            color: result.color.clone(),
            error: Some(result.error.clone()),
            samples: None,
            debug: result.debug.clone(),
        },
    )?;
    io::write_png_preview(&preview, &result.color)?;
    io::write_png_preview(&input_preview, &colour_of(&img))?;
    println!(
        "WLR on the GPU in {secs:.2} s (the first run on lavapipe also compiles the kernels) -> {} (color, error, debug layers), {}",
        output.display(),
        preview.display()
    );
    let gpu_ms: f64 = result.timings.iter().map(|t| t.nanoseconds).sum::<f64>() / 1e6;
    for (k, ns, n) in mcdenoise::timings_per_kernel(&result.timings) {
        println!("  {k:<18} {:>9.1} ms  ({n} dispatches)", ns / 1e6);
    }
    println!("  {:<18} {gpu_ms:>9.1} ms", "total GPU");
    let m = metrics::compare(&result.color, &r)?;
    println!("\nagainst {}:          input     WLR", reference.display());
    println!(
        "  rMSE            {:>9.5} {:>9.5}",
        input_metrics.rmse, m.rmse
    );
    println!(
        "  relMSE          {:>9.5} {:>9.5}",
        input_metrics.relmse, m.relmse
    );
    println!(
        "  PSNR (dB)       {:>9.2} {:>9.2}",
        input_metrics.psnr, m.psnr
    );
    println!(
        "  SSIM            {:>9.4} {:>9.4}",
        input_metrics.ssim, m.ssim
    );
    Ok(true)
}

fn print_report(r: &PrepareReport, input: &Path) {
    for line in r.messages(input) {
        eprintln!("{line}");
    }
}

/// The long help of `mcdenoise bench`.
const BENCH_LONG_ABOUT: &str = "Benchmark the methods through the same API as `denoise`.\n\n\
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

#[derive(clap::Args)]
struct BenchArgs {
    /// Quality benchmark over this scenes folder (instead of the timing benchmark).
    #[arg(long, value_name = "DIR")]
    quality: Option<PathBuf>,
    /// The outlier stage (spec §4.4) for every method.
    #[arg(long, value_enum, default_value = "auto")]
    outliers: OutliersArg,
    /// The G-buffer prefilter (spec §6) for every method.
    #[arg(long, value_enum, default_value = "auto")]
    prefilter: PrefilterArg,
    /// Methods to run, comma-separated [default: every method in this build].
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<MethodArg>,
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
    #[arg(long, value_name = "WxH", conflicts_with = "quality",
          value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
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

#[derive(clap::Args)]
struct RenderArgs {
    /// A built-in scene (see --list-scenes) or a TOML scene file.
    #[arg(long, required_unless_present = "list_scenes")]
    scene: Option<String>,
    /// List the built-in scenes and exit.
    #[arg(long)]
    list_scenes: bool,
    /// Average samples per pixel of the whole render (≥ 4 with --adaptive).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Adaptive sampling: 4 uniform spp, then passes where the sample map sends them.
    #[arg(long)]
    adaptive: bool,
    /// Reconstruction (none: the plain Monte Carlo mean).
    #[arg(long, value_enum, default_value = "wlr")]
    method: MethodArg,
    /// Feature prefilter before the method (spec §6).
    #[arg(long, value_enum, default_value = "auto")]
    prefilter: PrefilterArg,
    /// Energy-preserving firefly removal around the method (spec §4.4).
    #[arg(long, value_enum, default_value = "auto")]
    outliers: OutliersArg,
    /// With --adaptive: at most K times the pass's mean samples in one pixel
    /// per pass (the excess goes to the other pixels); 0 = no cap. Default:
    /// 4 for LP, no cap for the others.
    #[arg(long, value_name = "K",
          value_parser = |s: &str| s.parse::<f64>().ok().filter(|k| *k == 0.0 || (*k >= 1.0 && k.is_finite()))
              .ok_or_else(|| "0 (no cap) or a number >= 1".to_string()))]
    pass_cap: Option<f64>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "256x256",
          value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
    size: (usize, usize),
    /// Random-number seed: the same scene, seed and options give the same image.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output EXR (color.R/G/B and error.R/G/B).
    #[arg(short, long, required_unless_present = "list_scenes")]
    output: Option<PathBuf>,
    /// Also write a tone-mapped PNG.
    #[arg(long)]
    png: Option<PathBuf>,
    /// Also write the render statistics (the denoiser's input format).
    #[arg(long, value_name = "FILE")]
    save_stats: Option<PathBuf>,
    /// Compare with a K-spp uniform render of the same scene (cached on disk
    /// by scene content, size, K and seed) and print rMSE, relMSE, PSNR, SSIM.
    #[arg(long, value_name = "K")]
    reference: Option<u32>,
    /// Kernel arithmetic.
    #[arg(long, value_enum, default_value = "f32")]
    precision: PrecisionArg,
    /// Method option key=value (repeatable); see `mcdenoise denoise --help`.
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
enum BenchBackendArg {
    /// Vulkan compute kernels.
    Gpu,
    /// The scalar f64 reference implementation.
    Cpu,
    /// Both, one row each.
    Both,
}

/// `mcdenoise bench`: runs [`mcdenoise::bench`], prints Markdown, writes files.
fn bench(cli: &Cli, args: &BenchArgs) -> anyhow::Result<bool> {
    use mcdenoise::bench::{self as b, Note};
    let methods: Vec<Method> = args.methods.iter().map(|m| m.get()).collect();
    let backends = match args.backend {
        BenchBackendArg::Gpu => vec![Backend::Gpu],
        BenchBackendArg::Cpu => vec![Backend::Cpu],
        BenchBackendArg::Both => vec![Backend::Gpu, Backend::Cpu],
    };
    let stages = b::Stages {
        outliers: args.outliers.get(),
        prefilter: args.prefilter.get(),
        options: Options::parse(&args.opts)?,
    };
    for path in [&args.json, &args.markdown].into_iter().flatten() {
        if args.input.as_ref().is_some_and(|i| same_file(path, i)) {
            bail!("{}: refusing to overwrite an input file", path.display());
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
    if args.peak {
        let ctx = context(cli)?;
        let p = b::measure_peak(&ctx, args.runs)?;
        let markdown = format!(
            "Device: {}\n\nDevice limits ({} runs after a warm-up):\n\n{}",
            ctx.info().name,
            p.runs,
            p.to_markdown()
        );
        print!("{markdown}");
        if let Some(path) = &args.json {
            let text = serde_json::to_string_pretty(&p)? + "\n";
            b::write_text(path, &text)?;
        }
        if let Some(path) = &args.markdown {
            b::write_text(path, &markdown)?;
        }
        return Ok(true);
    }
    let (markdown, json, empty) = if let Some(dir) = &args.quality {
        let report = b::run_quality(
            ctx.as_ref(),
            &b::QualityConfig {
                dir: dir.clone(),
                methods,
                backends,
                filter: args.filter.clone(),
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
                input: match &args.input {
                    Some(p) => b::TimingInput::File(p.clone()),
                    None => b::TimingInput::Synthetic,
                },
                size: args.size,
                runs: args.runs,
                filter: args.filter.clone(),
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
    print!("{markdown}");
    if let Some(p) = &args.json {
        b::write_text(p, &json)?;
    }
    if let Some(p) = &args.markdown {
        b::write_text(p, &markdown)?;
    }
    if empty {
        bail!(
            "no benchmark case ran{}",
            args.filter
                .as_ref()
                .map_or(String::new(), |f| format!(" (--filter {f:?})"))
        );
    }
    Ok(true)
}

/// The library reports progress and repairs through `log`; the CLI prints
/// them on stderr (warnings always, the rest unless --quiet).
struct StderrLog {
    level: log::LevelFilter,
}

impl log::Log for StderrLog {
    fn enabled(&self, m: &log::Metadata) -> bool {
        m.level() <= self.level && m.target().starts_with("mcdenoise")
    }
    fn log(&self, r: &log::Record) {
        if self.enabled(r.metadata()) {
            match r.level() {
                log::Level::Error | log::Level::Warn => {
                    eprintln!(
                        "mcdenoise: {}: {}",
                        r.level().as_str().to_lowercase(),
                        r.args()
                    )
                }
                _ => eprintln!("mcdenoise: {}", r.args()),
            }
        }
    }
    fn flush(&self) {}
}

/// Where rendered references are cached: `MCDENOISE_CACHE`, else
/// `$XDG_CACHE_HOME/mcdenoise`, else `~/.cache/mcdenoise`, else `target/`.
fn cache_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("MCDENOISE_CACHE") {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME") {
        return PathBuf::from(d).join("mcdenoise");
    }
    if let Some(h) = std::env::var_os("HOME") {
        return PathBuf::from(h).join(".cache/mcdenoise");
    }
    PathBuf::from("target/mcdenoise-cache")
}

/// FNV-1a, 64 bits: a stable key for the reference cache (not a security
/// hash; the key also holds the size, K and seed in clear).
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h = 0xcbf29ce484222325u64;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100000001b3);
    }
    h
}

/// A stop flag set by Ctrl-C (installed once per process).
fn stop_flag() -> Arc<std::sync::atomic::AtomicBool> {
    static FLAG: std::sync::OnceLock<Arc<std::sync::atomic::AtomicBool>> =
        std::sync::OnceLock::new();
    FLAG.get_or_init(|| {
        let f = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let g = f.clone();
        if ctrlc::set_handler(move || {
            if g.swap(true, std::sync::atomic::Ordering::SeqCst) {
                std::process::exit(130); // a second Ctrl-C: stop now
            }
            eprintln!("\nmcdenoise: stopping after this pass (Ctrl-C again to quit now)");
        })
        .is_err()
        {
            log::warn!("cannot install a Ctrl-C handler");
        }
        f
    })
    .clone()
}

/// A bar over the passes of a render on a terminal (none when piped or --quiet).
fn pass_bar(cli: &Cli, what: &str) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    if cli.quiet || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] [{wide_bar}] {pos}/{len} {msg}",
        )
        .ok()?,
    );
    bar.set_message(what.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    Some(bar)
}

/// The K-spp uniform reference of `scene`, rendered once and cached.
fn reference_image(
    cli: &Cli,
    ctx: &Arc<GpuContext>,
    scene: &mcdenoise::render::Scene,
    size: (usize, usize),
    k: u32,
    seed: u64,
) -> anyhow::Result<(mcdenoise::RgbImage, PathBuf)> {
    // The reference uses its own random numbers, independent of the render's.
    let ref_seed = seed ^ 0x5eed_5eed_5eed_5eed;
    // The key covers the scene's content and the renderer's shaders, so a
    // changed renderer never reuses a stale reference.
    const RENDERER: [&str; 2] = [
        include_str!("../../spirv/render/render_trace.comp"),
        include_str!("../../spirv/render/render_scene.glsl"),
    ];
    let content = format!(
        "{scene:?}{:?}{}{}",
        scene.primitives()?,
        RENDERER[0],
        RENDERER[1]
    );
    let key = format!(
        "ref-{:016x}-{}x{}-k{k}-s{seed}.exr",
        fnv1a(content.as_bytes()),
        size.0,
        size.1
    );
    let path = cache_dir().join(key);
    if let Ok(img) = io::read_rgb(&path) {
        if (img.width, img.height) == size {
            if !cli.quiet {
                eprintln!("reference: {} (cached)", path.display());
            }
            return Ok((img, path));
        }
    }
    let renderer = mcdenoise::render::Renderer::new(ctx, scene, size.0, size.1, ref_seed)?;
    let stop = stop_flag();
    let step = 16u32;
    let passes = k.div_ceil(step);
    let bar = pass_bar(cli, &format!("reference, {k} spp"));
    if let Some(b) = &bar {
        b.set_length(passes as u64);
    }
    let t0 = std::time::Instant::now();
    for p in 0..passes {
        if stop.load(std::sync::atomic::Ordering::SeqCst) {
            return Err(mcdenoise::Error::Interrupted.into());
        }
        let spp = step.min(k - p * step);
        let mut batch = mcdenoise::Batch::new(ctx)?;
        renderer.record_pass(&mut batch, mcdenoise::render::Samples::Uniform(spp))?;
        batch.finish()?;
        if let Some(b) = &bar {
            b.set_position(p as u64 + 1);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let img = colour_of(&renderer.statistics()?);
    std::fs::create_dir_all(cache_dir()).ok();
    if let Err(e) = io::write_rgb(&path, &img) {
        log::warn!("could not cache the reference: {e}");
    } else if !cli.quiet {
        eprintln!(
            "reference: {k} spp in {:.1} s, cached as {}",
            t0.elapsed().as_secs_f64(),
            path.display()
        );
    }
    Ok((img, path))
}

/// `mcdenoise render`.
fn render(cli: &Cli, args: &RenderArgs) -> anyhow::Result<bool> {
    use mcdenoise::render::{adaptive, Renderer, Scene};
    if args.list_scenes {
        for name in Scene::builtin_names() {
            let about = Scene::builtin_source(name)
                .and_then(|s| s.lines().next())
                .map(|l| l.trim_start_matches('#').trim().to_string())
                .unwrap_or_default();
            println!("{name:<14} {about}");
        }
        return Ok(true);
    }
    let (Some(name), Some(output)) = (&args.scene, &args.output) else {
        bail!("--scene and -o are required");
    };
    let scene_file = Path::new(name);
    for path in [Some(output), args.png.as_ref(), args.save_stats.as_ref()]
        .into_iter()
        .flatten()
    {
        if scene_file.exists() && same_file(path, scene_file) {
            bail!("{}: refusing to overwrite an input file", path.display());
        }
    }
    let method = args.method.get();
    if args.adaptive && args.spp < mcdenoise::schedule::INITIAL_SPP {
        bail!(
            "--adaptive needs --spp of at least {} (the uniform first pass)",
            mcdenoise::schedule::INITIAL_SPP
        );
    }
    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    let scene = Scene::by_name_or_file(name)?;
    let ctx = context(cli)?;
    let (w, h) = args.size;
    let renderer = Renderer::new(&ctx, &scene, w, h, args.seed)?;
    let cfg = adaptive::LoopConfig {
        spp: args.spp,
        adaptive: args.adaptive,
        method,
        prefilter: args.prefilter.get(),
        outliers: args.outliers.get(),
        pass_cap: match args.pass_cap {
            None => adaptive::default_pass_cap(method),
            Some(k) => (k > 0.0).then_some(k),
        },
        precision: args.precision.get(),
        options: Options::parse(&args.opts)?,
    };
    let stop = stop_flag();
    let bar = pass_bar(
        cli,
        &format!(
            "{name}, {} spp{}, {}",
            args.spp,
            if args.adaptive { " adaptive" } else { "" },
            method.name()
        ),
    );
    let t0 = std::time::Instant::now();
    let result = adaptive::render(&ctx, &renderer, &cfg, &stop, |p| {
        if let Some(b) = &bar {
            b.set_length(p.total as u64);
            b.set_position(p.done as u64);
        }
    });
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let result = result?;
    let secs = t0.elapsed().as_secs_f64();
    let frame = &result.frame;
    io::write_output(
        output,
        &io::OutputImage {
            color: frame.color.clone(),
            error: (method != Method::None).then(|| frame.error.clone()),
            samples: None,
            debug: Vec::new(),
        },
    )?;
    if let Some(p) = &args.png {
        io::write_png_preview(p, &frame.color)?;
    }
    let stats = renderer.statistics()?;
    if let Some(p) = &args.save_stats {
        io::write_stats(p, &stats)?;
    }
    if !cli.quiet {
        let s = &result.split;
        let samples = args.spp as f64 * (w * h) as f64;
        eprintln!(
            "{name} {w}x{h}, {} spp{} ({} passes), {}: {secs:.1} s wall; GPU: render {:.0} ms ({:.0} ksamples/s), reconstruction {:.0} ms, sampling {:.0} ms",
            args.spp,
            if args.adaptive { " adaptive" } else { " uniform" },
            1 + result.schedule.as_ref().map_or(0, |s| s.budgets.len()),
            method.name(),
            s.render_ms,
            samples / s.render_ms.max(1e-9),
            s.reconstruction_ms,
            s.sampling_ms
        );
        eprintln!("-> {}", output.display());
    }
    if let Some(k) = args.reference {
        let (r, path) = reference_image(cli, &ctx, &scene, (w, h), k, args.seed)?;
        let mc = metrics::compare(&colour_of(&stats), &r)?;
        let m = metrics::compare(&frame.color, &r)?;
        println!("reference: {} ({k} spp)", path.display());
        println!(
            "against the reference:         Monte Carlo mean   {}",
            method.name()
        );
        println!("  rMSE            {:>18.5} {:>9.5}", mc.rmse, m.rmse);
        println!("  relMSE          {:>18.5} {:>9.5}", mc.relmse, m.relmse);
        println!("  PSNR (dB)       {:>18.2} {:>9.2}", mc.psnr, m.psnr);
        println!("  SSIM            {:>18.4} {:>9.4}", mc.ssim, m.ssim);
    }
    Ok(true)
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
    // One malloc arena for the whole process. lavapipe's worker threads
    // allocate while they run our dispatches, and glibc gives each thread an
    // arena of its own whose freed pages stay resident (malloc_trim after
    // the pipeline builds does not reach what they allocate later): 8-12 MB
    // of LP's peak at 1 MP, varying from run to run (docs/performance.md,
    // eighth part). No measurable change in speed.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt before any thread is started; M_ARENA_MAX only limits
    // how many arenas the allocator makes.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
    let cli = Cli::parse();
    // Progress lines of the CPU references only on a terminal, as the GPU bar.
    let level = if cli.quiet || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        log::LevelFilter::Warn
    } else {
        log::LevelFilter::Info
    };
    static LOGGER: std::sync::OnceLock<StderrLog> = std::sync::OnceLock::new();
    if log::set_logger(LOGGER.get_or_init(|| StderrLog { level })).is_ok() {
        log::set_max_level(level);
    }
    match run(cli) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(e) if matches!(e.downcast_ref(), Some(mcdenoise::Error::Interrupted)) => {
            eprintln!("mcdenoise: interrupted; no output written");
            ExitCode::from(130)
        }
        Err(e) => {
            eprintln!("mcdenoise: error: {}", error_text(&e));
            ExitCode::from(2)
        }
    }
}

/// The error and its causes, `: `-separated, each cause once: an error whose
/// message already quotes its source (mcdenoise's `Io`: "path: OS error")
/// would otherwise print the OS error twice.
fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}
