//! `mcdenoise denoise`: one render-statistics file, or a sequence of them
//! (`--frames`), through the [`Denoiser`] facade (and, for APR's temporal
//! window, the [`SequenceDenoiser`]).

use std::collections::{HashSet, VecDeque};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use mcdenoise::{
    has_low_spp, io, metrics, Config, Denoiser, Frame, Method, Options, SequenceDenoiser, Source,
    StatsImage, Temporal, WarmUp,
};

use crate::args::{
    method_parser, BackendArg, BlendArg, OutliersArg, PassArg, PrecisionArg, PrefilterArg,
    PyramidArg, TemporalArg,
};
use crate::common::{
    check_error, check_outputs, context, print_metrics, print_report, progress_bar, read_colour,
};
use crate::Cli;

#[derive(clap::Args)]
pub struct Args {
    /// The statistics EXR (`/dev/stdin` reads them from a pipe)
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
    #[arg(long, conflicts_with = "temporal")]
    resume: bool,
    /// With --frames: a temporal stage, over the frames in frame order. A
    /// gap in the numbering, a frame that fails or one of another size or
    /// layers starts the history again (said on stderr). GPU only.
    #[arg(long, value_enum, default_value = "off", requires = "frames")]
    temporal: TemporalArg,
    /// Reconstruction method.
    #[arg(long, value_parser = method_parser(), default_value = "wlr")]
    method: Method,
    /// Where the kernels run: the Vulkan device, or their scalar f64 twins
    /// on the CPU (slow; for checking).
    #[arg(long, value_enum, default_value = "gpu")]
    backend: BackendArg,
    /// Kernel arithmetic on the GPU (f64 where the device supports it).
    #[arg(long, value_enum, default_value = "f32")]
    precision: PrecisionArg,
    /// The reconstruction's pass: the final image, or an intermediate one
    /// of an adaptive loop (smaller windows, as for a sample map).
    #[arg(long, value_enum, default_value = "final")]
    pass: PassArg,
    /// Feature prefilter before the method (spec §1, §6).
    #[arg(long, value_enum, default_value = "auto")]
    prefilter: PrefilterArg,
    /// Energy-preserving firefly removal around the method (spec §4.4).
    #[arg(long, value_enum, default_value = "auto")]
    outliers: OutliersArg,
    /// The pyramid's low band after the method (auto: with --method auto
    /// only): the method also reconstructs the statistics pooled 2x2, and
    /// the output takes its low-frequency part from that half-resolution
    /// reconstruction where the error estimates favour it (light that
    /// arrives only indirectly). 1.3-1.6x the GPU time. `--pyramid` alone
    /// is `--pyramid=on`
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
    #[arg(long, value_parser = crate::common::parse_max_error, requires = "reference")]
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
}

impl Args {
    /// The configuration of every call but what only the pixels tell
    /// (`low_spp`, false here).
    fn config(&self, cli: &Cli, options: &Options) -> Config {
        let mut config = Config::new(self.method);
        config.precision = self.precision.get();
        config.pass = self.pass.get();
        config.prefilter = self.prefilter.get();
        config.outliers = self.outliers.get();
        config.options = options.clone();
        config.debug = self.debug_layers;
        // The error estimate comes back only when it is written.
        config.error = self.error;
        config.progress = !cli.quiet;
        config.max_memory = self.max_memory.map(|mb| mb.saturating_mul(1 << 20));
        config.tile = self.tile.map(|t| t as usize);
        config.temporal = self.temporal.get();
        config.pyramid = self.pyramid.get();
        config.input_blend = self.input_blend.get();
        config
    }
}

