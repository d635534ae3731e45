//! `mcdenoise render`: a scene through the built-in path tracer, uniformly
//! or through the adaptive loop (spec §9.3), reconstructed; with
//! `--reference K`, compared with a cached K-spp render.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use mcdenoise::io::frames::FramePattern;
use mcdenoise::render::{adaptive, reference, sequence, Renderer, Scene};
use mcdenoise::{
    colour_of, io, metrics, schedule, Config, Frame, GpuContext, Method, Options, RgbImage,
};

use crate::args::{
    method_parser, parse_size, BlendArg, FeatureSamplesArg, MapCheckArg, OutliersArg, PrecisionArg,
    PrefilterArg, PyramidArg, TemporalArg,
};
use crate::common::{check_outputs, context, pass_bar, stop_flag};
use crate::Cli;

pub const AFTER_HELP: &str = "Examples:\n  mcdenoise render --list-scenes\n  \
mcdenoise render --scene cornell --spp 16 --adaptive -o out.exr --png out.png --reference 1024\n  \
mcdenoise render --scene my_scene.toml --spp 64 --method lp --save-stats stats.exr -o out.exr\n  \
mcdenoise render --scene moving_box --frames 0..24 --size 128x128 --temporal lp -o out/f_####.exr --strip strip.png";

#[derive(clap::Args)]
pub struct Args {
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
    #[arg(long, value_parser = method_parser(), default_value = "wlr")]
    method: Method,
    /// Feature prefilter before the method (spec §6).
    #[arg(long, value_enum, default_value = "auto")]
    prefilter: PrefilterArg,
    /// Energy-preserving firefly removal around the method (spec §4.4).
    #[arg(long, value_enum, default_value = "auto")]
    outliers: OutliersArg,
    /// The pyramid's low band in the final reconstruction (auto: with --method auto
    /// only): the method also reconstructs the statistics pooled 2x2, and
    /// the output takes its low-frequency part from that half-resolution
    /// reconstruction where the error estimates favour it (light that
    /// arrives only indirectly). 1.3-1.6x the GPU time. `--pyramid` alone
    /// is `--pyramid=on`
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, require_equals = true, default_missing_value = "on")]
    pyramid: PyramidArg,
    /// The input blend in the final reconstruction (auto: after every
    /// method but auto): each pixel's output is the method's and the
    /// input's, weighed by the method's error estimate, read as at least
    /// the residual's excess over the input's variance, and the input's
    /// variance (--opt blend.radius, blend.k, blend.residual_radius,
    /// blend.z). `--input-blend` alone is `--input-blend=on`
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, require_equals = true, default_missing_value = "on")]
    input_blend: BlendArg,
    /// With --adaptive: the method whose reconstruction and error estimate
    /// make the adaptive passes' sample maps, with its schedule and sampling
    /// parameters and per-pass cap (none: the input's variance); the final
    /// image is still --method's. Default: wlr for lp, apr, aos and auto
    /// (decision records MAP-WLR, AUTO-MAPS), the method itself otherwise
    #[arg(long, value_parser = method_parser())]
    map_method: Option<Method>,
    /// With --adaptive: at most K times the pass's mean samples in one pixel
    /// per pass (the excess goes to the other pixels); 0 = no cap. Default:
    /// 4 when LP or APR makes the maps (--map-method), no cap otherwise.
    #[arg(long, value_name = "K", value_parser = adaptive::parse_pass_cap)]
    pass_cap: Option<f64>,
    /// With --adaptive: N adaptive passes after the uniform first one, each
    /// with a reconstruction for its sample map (default: the map method's,
    /// 5 for wlr, lp and apr, 3 for aos). Fewer passes leave more time to
    /// samples where a reconstruction costs many of them
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=adaptive::MAX_PASSES as i64))]
    passes: Option<u32>,
    /// With --adaptive: make each adaptive pass's sample map from a
    /// half-resolution reconstruction (the statistics pooled over 2x2
    /// blocks), about a quarter of the map method's work per pass
    /// (decision record MAP-COARSE). Images of at least 16x16 pixels
    #[arg(long)]
    coarse_maps: bool,
    /// With --adaptive, when another method makes the maps (--map-method):
    /// before each adaptive pass the final method's own error estimate
    /// decides how much of the pass follows the map and how much is spread
    /// evenly over the image, to the least error it predicts for itself
    /// (decision record MAP-CHECK). Costs one final reconstruction per
    /// pass. Not with --temporal lp or lp-smooth. `--map-check` alone is
    /// `--map-check=on`
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, require_equals = true, default_missing_value = "on")]
    map_check: MapCheckArg,
    /// Which samples the feature planes (albedo, normal, depth, position,
    /// visibility) average: the colour's own, or a camera path and a
    /// shadow ray of their own per sample, whose noise is not the colour's
    /// (decision record RENDER-FEATURE-SAMPLES). Independent features cost
    /// those two rays per sample and help where a pixel's coverage is
    /// random: edges under motion blur and lens blur, thin geometry
    #[arg(long, value_enum, default_value = "shared")]
    feature_samples: FeatureSamplesArg,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "256x256", value_parser = parse_size)]
    size: (usize, usize),
    /// Random-number seed: the same scene, seed and options give the same image.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output EXR (color.R/G/B, and error.R/G/B unless --method none); with --frames, a pattern
    /// such as out/frame_####.exr (as for --png and --save-stats).
    #[arg(short, long, required_unless_present = "list_scenes")]
    output: Option<PathBuf>,
    /// Render frames of an animated scene's sequence (its `[animation]`):
    /// A..B is frames A to B−1, A..=B includes B. One device and one set of
    /// pipelines for all; frame f uses its own seed (from --seed and f), so
    /// each frame renders the same alone or in any range. With --reference,
    /// per-frame metrics and the sequence's temporal error.
    #[arg(long, value_name = "A..B", value_parser = parse_frames, conflicts_with = "figure")]
    frames: Option<std::ops::Range<u32>>,
    /// With --frames: a temporal filter after the method, carrying each
    /// pixel's history from frame to frame (the first frame of the range
    /// starts it).
    #[arg(long, value_enum, default_value = "off", requires = "frames")]
    temporal: TemporalArg,
    /// With --frames: also write a PNG strip of up to six frames of the
    /// reconstruction side by side, evenly spaced over the range.
    #[arg(long, value_name = "PNG", requires = "frames")]
    strip: Option<PathBuf>,
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
    /// Render until the reconstruction's estimated rMSE is at most E: after
    /// pass 0 the method's own estimate (mean E_i/(f̂_i²+0.01) over pixels
    /// and channels, times a factor per method that corrects its measured
    /// bias), after the others how far the reconstruction moved since an
    /// earlier pass, weighed by the samples added (STOP-CHANGE). Passes
    /// continue, each sized from how the estimate fell so far, bounded by
    /// --max-spp. Uniform passes without --adaptive.
    #[arg(long, value_name = "E", conflicts_with = "spp",
          value_parser = |s: &str| s.parse::<f64>().ok().filter(|e| *e > 0.0 && e.is_finite())
              .ok_or_else(|| "a positive number".to_string()))]
    target_error: Option<f64>,
    /// Stop at the last pass that fits in this many seconds of wall time
    /// (with or without --target-error), bounded by --max-spp.
    #[arg(long, value_name = "S", conflicts_with = "spp",
          value_parser = |s: &str| s.parse::<f64>().ok().filter(|t| *t > 0.0 && t.is_finite())
              .map(std::time::Duration::from_secs_f64)
              .ok_or_else(|| "a positive number of seconds".to_string()))]
    time_limit: Option<std::time::Duration>,
    /// With --target-error or --time-limit: the most samples per pixel on
    /// average the render may take [default: 1024].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    max_spp: Option<u32>,
    /// Write a figure (PNG): the Monte Carlo input (with --adaptive, a
    /// uniform render of the same samples per pixel and seed), the samples
    /// per pixel, the reconstruction, its estimated error and, with
    /// --reference, the reference, side by side.
    #[arg(long, value_name = "PNG")]
    figure: Option<PathBuf>,
    /// Kernel arithmetic.
    #[arg(long, value_enum, default_value = "f32")]
    precision: PrecisionArg,
    /// Method option key=value (repeatable); see `mcdenoise denoise --help`.
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
}

