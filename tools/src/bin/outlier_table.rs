//! The outlier stage's table (issues #11, #41): for each case, the input's
//! rMSE and each method's rMSE with the stage off and on, with the output's
//! image mean relative to the input's. GPU, f32, prefilter auto. Used by
//! `benches/outliers.sh`.
//!
//! Cases are `STATS=REF` pairs of files, or built-in scenes (`--scenes`)
//! rendered here: per scene, a reference that is the mean of two renders of
//! `--reference` spp with independent seeds (the pair `equal_samples` uses,
//! so the cache serves both), its own error estimated as `rMSE(r₀, r)`; per
//! spp and seed one uniform render. A scene's row is the mean over the
//! seeds, and the summary's ratios take the reference's error off as
//! `equal_samples` does. `--opt` applies to the runs with the stage on;
//! with `--base-opt`, the "off" columns are the stage on with those
//! options instead (one variant of the stage against another).
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin outlier_table -- [--methods wlr,lp] [--opt k=v] \
//!     [--scenes glossy,caustics --size 256x256 --spp 4,16,64 --seeds 3,4 --reference 1024] \
//!     [--base-opt k=v] [--json out.json] [a.exr=ref.exr ...]
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use clap::Parser;
use mcdenoise::metrics::rmse;
use mcdenoise::render::{Renderer, Samples, Scene};
use mcdenoise::{
    Batch, Config, ContextOptions, Denoiser, GpuContext, Method, Options, Outliers, RgbImage,
    Source, StatsImage,
};
use mcdenoise_tools::{corrected, parse_method, references};
use serde::Serialize;

#[derive(Parser)]
struct Args {
    /// Methods, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "wlr,lp,apr,aos", value_parser = parse_method)]
    methods: Vec<Method>,
    /// Method option key=value for the runs with the stage on (repeatable).
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
    /// Compare against the stage on with these options (repeatable) rather
    /// than off: the "off" columns become this baseline.
    #[arg(long = "base-opt", value_name = "KEY=VALUE")]
    base_opts: Vec<String>,
    /// Built-in scenes (or TOML files) to render, comma-separated.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// Image size of the rendered scenes.
    #[arg(long, default_value = "256x256", value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
    size: (usize, usize),
    /// Samples per pixel of the rendered scenes' inputs, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "4,16,64")]
    spp: Vec<u32>,
    /// Seeds of the inputs, comma-separated: a row is the mean over them.
    #[arg(long, value_delimiter = ',', default_value = "3")]
    seeds: Vec<u64>,
    /// Samples per pixel of each of the two reference renders.
    #[arg(long, default_value_t = 1024)]
    reference: u32,
    /// Also write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// `STATS=REF` pairs of EXR files.
    pairs: Vec<String>,
}

/// One method on one case: rMSE and image mean over the input's, off and on.
#[derive(Clone, Debug, Default, Serialize)]
struct MethodRow {
    method: String,
    off: f64,
    on: f64,
    mean_off: f64,
    mean_on: f64,
}

/// One case (a file pair, or a scene at one spp averaged over the seeds).
#[derive(Clone, Debug, Default, Serialize)]
struct Row {
    case: String,
    /// Estimated rMSE of the reference itself (0 when not known).
    ref_err: f64,
    input: f64,
    methods: Vec<MethodRow>,
}

fn mean(img: &RgbImage) -> f64 {
    let n = img.planes[0].len() * 3;
    img.planes.iter().flatten().map(|&v| v as f64).sum::<f64>() / n as f64
}

/// Every method off and on for one input.
fn run(
    ctx: &Arc<GpuContext>,
    a: &Args,
    options: &Options,
    base: Option<&Options>,
    img: &StatsImage,
    r: &RgbImage,
) -> anyhow::Result<(f64, Vec<MethodRow>)> {
    let input = mcdenoise::colour_of(img);
    let input_mean = mean(&input);
    let mut rows = Vec::new();
    for &m in &a.methods {
        let mut row = MethodRow {
            method: m.name().into(),
            ..Default::default()
        };
        for o in [Outliers::Off, Outliers::On] {
            let mut cfg = Config::new(m);
            cfg.outliers = o;
            if o == Outliers::On {
                cfg.options = options.clone();
            } else if let Some(b) = base {
                cfg.outliers = Outliers::On;
                cfg.options = b.clone();
            }
            let out = Denoiser::new(ctx, Source::of_image(img), cfg)?.denoise(img, None)?;
            let (e, ratio) = (rmse(&out.color, r), mean(&out.color) / input_mean);
            if o == Outliers::On {
                (row.on, row.mean_on) = (e, ratio);
            } else {
                (row.off, row.mean_off) = (e, ratio);
            }
        }
        rows.push(row);
    }
    Ok((rmse(&input, r), rows))
}