pub fn run(cli: &Cli, a: &Args) -> anyhow::Result<bool> {
    let options = Options::parse(&a.opts)?;
    crate::common::warn_unused_method_options(&options, &[a.method]);
    if (a.max_memory.is_some() || a.tile.is_some()) && a.backend == BackendArg::Cpu {
        bail!("--max-memory and --tile apply to the GPU backend");
    }
    // The warm-up's configuration, before the pixels are read, is as if
    // every pixel had 2 samples or more (the usual render), so the spp < 2
    // stage's pipeline (resident memory for the process's life) is built
    // only by a call whose pixels need it.
    let mut warm_config = a.config(cli, &options);
    warm_config.low_spp = false;
    let temporal = a.temporal.get() != mcdenoise::Temporal::Off;
    let config_for = |img: &StatsImage| {
        let mut config = a.config(cli, &options);
        // A temporal denoiser lives through the sequence: it runs
        // sanitation's step for 1 <= spp < 2 (which changes nothing on
        // frames without such pixels) rather than being replaced.
        config.low_spp = temporal || has_low_spp(img);
        config
    };
    let Some(input) = &a.input else {
        let frames = a.frames.as_ref().expect("clap: input or --frames");
        // What would fail every frame is refused before the first.
        let t = a.temporal.get();
        if t == Temporal::Apr && a.method != Method::Apr {
            bail!(
                "--temporal apr is APR's temporal window: it runs with --method apr, not {}",
                a.method.name()
            );
        }
        if t == Temporal::Lp && a.tile.is_some() {
            bail!(
                "--temporal {} keeps one state for the whole image: it cannot run in --tile tiles",
                a.temporal.name()
            );
        }
        if matches!(t, Temporal::Apr | Temporal::LpSmooth) {
            return denoise_window(cli, a, frames, &config_for);
        }
        return denoise_frames(cli, a, frames, &warm_config, &config_for);
    };
    if a.resume {
        // clap's `requires` does not hold a flag back here.
        bail!("--resume needs --frames");
    }
    let mut inputs = vec![input.as_path()];
    inputs.extend(a.reference.as_deref());
    check_outputs(
        [Some(&a.output), a.png.as_ref(), a.sample_map.as_ref()]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path),
        &inputs,
    )?;
    // The pipelines build while the file is read (from its headers'
    // layers); a file whose headers do not read goes straight to
    // read_stats, whose error names the problem. Not for a pipe
    // (`/dev/stdin`): reading its headers would consume them.
    let regular = std::fs::metadata(input).is_ok_and(|m| m.is_file());
    let hint = match a.backend {
        BackendArg::Gpu if regular => io::read_stats_layers(input).ok(),
        _ => None,
    };
    let (mut ctx, mut warm) = (None, None);
    if let Some((width, height, layers)) = hint {
        let c = context(cli)?;
        let source = Source::Stats {
            width,
            height,
            layers,
        };
        warm = Some(Denoiser::warm_up(
            &c,
            &source,
            &warm_config,
            a.budget.is_some(),
        ));
        ctx = Some(c);
    }
    let img = crate::common::read_stats(input)?;
    let config = config_for(&img);
    let source = Source::of_image(&img);
    let mut denoiser = match a.backend {
        BackendArg::Gpu => {
            let ctx = match ctx {
                Some(c) => c,
                None => context(cli)?,
            };
            Denoiser::new(&ctx, source, config)?
        }
        BackendArg::Cpu => Denoiser::new_cpu(source, config)?,
    };
    drop(warm);
    let bar = progress_bar(cli, &mut denoiser);
    let t0 = std::time::Instant::now();
    let (width, height) = (img.width, img.height);
    // The host's copy of the statistics goes once they are uploaded.
    let result = denoiser.denoise_owned(img, a.budget);
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
            a.method.name(),
            a.backend,
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
        error: a.error.then_some(result.error),
        samples: result
            .samples
            .as_ref()
            .map(|s| s.iter().map(|&v| v as f32).collect()),
        debug: result.debug,
    };
    io::write_output(&a.output, &out)?;
    if let (Some(path), Some(s)) = (&a.sample_map, &result.samples) {
        io::write_samples(path, width, height, s)?;
        if !cli.quiet {
            let max = s.iter().max().copied().unwrap_or(0);
            let zero = s.iter().filter(|&&v| v == 0).count();
            eprintln!(
                "{}: {} samples (budget {}), max {max} per pixel, {zero} pixels get none",
                path.display(),
                s.iter().map(|&v| v as u64).sum::<u64>(),
                a.budget.unwrap_or(0)
            );
        }
    }
    if let Some(p) = &a.png {
        io::write_png_preview(p, &out.color)?;
    }
    if let Some(r) = &a.reference {
        let r = read_colour(r)?;
        let m = metrics::compare(&out.color, &r)?;
        print_metrics(&m);
        return Ok(check_error(m.rmse, a.max_error));
    }
    Ok(true)
}

