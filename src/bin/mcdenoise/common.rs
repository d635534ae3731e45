//! What the subcommands share: the device, progress display, Ctrl-C, output
//! checks and metric printing.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use anyhow::Context as _;

use mcdenoise::{
    io, metrics, ContextOptions, Denoiser, GpuContext, Layer, Method, Options, PrepareReport,
    RgbImage, StatsImage, Validation,
};

use crate::Cli;

/// The device `--device` (or the default) names, with validation on request.
pub fn context(cli: &Cli) -> anyhow::Result<Arc<GpuContext>> {
    let ctx = GpuContext::new(&ContextOptions {
        device: cli.device.clone(),
        validation: if cli.validation {
            Validation::Required
        } else {
            Validation::Off
        },
        no_64bit: cli.no_64bit,
    })?;
    if !cli.no_pipeline_cache {
        let path = cli.pipeline_cache.clone().unwrap_or_else(|| {
            let device: String = ctx
                .info()
                .name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
                .collect();
            mcdenoise::render::reference::cache_dir().join(format!("pipelines-{device}.bin"))
        });
        // A cache that cannot be read costs only the compile time.
        if let Err(e) = ctx.use_pipeline_cache(&path) {
            log::warn!("pipeline cache not used: {e}");
        }
    }
    Ok(Arc::new(ctx))
}

/// Whether progress may be drawn: stderr is a terminal and not --quiet
/// (logs and pipes stay clean).
fn interactive(cli: &Cli) -> bool {
    !cli.quiet && std::io::stderr().is_terminal()
}

fn bar(template: &str, len: u64) -> Option<indicatif::ProgressBar> {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(indicatif::ProgressStyle::with_template(template).ok()?);
    bar.enable_steady_tick(Duration::from_millis(200));
    Some(bar)
}

/// A progress bar on stderr for a GPU denoiser (none when not interactive).
pub fn progress_bar(cli: &Cli, denoiser: &mut Denoiser) -> Option<indicatif::ProgressBar> {
    if !interactive(cli) {
        return None;
    }
    let bar = bar(
        "{spinner} [{elapsed_precise}] [{wide_bar}] {percent:>3}% {msg}",
        1000,
    )?;
    let b = bar.clone();
    denoiser.set_progress(Some(Arc::new(move |fraction: f64, kernel: &str| {
        b.set_position((fraction * 1000.0) as u64);
        b.set_message(kernel.to_string());
    })));
    Some(bar)
}

/// A bar over the passes of a render (none when not interactive).
pub fn pass_bar(cli: &Cli, what: &str) -> Option<indicatif::ProgressBar> {
    if !interactive(cli) {
        return None;
    }
    let bar = bar(
        "{spinner} [{elapsed_precise}] [{wide_bar}] {pos}/{len} {msg}",
        1,
    )?;
    bar.set_message(what.to_string());
    Some(bar)
}

/// A stop flag set by Ctrl-C (installed once per process); a second Ctrl-C
/// exits at once.
pub fn stop_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let f = Arc::new(AtomicBool::new(false));
        let g = f.clone();
        if ctrlc::set_handler(move || {
            if g.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
            eprintln!(
                "\nmcdenoise: stopping after this pass, without the output in progress (Ctrl-C again to quit now)"
            );
        })
        .is_err()
        {
            log::warn!("cannot install a Ctrl-C handler");
        }
        f
    })
    .clone()
}

/// Whether two paths name the same existing file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// Where `p` would be written, to tell two outputs apart: the file when it
/// exists, else its folder's canonical path joined with its name (the path
/// as given when the folder does not exist either).
fn output_key(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    let dir = p
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    match (dir.canonicalize(), p.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => p.to_path_buf(),
    }
}

/// Before any work: refuses any of `outputs` that is one of `inputs` or a
/// folder, and two outputs that name the same file (or the same frame
/// pattern), one of which would silently replace the other; then creates
/// the folders the outputs go in, so that a missing one fails now, not
/// after the render.
pub fn check_outputs<'a>(
    outputs: impl IntoIterator<Item = &'a Path>,
    inputs: &[&Path],
) -> anyhow::Result<()> {
    let outputs: Vec<&Path> = outputs.into_iter().collect();
    for (k, out) in outputs.iter().enumerate() {
        if out.is_dir() {
            anyhow::bail!("{}: a folder; name the output file", out.display());
        }
        if inputs.iter().any(|i| same_file(out, i)) {
            anyhow::bail!("{}: refusing to overwrite an input file", out.display());
        }
        let key = output_key(out);
        if outputs[..k].iter().any(|o| output_key(o) == key) {
            anyhow::bail!(
                "{}: named for two outputs; give each output its own file",
                out.display()
            );
        }
    }
    for out in outputs {
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: creating its folder", out.display()))?;
        }
    }
    Ok(())
}