impl Args {
    /// `--max-spp`, or its default.
    fn max_spp(&self) -> u32 {
        self.max_spp.unwrap_or(1024)
    }
}

/// `A..B` (A to B−1) or `A..=B` (A to B).
fn parse_frames(s: &str) -> Result<std::ops::Range<u32>, String> {
    let bad =
        || format!("{s:?}: expected A..B or A..=B, frame numbers with A < B (A <= B with ..=)");
    let (a, b, inclusive) = match s.split_once("..=") {
        Some((a, b)) => (a, b, true),
        None => {
            let (a, b) = s.split_once("..").ok_or_else(bad)?;
            (a, b, false)
        }
    };
    let (a, b): (u32, u32) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    let end = if inclusive {
        b.checked_add(1).ok_or_else(bad)?
    } else {
        b
    };
    if a >= end {
        return Err(bad());
    }
    Ok(a..end)
}

/// Frames of a `--strip`.
const STRIP_FRAMES: usize = 6;

/// Indices of at most `most` of `n` frames, evenly spaced, first and last
/// included.
fn strip_frames(n: usize, most: usize) -> Vec<usize> {
    if n <= most {
        return (0..n).collect();
    }
    (0..most).map(|k| k * (n - 1) / (most - 1)).collect()
}

fn list_scenes() {
    let names = Scene::builtin_names();
    let width = names.iter().map(|n| n.len()).max().unwrap_or(0);
    for name in names {
        let about = Scene::builtin_source(name)
            .and_then(|s| s.lines().next())
            .map(|l| l.trim_start_matches('#').trim().to_string())
            .unwrap_or_default();
        println!("{name:<width$}  {about}");
    }
}