/// The output pattern and the input frames of `denoise --frames`, refusing
/// an output pattern that names an input frame.
fn frame_patterns(
    a: &Args,
    pattern: &Path,
) -> anyhow::Result<(io::frames::FramePattern, Vec<io::frames::Frame>)> {
    let inp = io::frames::FramePattern::parse(pattern)?;
    let outp = io::frames::FramePattern::parse(&a.output)?;
    let frames = inp.list()?;
    // Every input frame, resolved, so that no output (of any frame number)
    // lands on an input, through a symbolic link either.
    let inputs: HashSet<PathBuf> = frames
        .iter()
        .filter_map(|f| f.path.canonicalize().ok())
        .collect();
    if frames
        .iter()
        .any(|f| inputs.contains(&outp.path(f.number).canonicalize().unwrap_or_default()))
    {
        bail!(
            "{}: refusing to overwrite input frames ({} names them)",
            a.output.display(),
            pattern.display()
        );
    }
    check_outputs([a.output.as_path()], &[])?;
    Ok((outp, frames))
}

/// Writes frame `number`'s reconstruction to the output pattern.
fn write_frame(
    a: &Args,
    outp: &io::frames::FramePattern,
    number: u64,
    result: Frame,
) -> anyhow::Result<()> {
    io::write_output(
        &outp.path(number),
        &io::OutputImage {
            color: result.color,
            error: a.error.then_some(result.error),
            samples: None,
            debug: result.debug,
        },
    )?;
    Ok(())
}

/// `denoise --frames --temporal apr|lp-smooth`: APR's temporal window
/// (spec §10.2) or the two-way filter (TEMPORAL-SMOOTH) over every run of consecutive frames of one size and set of layers. A
/// gap in the numbering or a frame of another shape ends the run (its
/// last frames come out) and starts another; a frame that fails to read or
/// to denoise is reported and skipped, and the frames waiting in the sequence
/// with it fail too; the exit status is 1 if any frame failed.
fn denoise_window(
    cli: &Cli,
    a: &Args,
    pattern: &Path,
    config_for: &dyn Fn(&StatsImage) -> Config,
) -> anyhow::Result<bool> {
    if a.backend == BackendArg::Cpu {
        bail!(
            "--temporal {} keeps its frames on the GPU: use --backend gpu",
            a.temporal.name()
        );
    }
    if a.max_memory.is_some() || a.tile.is_some() {
        bail!(
            "--temporal {} denoises whole frames: --max-memory and --tile do not apply",
            a.temporal.name()
        );
    }
    let (outp, frames) = frame_patterns(a, pattern)?;
    let ctx = context(cli)?;
    let t0 = std::time::Instant::now();
    let mut out = WindowOutput {
        a,
        quiet: cli.quiet,
        outp,
        waiting: VecDeque::new(),
        done: 0,
        failed: Vec::new(),
    };
    let mut run: Option<(Source, SequenceDenoiser)> = None;
    let mut last: Option<u64> = None;
    for frame in &frames {
        let img = match crate::common::read_stats(&frame.path) {
            Ok(img) => img,
            Err(e) => {
                out.fail(frame, &crate::common::error_text(e.as_ref()));
                continue;
            }
        };
        let source = Source::of_image(&img);
        let same_shape = matches!(&run, Some((s, _)) if *s == source);
        let next = same_shape && last.map(|l| l + 1) == Some(frame.number);
        if let (Some((_, seq)), false) = (&mut run, next) {
            eprintln!(
                "frame {}: {}: a new sequence starts",
                frame.number,
                if same_shape {
                    "not the next frame of the last one"
                } else {
                    "another size or layers"
                }
            );
            out.end(seq);
        }
        if !same_shape {
            // The previous run's buffers go before the next one's.
            drop(run.take());
            match SequenceDenoiser::new(&ctx, source.clone(), config_for(&img)) {
                Ok(seq) => run = Some((source, seq)),
                Err(e) => {
                    out.fail(frame, &crate::common::error_text(&e));
                    continue;
                }
            }
        }
        let seq = &mut run.as_mut().expect("just set").1;
        out.waiting.push_back(frame);
        match seq.push(&img) {
            Ok(done) => out.emit(done),
            Err(e) => {
                // The window is broken: its frames are lost with this one.
                let msg = crate::common::error_text(&e);
                out.waiting.pop_back();
                out.fail(frame, &msg);
                out.lose(&format!("lost with frame {}: {msg}", frame.number));
                run = None;
                last = None;
                continue;
            }
        }
        last = Some(frame.number);
    }
    if let Some((_, seq)) = &mut run {
        out.end(seq);
    }
    eprintln!(
        "{} frames in {:.1} s: {} denoised, {} failed",
        frames.len(),
        t0.elapsed().as_secs_f64(),
        out.done,
        out.failed.len()
    );
    for (n, msg) in &out.failed {
        eprintln!("  failed frame {n}: {msg}");
    }
    Ok(out.failed.is_empty())
}