/// The rows of one rendered scene, one per spp.
fn scene_rows(
    ctx: &Arc<GpuContext>,
    a: &Args,
    options: &Options,
    base: Option<&Options>,
    name: &str,
) -> anyhow::Result<Vec<Row>> {
    let scene = Scene::by_name_or_file(name)?;
    let (_, r, ref_err) = references(ctx, &scene, a.size, a.reference, 2, 3)?;
    let stem = Path::new(name).file_stem().unwrap().to_string_lossy();
    let (w, h) = a.size;
    let mut rows = Vec::new();
    for &n in &a.spp {
        let mut row = Row {
            case: format!("{stem} {n}"),
            ref_err,
            ..Default::default()
        };
        let k = 1.0 / a.seeds.len() as f64;
        for &seed in &a.seeds {
            let renderer = Renderer::new(ctx, &scene, w, h, seed)?;
            let mut b = Batch::new(ctx)?;
            renderer.record_clear(&mut b);
            renderer.record_pass(&mut b, Samples::Uniform(n))?;
            b.finish()?;
            let (input, methods) = run(ctx, a, options, base, &renderer.statistics()?, &r)?;
            row.input += k * input;
            row.methods.resize(methods.len(), MethodRow::default());
            for (sum, m) in row.methods.iter_mut().zip(methods) {
                sum.method = m.method;
                sum.off += k * m.off;
                sum.on += k * m.on;
                sum.mean_off += k * m.mean_off;
                sum.mean_on += k * m.mean_on;
            }
        }
        eprintln!("{} done", row.case);
        rows.push(row);
    }
    Ok(rows)
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let options = Options::parse(&a.opts)?;
    let base = (!a.base_opts.is_empty())
        .then(|| Options::parse(&a.base_opts))
        .transpose()?;
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let mut rows = Vec::new();
    for pair in &a.pairs {
        let (s, r) = pair
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("{pair}: arguments are STATS=REF"))?;
        let img = mcdenoise::io::read_stats(Path::new(s))?;
        let reference = mcdenoise::io::read_rgb(Path::new(r))?;
        let p = Path::new(s);
        let scene = p.parent().and_then(|d| d.file_name()).unwrap_or_default();
        let (input, methods) = run(&ctx, &a, &options, base.as_ref(), &img, &reference)?;
        rows.push(Row {
            case: format!(
                "{}/{}",
                scene.to_string_lossy(),
                p.file_stem().unwrap().to_string_lossy()
            ),
            ref_err: 0.0,
            input,
            methods,
        });
    }
    for name in &a.scenes {
        rows.extend(scene_rows(&ctx, &a, &options, base.as_ref(), name)?);
    }

    let names: Vec<&str> = a.methods.iter().map(|m| m.name()).collect();
    let mut head = String::from("| case | reference's error | input |");
    for n in &names {
        head += &format!(" {n} off | {n} on |");
    }
    for n in &names {
        head += &format!(" mean ratio {n} off / on |");
    }
    println!("{head}");
    println!("|{}", "---|".repeat(3 + 3 * names.len()));
    for row in &rows {
        let mut line = format!("| {} | {:.5} | {:.5} |", row.case, row.ref_err, row.input);
        for m in &row.methods {
            line += &format!(" {:.5} | {:.5} |", m.off, m.on);
        }
        for m in &row.methods {
            line += &format!(" {:.4} / {:.4} |", m.mean_off, m.mean_on);
        }
        println!("{line}");
    }
    // Per method: mean rMSE off and on over every case, and the case where
    // the stage costs most (on over off, the reference's error taken off).
    println!();
    println!("| method | mean off | mean on | worst on/off | at |");
    println!("|---|---|---|---|---|");
    for (j, n) in names.iter().enumerate() {
        let k = 1.0 / rows.len().max(1) as f64;
        let off: f64 = rows.iter().map(|r| k * r.methods[j].off).sum();
        let on: f64 = rows.iter().map(|r| k * r.methods[j].on).sum();
        let worst = rows
            .iter()
            .map(|r| {
                let m = &r.methods[j];
                (
                    corrected(m.on, r.ref_err) / corrected(m.off, r.ref_err),
                    &r.case,
                )
            })
            .max_by(|x, y| x.0.total_cmp(&y.0));
        if let Some((w, case)) = worst {
            println!("| {n} | {off:.5} | {on:.5} | {w:.3} | {case} |");
        }
    }
    if let Some(p) = &a.json {
        std::fs::write(p, serde_json::to_string_pretty(&rows)?)?;
    }
    Ok(())
}