/// The cached reference of `scene`, with a bar while it renders.
fn reference_image(
    cli: &Cli,
    ctx: &std::sync::Arc<GpuContext>,
    scene: &Scene,
    size: (usize, usize),
    k: u32,
    seed: u64,
) -> mcdenoise::Result<(RgbImage, PathBuf)> {
    let bar = pass_bar(cli, &format!("reference, {k} spp"));
    let t0 = std::time::Instant::now();
    let r = reference::reference(
        ctx,
        scene,
        size,
        k,
        reference::reference_seed(seed),
        &stop_flag(),
        |done, total| {
            if let Some(b) = &bar {
                b.set_length(total as u64);
                b.set_position(done as u64);
            }
        },
    )?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    if !cli.quiet {
        if r.cached {
            eprintln!("reference: {} (cached)", r.path.display());
        } else {
            eprintln!(
                "reference: {k} spp in {:.1} s, cached as {}",
                t0.elapsed().as_secs_f64(),
                r.path.display()
            );
        }
    }
    Ok((r.image, r.path))
}

/// The figure of `--figure`: input, samples per pixel, reconstruction,
/// estimated error and reference, side by side.
#[allow(clippy::too_many_arguments)] // the render's pieces, as render() holds them
fn write_figure(
    cli: &Cli,
    a: &Args,
    ctx: &std::sync::Arc<GpuContext>,
    scene: &Scene,
    stats: &mcdenoise::StatsImage,
    frame: &mcdenoise::Frame,
    reference: Option<&(RgbImage, PathBuf)>,
    path: &Path,
) -> anyhow::Result<()> {
    let (w, h) = a.size;
    let spp = &stats
        .get(mcdenoise::Layer::Spp)
        .expect("the renderer's statistics hold spp")[0];
    let mean_spp = spp.iter().map(|&s| s as f64).sum::<f64>() / (w * h) as f64;
    // With --adaptive the input panel is a uniform render of the same
    // samples per pixel and seed: what the samples would have been.
    let input = if a.adaptive {
        let uniform = Renderer::new(ctx, scene, w, h, a.seed)?;
        let mut batch = mcdenoise::Batch::new(ctx)?;
        uniform.record_clear(&mut batch);
        uniform.record_uniform(&mut batch, mean_spp.round().max(1.0) as u32)?;
        batch.finish()?;
        colour_of(&uniform.statistics()?)
    } else {
        colour_of(stats)
    };
    // The error as relative MSE, the scale of rMSE, up to its 99th
    // percentile; the counts up to their 99th percentile.
    let rel: Vec<f32> = (0..w * h)
        .map(|i| {
            (0..3)
                .map(|c| {
                    let f = frame.color.planes[c][i];
                    frame.error.planes[c][i].max(0.0) / (f * f + 0.01)
                })
                .sum::<f32>()
                / 3.0
        })
        .collect();
    let p99 = |v: &[f32]| {
        let mut s: Vec<f32> = v.iter().copied().filter(|x| x.is_finite()).collect();
        s.sort_by(f32::total_cmp);
        s.get(s.len() * 99 / 100).copied().unwrap_or(1.0).max(1e-12)
    };
    let mut panels = vec![
        io::Panel::Colour(&input),
        io::Panel::Heat(spp, p99(spp)),
        io::Panel::Colour(&frame.color),
    ];
    if frame.error.width == w {
        panels.push(io::Panel::Heat(&rel, p99(&rel)));
    }
    if let Some((r, _)) = reference {
        panels.push(io::Panel::Colour(r));
    }
    io::write_panels(path, w, h, &panels, 4)?;
    if !cli.quiet {
        eprintln!(
            "figure: {} (input at {mean_spp:.1} spp, samples per pixel, {}, estimated error{})",
            path.display(),
            a.method.name(),
            if reference.is_some() {
                ", reference"
            } else {
                ""
            }
        );
    }
    Ok(())
}