/// Where `denoise_window`'s frames go: the output pattern, the frames in
/// the window (oldest first), the counts.
struct WindowOutput<'a> {
    a: &'a Args,
    quiet: bool,
    outp: io::frames::FramePattern,
    waiting: VecDeque<&'a io::frames::Frame>,
    done: usize,
    failed: Vec<(u64, String)>,
}

impl WindowOutput<'_> {
    fn fail(&mut self, f: &io::frames::Frame, msg: &str) {
        eprintln!("frame {}: {} failed: {msg}", f.number, f.path.display());
        self.failed.push((f.number, msg.to_string()));
    }

    /// The frames in the window fail with `msg`.
    fn lose(&mut self, msg: &str) {
        while let Some(f) = self.waiting.pop_front() {
            self.fail(f, msg);
        }
    }

    /// Writes the frames a call completed (they leave the window in order).
    fn emit(&mut self, out: Vec<(usize, Frame)>) {
        for (_, result) in out {
            let f = self.waiting.pop_front().expect("a frame out is a frame in");
            let path = self.outp.path(f.number);
            if !self.quiet {
                print_report(&result.report, &f.path);
            }
            match write_frame(self.a, &self.outp, f.number, result) {
                Ok(()) => {
                    self.done += 1;
                    if !self.quiet {
                        eprintln!(
                            "frame {}: {} -> {}",
                            f.number,
                            f.path.display(),
                            path.display()
                        );
                    }
                }
                Err(e) => self.fail(f, &crate::common::error_text(e.as_ref())),
            }
        }
    }

    /// Ends a run: its last frames come out, or fail with it.
    fn end(&mut self, seq: &mut SequenceDenoiser) {
        match seq.finish() {
            Ok(out) => self.emit(out),
            Err(e) => self.lose(&format!(
                "the sequence's end failed: {}",
                crate::common::error_text(&e)
            )),
        }
    }
}

/// `denoise --frames`: every existing frame of `pattern` into the output
/// pattern, on one device; a denoiser is reused while the frames keep their
/// size and layers. A frame that fails is reported and skipped; the summary
/// lists them, and the result is `false` (exit status 1) if any failed.
fn denoise_frames(
    cli: &Cli,
    a: &Args,
    pattern: &Path,
    warm_config: &Config,
    config_for: &dyn Fn(&StatsImage) -> Config,
) -> anyhow::Result<bool> {
    let (outp, frames) = frame_patterns(a, pattern)?;
    let ctx = match a.backend {
        BackendArg::Gpu => Some(context(cli)?),
        BackendArg::Cpu => None,
    };
    // The pipelines build while the first frame that needs them is read.
    let mut warm: Option<WarmUp> = None;
    let mut warmed = false;
    let mut cached: Option<(Source, bool, Denoiser)> = None;
    let (mut done, mut skipped) = (0usize, 0usize);
    let mut failed: Vec<(u64, String)> = Vec::new();
    let t0 = std::time::Instant::now();
    let temporal = warm_config.temporal != mcdenoise::Temporal::Off;
    // The last frame denoised: the temporal history continues from it.
    let mut history: Option<u64> = None;
    for frame in &frames {
        let out = outp.path(frame.number);
        if a.resume && out.exists() && io::read_rgb(&out).is_ok() {
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
            let img = crate::common::read_stats(&frame.path)?;
            let source = Source::of_image(&img);
            let low_spp = temporal || has_low_spp(&img);
            let reuse = matches!(&cached, Some((s, l, _)) if *s == source && *l == low_spp);
            if temporal && history.is_some() && !reuse {
                eprintln!(
                    "frame {}: another size or layers than frame {}: the temporal history starts again",
                    frame.number,
                    history.unwrap_or_default()
                );
            }
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
            if let (true, Some(h)) = (temporal && reuse, history) {
                if frame.number != h + 1 {
                    eprintln!(
                        "frame {}: frame {} is missing or failed: the temporal history starts again",
                        frame.number,
                        h + 1
                    );
                    denoiser.reset();
                }
            }
            let result = denoiser.denoise_owned(img, None)?;
            history = Some(frame.number);
            if !cli.quiet {
                print_report(&result.report, &frame.path);
            }
            write_frame(a, &outp, frame.number, result)
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
                let msg = crate::common::error_text(e.as_ref());
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
