//! `mcdenoise render`: a scene through the built-in path tracer, uniformly
//! or through the adaptive loop (spec §9.3), reconstructed; with
//! `--reference K`, compared with a cached K-spp render.

use std::path::{Path, PathBuf};

use anyhow::bail;
use mcdenoise::render::{adaptive, reference, Renderer, Scene};
use mcdenoise::{colour_of, io, metrics, schedule, GpuContext, Method, Options, RgbImage};

use crate::args::{method_parser, parse_size, OutliersArg, PrecisionArg, PrefilterArg};
use crate::common::{context, pass_bar, refuse_overwrite, stop_flag};
use crate::Cli;

pub const AFTER_HELP: &str = "Examples:\n  mcdenoise render --list-scenes\n  \
mcdenoise render --scene cornell --spp 16 --adaptive -o out.exr --png out.png --reference 1024\n  \
mcdenoise render --scene my_scene.toml --spp 64 --method lp --save-stats stats.exr -o out.exr";

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
    /// With --adaptive: at most K times the pass's mean samples in one pixel
    /// per pass (the excess goes to the other pixels); 0 = no cap. Default:
    /// the method's (4 for LP, no cap for the others).
    #[arg(long, value_name = "K",
          value_parser = |s: &str| s.parse::<f64>().ok().filter(|k| *k == 0.0 || (*k >= 1.0 && k.is_finite()))
              .ok_or_else(|| "0 (no cap) or a number >= 1".to_string()))]
    pass_cap: Option<f64>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "256x256", value_parser = parse_size)]
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

fn list_scenes() {
    for name in Scene::builtin_names() {
        let about = Scene::builtin_source(name)
            .and_then(|s| s.lines().next())
            .map(|l| l.trim_start_matches('#').trim().to_string())
            .unwrap_or_default();
        println!("{name:<14} {about}");
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
) -> anyhow::Result<(RgbImage, PathBuf)> {
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

pub fn run(cli: &Cli, a: &Args) -> anyhow::Result<bool> {
    if a.list_scenes {
        list_scenes();
        return Ok(true);
    }
    let (Some(name), Some(output)) = (&a.scene, &a.output) else {
        bail!("--scene and -o are required");
    };
    let scene_file = Path::new(name);
    if scene_file.exists() {
        refuse_overwrite(
            [Some(output), a.png.as_ref(), a.save_stats.as_ref()]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path),
            &[scene_file],
        )?;
    }
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
    let scene = Scene::by_name_or_file(name)?;
    let ctx = context(cli)?;
    let (w, h) = a.size;
    let renderer = Renderer::new(&ctx, &scene, w, h, a.seed)?;
    let cfg = adaptive::LoopConfig {
        spp: a.spp,
        adaptive: a.adaptive,
        method,
        prefilter: a.prefilter.get(),
        outliers: a.outliers.get(),
        pass_cap: match a.pass_cap {
            None => adaptive::default_pass_cap(method),
            Some(k) => (k > 0.0).then_some(k),
        },
        precision: a.precision.get(),
        options: Options::parse(&a.opts)?,
    };
    let bar = pass_bar(
        cli,
        &format!(
            "{name}, {} spp{}, {}",
            a.spp,
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
    if let Some(p) = &a.png {
        io::write_png_preview(p, &frame.color)?;
    }
    let stats = renderer.statistics()?;
    if let Some(p) = &a.save_stats {
        io::write_stats(p, &stats)?;
    }
    if !cli.quiet {
        let s = &result.split;
        let samples = a.spp as f64 * (w * h) as f64;
        eprintln!(
            "{name} {w}x{h}, {} spp{} ({} passes), {}: {secs:.1} s wall; GPU: render {:.0} ms ({:.0} ksamples/s), reconstruction {:.0} ms, sampling {:.0} ms",
            a.spp,
            if a.adaptive { " adaptive" } else { " uniform" },
            1 + result.schedule.as_ref().map_or(0, |s| s.budgets.len()),
            method.name(),
            s.render_ms,
            samples / s.render_ms.max(1e-9),
            s.reconstruction_ms,
            s.sampling_ms
        );
        eprintln!("-> {}", output.display());
    }
    if let Some(k) = a.reference {
        let (r, path) = reference_image(cli, &ctx, &scene, (w, h), k, a.seed)?;
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