pub fn run(cli: &Cli, a: &Args) -> anyhow::Result<bool> {
    if a.list_scenes {
        list_scenes();
        return Ok(true);
    }
    let (Some(name), Some(output)) = (&a.scene, &a.output) else {
        bail!("--scene and -o are required");
    };
    let scene_file = Path::new(name);
    let scene_inputs: &[&Path] = if scene_file.exists() {
        &[scene_file]
    } else {
        &[]
    };
    check_outputs(
        [
            Some(output),
            a.png.as_ref(),
            a.save_stats.as_ref(),
            a.figure.as_ref(),
            a.strip.as_ref(),
        ]
        .into_iter()
        .flatten()
        .map(PathBuf::as_path),
        scene_inputs,
    )?;
    let method = a.method;
    if a.adaptive && a.spp < schedule::INITIAL_SPP {
        bail!(
            "--adaptive needs --spp of at least {} (the uniform first pass)",
            schedule::INITIAL_SPP
        );
    }
    if a.spp == 0 {
        bail!("--spp must be at least 1");
    }
    if !a.adaptive && a.map_method.is_some() {
        bail!("--map-method makes the adaptive passes' sample maps: it needs --adaptive");
    }
    if a.coarse_maps && !a.adaptive {
        bail!("--coarse-maps makes the adaptive passes' sample maps: it needs --adaptive");
    }
    if a.coarse_maps && a.temporal.filters() {
        bail!("--coarse-maps and --temporal {}: the adaptive passes' maps read the temporal filter's state at the full resolution (TEMPORAL-MAP)", a.temporal.name());
    }
    if a.map_check == MapCheckArg::On && !a.adaptive {
        bail!("--map-check checks the adaptive passes' sample maps: it needs --adaptive");
    }
    if a.map_check == MapCheckArg::On && a.temporal.filters() {
        bail!("--map-check and --temporal {}: the adaptive passes' maps weigh what the temporal filter knows, which a frame's own reconstruction does not (TEMPORAL-MAP)", a.temporal.name());
    }
    if a.max_spp.is_some() && a.target_error.is_none() && a.time_limit.is_none() {
        bail!("--max-spp bounds --target-error and --time-limit: it needs one of them (--spp sets a fixed budget)");
    }
    if a.pass_cap.is_some() && !a.adaptive {
        bail!("--pass-cap caps the adaptive passes' sample maps: it needs --adaptive");
    }
    if a.passes.is_some() && !a.adaptive {
        bail!("--passes sets the adaptive schedule: it needs --adaptive");
    }
    if a.passes.is_some() && (a.target_error.is_some() || a.time_limit.is_some()) {
        bail!("--passes sets the fixed schedule; --target-error and --time-limit size their passes themselves");
    }
    let scene = Scene::by_name_or_file(name)?;
    let ctx = context(cli)?;
    let (w, h) = a.size;
    let cfg = loop_config(a)?;
    if let Some(frames) = &a.frames {
        return render_sequence(cli, a, &ctx, &scene, frames.clone(), &cfg);
    }
    let renderer = Renderer::new(&ctx, &scene, w, h, a.seed)
        .with_context(|| format!("rendering {w}x{h} pixels"))?
        .with_feature_samples(cfg.feature_samples);
    // Rendered first, so an open-ended render can report its true error
    // after every pass.
    let reference = match a.reference {
        Some(k) => Some(reference_image(cli, &ctx, &scene, (w, h), k, a.seed)?),
        None => None,
    };
    let budget = match cfg.stop {
        Some(_) => format!("up to {} spp", a.max_spp()),
        None => format!("{} spp", a.spp),
    };
    let bar = pass_bar(
        cli,
        &format!(
            "{name}, {budget}{}, {}",
            if a.adaptive { " adaptive" } else { "" },
            method.name()
        ),
    );
    let t0 = std::time::Instant::now();
    let result = adaptive::render(&ctx, &renderer, &cfg, &stop_flag(), |p| {
        if let Some(b) = &bar {
            b.set_length(p.total as u64);
            b.set_position(p.done as u64);
        }
        if let (Some(e), false) = (p.estimate, cli.quiet) {
            let truth = match (&reference, p.frame) {
                (Some((r, _)), Some(f)) => metrics::compare(&f.color, r)
                    .map(|m| format!(", true {:.5}", m.rmse))
                    .unwrap_or_default(),
                _ => String::new(),
            };
            let line = format!(
                "pass {}: {:.2} spp, estimated rMSE {e:.5}{truth}",
                p.done, p.spp
            );
            match &bar {
                Some(b) => b.println(line),
                None => eprintln!("{line}"),
            }
        }
    });
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let result = result?;
    let secs = t0.elapsed().as_secs_f64();
    let frame = &result.frame;
    write_frame(output, a.png.as_deref(), method, frame)?;
    let stats = renderer.statistics_at(cfg.precision)?;
    if let Some(p) = &a.save_stats {
        io::write_stats(p, &stats)?;
    }
    if !cli.quiet {
        let s = &result.split;
        let samples = result.samples as f64;
        let work = renderer.traversal()?;
        let ms = s.render_ms.max(1e-9);
        eprintln!(
            "{name} {w}x{h}, {:.2} spp{}, {}: {secs:.1} s wall; GPU: render {:.0} ms ({:.0} ksamples/s, {:.2} Mrays/s, {:.1} rays and {:.0} BVH nodes per sample), reconstruction {:.0} ms, sampling {:.0} ms",
            samples / (w * h) as f64,
            if a.adaptive { " adaptive" } else { " uniform" },
            method.name(),
            s.render_ms,
            samples / ms,
            work.rays as f64 / ms / 1e3,
            work.rays as f64 / samples.max(1.0),
            work.nodes as f64 / samples.max(1.0),
            s.reconstruction_ms,
            s.sampling_ms
        );
        eprintln!("-> {}", output.display());
    }
    // A target the render stopped short of is said even with -q: the
    // image is not what was asked for.
    if let (Some(target), Some(est)) = (a.target_error, result.estimate) {
        if est > target {
            eprintln!(
                "mcdenoise: warning: the estimated rMSE {est:.5} is above --target-error {target}: the render stopped at {} ({:.1} spp)",
                if a.time_limit.is_some() { "--time-limit or --max-spp" } else { "--max-spp" },
                result.samples as f64 / (w * h) as f64
            );
        }
    }
    if let Some(path) = &a.figure {
        write_figure(
            cli,
            a,
            &ctx,
            &scene,
            &stats,
            frame,
            reference.as_ref(),
            path,
        )?;
    }
    if let (Some(k), Some((r, path))) = (a.reference, &reference) {
        let mc = metrics::compare(&colour_of(&stats), r)?;
        let m = metrics::compare(&frame.color, r)?;
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

/// The adaptive loop's configuration from the command line.
fn loop_config(a: &Args) -> anyhow::Result<adaptive::LoopConfig> {
    let method = a.method;
    // Before any pass renders: the final denoiser is made last.
    Config {
        pyramid: a.pyramid.get(),
        input_blend: a.input_blend.get(),
        ..Config::new(method)
    }
    .check_size(a.size.0, a.size.1)?;
    let base = adaptive::LoopConfig::new(method, a.spp, a.adaptive)
        .with_map_method(a.map_method)
        .with_pass_cap(a.pass_cap);
    if a.coarse_maps {
        Config {
            coarse_map: true,
            ..Config::new(base.mapper())
        }
        .check_size(a.size.0, a.size.1)?;
    }
    let options = Options::parse(&a.opts)?;
    let mut running = vec![method];
    if a.adaptive {
        running.push(base.mapper());
    }
    crate::common::warn_unused_method_options(&options, &running);
    Ok(adaptive::LoopConfig {
        prefilter: a.prefilter.get(),
        outliers: a.outliers.get(),
        precision: a.precision.get(),
        options,
        stop: (a.target_error.is_some() || a.time_limit.is_some()).then_some(adaptive::StopRules {
            target_error: a.target_error,
            time_limit: a.time_limit,
            max_spp: a.max_spp(),
        }),
        passes: a.passes,
        pyramid: a.pyramid.get(),
        input_blend: a.input_blend.get(),
        coarse_maps: a.coarse_maps,
        map_check: a.map_check.get(base.map_check),
        feature_samples: a.feature_samples.get(),
        ..base
    })
}

/// `render --frames`: frames `frames` of `scene`'s sequence
/// ([`sequence::render_frames`]) into the output patterns; with
/// `--reference K`, each frame's metrics against its own K-spp reference
/// and the sequence's temporal error ([`metrics::temporal_error`]).
fn render_sequence(
    cli: &Cli,
    a: &Args,
    ctx: &std::sync::Arc<GpuContext>,
    scene: &Scene,
    frames: std::ops::Range<u32>,
    cfg: &adaptive::LoopConfig,
) -> anyhow::Result<bool> {
    let pattern = |p: &Path| FramePattern::parse(p);
    let output = pattern(a.output.as_deref().expect("clap: -o"))?;
    let png = a.png.as_deref().map(pattern).transpose()?;
    let stats_out = a.save_stats.as_deref().map(pattern).transpose()?;
    let (w, h) = a.size;
    let method = a.method;
    let bar = pass_bar(cli, &format!("frames {}..{}", frames.start, frames.end));
    if let Some(b) = &bar {
        b.set_length(frames.len() as u64);
    }
    // Only what the metrics and the strip need is kept: the last frame's
    // images, each frame's two numbers, the strip's frames.
    let mut metrics = SequenceMetrics::default();
    let picks = strip_frames(frames.len(), STRIP_FRAMES);
    let mut strip: Vec<(u32, RgbImage)> = Vec::new();
    let mut done = 0usize;
    let t0 = std::time::Instant::now();
    let each = |f: sequence::SequenceFrame| -> mcdenoise::Result<()> {
        let n = f.number as u64;
        let path = output.path(n);
        let png = png.as_ref().map(|p| p.path(n));
        write_frame(&path, png.as_deref(), method, &f.result.frame)?;
        if let Some(p) = &stats_out {
            io::write_stats(&p.path(n), &f.stats)?;
        }
        let reference = match a.reference {
            Some(k) => Some(reference_image(cli, ctx, &f.scene, (w, h), k, f.seed)?.0),
            None => None,
        };
        let line = format!(
            "frame {}: {:.2} spp -> {}",
            f.number,
            f.result.samples as f64 / (w * h) as f64,
            path.display()
        );
        match (&bar, cli.quiet) {
            (Some(b), _) => {
                b.println(line);
                b.inc(1);
            }
            (None, false) => eprintln!("{line}"),
            (None, true) => {}
        }
        if a.strip.is_some() && picks.contains(&done) {
            strip.push((f.number, f.result.frame.color.clone()));
        }
        done += 1;
        if let Some(r) = reference {
            metrics.add(f.number, colour_of(&f.stats), f.result.frame.color, r)?;
        }
        Ok(())
    };
    let temporal = a.temporal.get();
    let stop = stop_flag();
    sequence::render_frames(
        ctx,
        scene,
        frames,
        (w, h),
        a.seed,
        cfg,
        temporal,
        &stop,
        each,
    )?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    if let (Some(path), false) = (&a.strip, strip.is_empty()) {
        let panels: Vec<io::Panel> = strip.iter().map(|(_, c)| io::Panel::Colour(c)).collect();
        io::write_panels(path, w, h, &panels, 4)?;
        if !cli.quiet {
            let numbers: Vec<String> = strip.iter().map(|(n, _)| n.to_string()).collect();
            eprintln!("strip: {} (frames {})", path.display(), numbers.join(", "));
        }
    }
    if !cli.quiet {
        eprintln!(
            "{done} frames of {w}x{h} in {:.1} s wall",
            t0.elapsed().as_secs_f64()
        );
    }
    if let Some(k) = a.reference {
        println!("against per-frame {k}-spp references:");
        println!("frame   rMSE Monte Carlo mean   rMSE {}", method.name());
        for (f, mi, mo) in &metrics.frames {
            println!("{f:>5} {mi:>22.5} {mo:>10.5}");
        }
        let count = metrics.frames.len() as f64;
        let mean = |k: usize| metrics.frames.iter().map(|r| [r.1, r.2][k]).sum::<f64>() / count;
        let temporal = |k: usize| match metrics.pairs {
            0 => "-".to_string(),
            n => format!("{:.6}", metrics.temporal[k] / n as f64),
        };
        println!("mean  {:>22.5} {:>10.5}", mean(0), mean(1));
        println!("temporal error {:>15} {:>10}", temporal(0), temporal(1));
    }
    Ok(true)
}

/// A sequence's metrics against its per-frame references, taken frame by
/// frame in order, holding only the last frame's images: each frame's
/// rMSE of the input and the output, and the temporal error
/// ([`metrics::temporal_error`], a mean over the pairs of consecutive
/// frames, each of the same size).
#[derive(Default)]
struct SequenceMetrics {
    /// (frame, input's rMSE, output's rMSE)
    frames: Vec<(u32, f64, f64)>,
    /// The input's and the output's temporal error summed over the pairs.
    temporal: [f64; 2],
    pairs: usize,
    /// The last frame's input, output and reference.
    last: Option<[RgbImage; 3]>,
}

impl SequenceMetrics {
    fn add(
        &mut self,
        number: u32,
        input: RgbImage,
        output: RgbImage,
        reference: RgbImage,
    ) -> mcdenoise::Result<()> {
        self.frames.push((
            number,
            metrics::rmse(&input, &reference),
            metrics::rmse(&output, &reference),
        ));
        if let Some([i0, o0, r0]) = &self.last {
            for (k, (x0, x1)) in [(i0, &input), (o0, &output)].into_iter().enumerate() {
                let t = metrics::temporal_error(&[x0, x1], &[r0, &reference])?;
                self.temporal[k] += t.expect("two frames");
            }
            self.pairs += 1;
        }
        self.last = Some([input, output, reference]);
        Ok(())
    }
}

/// Writes a reconstruction: the EXR (colour, and the error unless the
/// method is `none`) and, if asked, its tone-mapped PNG.
fn write_frame(
    output: &Path,
    png: Option<&Path>,
    method: Method,
    frame: &Frame,
) -> mcdenoise::Result<()> {
    io::write_output(
        output,
        &io::OutputImage {
            color: frame.color.clone(),
            error: (method != Method::None).then(|| frame.error.clone()),
            samples: None,
            debug: Vec::new(),
        },
    )?;
    if let Some(p) = png {
        io::write_png_preview(p, &frame.color)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frame by frame, the metrics equal those of the whole sequence at once.
    #[test]
    fn sequence_metrics_taken_frame_by_frame_equal_the_whole_sequences() {
        let image = |seed: u32| {
            let mut v = seed.wrapping_mul(2654435761);
            let planes = std::array::from_fn(|_| {
                (0..12)
                    .map(|_| {
                        v = v.wrapping_mul(1664525).wrapping_add(1013904223);
                        (v >> 8) as f32 / (1 << 24) as f32
                    })
                    .collect()
            });
            RgbImage::from_planes(4, 3, planes)
        };
        let frames: Vec<[RgbImage; 3]> = (0..4)
            .map(|t| [image(3 * t), image(3 * t + 1), image(3 * t + 2)])
            .collect();
        let mut m = SequenceMetrics::default();
        for (t, [i, o, r]) in frames.iter().cloned().enumerate() {
            m.add(t as u32, i, o, r).unwrap();
        }
        let all = |k: usize| frames.iter().map(|f| &f[k]).collect::<Vec<_>>();
        for k in 0..2 {
            let whole = metrics::temporal_error(&all(k), &all(2)).unwrap().unwrap();
            let streamed = m.temporal[k] / m.pairs as f64;
            assert!(
                (whole - streamed).abs() <= 1e-12 * whole,
                "{whole} {streamed}"
            );
        }
        assert_eq!(m.frames.len(), 4);
        assert_eq!(m.frames[2].2, metrics::rmse(&frames[2][1], &frames[2][2]));
    }
}