/// Warns about each `--opt` key of a method (`wlr.`, `lp.`, `apr.`,
/// `aos.`, `auto.`) that none of `running` runs ([`Method::runs`]):
/// such an option has no effect on this command.
pub fn warn_unused_method_options(options: &Options, running: &[Method]) {
    let all: Vec<Method> = running.iter().flat_map(|m| m.runs(options)).collect();
    for key in options.keys() {
        let prefix = key.split('.').next().unwrap_or(key);
        if let Some(m) = Method::from_name(prefix).filter(|m| !all.contains(m)) {
            eprintln!(
                "mcdenoise: warning: --opt {key}: method {} does not run in this command, so the option has no effect",
                m.name()
            );
        }
    }
}

/// clap's parser of `--max-error`: a finite number ≥ 0 (NaN would never
/// fail a check).
pub fn parse_max_error(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        Ok(_) => Err("must be a finite number of at least 0".into()),
        Err(e) => Err(e.to_string()),
    }
}

/// `Ok(false)` (exit status 1) when `rmse` exceeds `max`.
pub fn check_error(rmse: f64, max: Option<f64>) -> bool {
    match max {
        Some(max) if rmse.is_nan() || rmse > max => {
            eprintln!("rMSE {rmse:.5} exceeds --max-error {max}");
            false
        }
        _ => true,
    }
}

pub fn print_metrics(m: &metrics::Metrics) {
    println!("rMSE    {:.5}", m.rmse);
    println!("relMSE  {:.5}", m.relmse);
    println!("PSNR    {:.2} dB", m.psnr);
    println!("SSIM    {:.4}", m.ssim);
}

/// A statistics file to denoise: [`io::read_stats`], refusing one in
/// which no pixel has a sample (every `spp` below 1), whose output could
/// only be black.
pub fn read_stats(path: &Path) -> anyhow::Result<StatsImage> {
    let img = io::read_stats(path)?;
    let counted = img.get(Layer::Spp).is_some_and(|p| !p[0].is_empty());
    if counted && !mcdenoise::has_samples(&img) {
        anyhow::bail!(
            "{}: no pixel has a sample (spp < 1 everywhere): nothing to denoise",
            path.display()
        );
    }
    // Sanitation repairs them and counts them over all layers; say where.
    for (layer, planes) in img.layers() {
        let (mut count, mut first) = (0, None::<usize>);
        for (c, plane) in planes.iter().enumerate() {
            let mut bad = plane.iter().enumerate().filter(|(_, v)| !v.is_finite());
            let Some((i, _)) = bad.next() else { continue };
            let n = 1 + bad.count();
            if n == plane.len() {
                anyhow::bail!(
                    "{}: layer {}, channel {}: every value is non-finite (NaN or infinite)",
                    path.display(),
                    layer.name(),
                    layer.channels()[c]
                );
            }
            count += n;
            first = Some(first.map_or(i, |f| f.min(i)));
        }
        if let Some(i) = first {
            eprintln!(
                "{}: layer {}: {count} non-finite values, the first at pixel ({}, {}); sanitation repairs them",
                path.display(),
                layer.name(),
                i % img.width,
                i / img.width
            );
        }
    }
    Ok(img)
}

/// The colour of `path`: a render-statistics file or a plain RGB image.
pub fn read_colour(path: &Path) -> anyhow::Result<RgbImage> {
    Ok(io::read_rgb(path)?)
}

/// What sanitation repaired, on stderr.
pub fn print_report(r: &PrepareReport, input: &Path) {
    for line in r.messages(input) {
        eprintln!("{line}");
    }
}

/// The error and its causes, `: `-separated, each cause once: an error whose
/// message already quotes its source (mcdenoise's `Io`: "path: OS error")
/// would otherwise print the OS error twice.
pub fn error_text(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = String::new();
    let mut cause = Some(e);
    while let Some(c) = cause {
        let part = c.to_string();
        if !text.contains(&part) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&part);
        }
        cause = c.source();
    }
    text
}
