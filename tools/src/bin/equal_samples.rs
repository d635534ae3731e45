//! The equal-sample (and equal-time) comparison of adaptive and uniform
//! sampling on the built-in scenes, for every method, against references
//! whose own error is estimated.
//!
//! Per scene: `--reference-renders` references (2 unless told) of K spp
//! with independent seeds; the table uses their mean `r`, whose own error
//! against the converged image is estimated from the means `h₀`, `h₁` of
//! the even- and the odd-numbered renders as `rMSE(h₀, r) = mean (h₀ −
//! h₁)²/4 / (r² + 0.01)` (the expected `(r − t)²`, weighted by `r` as the
//! metric weighs an output's error) and printed next to the rows; the
//! ratios use the rMSE with that estimate subtracted. Per scene and spp N:
//! one uniform render of N spp (seed `--seed`) reconstructed by every
//! method (the Monte Carlo mean too), and per method the adaptive loop of
//! spec §9.3 with the same seed and total. With `--oidn`, OIDN 2.5
//! (`benches/oidn.sh`) on the uniform statistics and on each method's
//! adaptive statistics. With `--equal-time`, per method a uniform render
//! given the adaptive run's whole GPU time (renders, reconstructions and
//! sample maps; its spp from the uniform run's GPU time per sample and the
//! method's reconstruction time). Times and render rates come from the
//! GPU timestamps, which a shared machine disturbs less than wall time.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin equal_samples -- \
//!     [--scenes a,b] [--size 256x256] [--spp 16,64] [--methods wlr,lp,apr,aos] \
//!     [--reference 4096] [--reference-renders 2] [--seeds 3,4] [--oidn] [--equal-time] [--target | --target-only]
//!     [--map-method M] [--pass-cap K] [--passes N] [--coarse-maps] [--map-check on|off] [--opt key=value]
//!     [--json out.json] [--work DIR]
//! ```

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use clap::Parser;
use mcdenoise::render::adaptive::{self, LoopConfig};
use mcdenoise::render::{Renderer, Samples, Scene};
use mcdenoise::{
    colour_of, io, metrics, Batch, Config, ContextOptions, Denoiser, GpuContext, Method, Options,
    Pass, RgbImage, Source,
};
use mcdenoise_tools::{corrected, parse_method, references};
use serde::Serialize;

#[derive(Parser)]
struct Args {
    /// Scenes (built-in names or TOML files), comma-separated [default: every built-in scene].
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// Image size.
    #[arg(long, default_value = "256x256", value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
    size: (usize, usize),
    /// Average samples per pixel, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "16,64")]
    spp: Vec<u32>,
    /// Methods, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "wlr,lp,apr,aos", value_parser = parse_method)]
    methods: Vec<Method>,
    /// Samples per pixel of each reference render.
    #[arg(long, default_value_t = 4096)]
    reference: u32,
    /// Reference renders per scene, with independent seeds (even, at least
    /// 2): the reference is their mean, its own error estimated from the
    /// mean of the even- against the odd-numbered ones. Renders already
    /// made are read from the cache, so raising it adds only the new ones.
    #[arg(long, default_value_t = 2, value_parser = parse_renders)]
    reference_renders: u32,
    /// Seeds of the renders, comma-separated: every number is the mean over
    /// them (the comparison of two renders is noisy where rare paths
    /// dominate, fireflies and caustics).
    #[arg(long, value_delimiter = ',', default_value = "3")]
    seeds: Vec<u64>,
    /// Seed the references derive theirs from.
    #[arg(long, default_value_t = 3)]
    reference_seed: u64,
    /// Also OIDN on the uniform and on every adaptive run's statistics.
    #[arg(long)]
    oidn: bool,
    /// Also a uniform render per method given the adaptive run's GPU time.
    #[arg(long)]
    equal_time: bool,
    /// Adaptive passes after the uniform first one (default: the map
    /// method's schedule, §9.3).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=adaptive::MAX_PASSES as i64))]
    passes: Option<u32>,
    /// The method whose maps drive every adaptive run, with its schedule,
    /// sampling parameters and cap (default: each method's `map_method`,
    /// MAP-WLR).
    #[arg(long, value_parser = parse_method)]
    map_method: Option<Method>,
    /// Every adaptive run's maps from half-resolution reconstructions
    /// (MAP-COARSE).
    #[arg(long)]
    coarse_maps: bool,
    /// `on` or `off`: the final method's estimate decides each adaptive
    /// pass's mixture of the map and an even spread (MAP-CHECK; default:
    /// each method's `map_check`).
    #[arg(long, value_parser = parse_on_off)]
    map_check: Option<bool>,
    /// Per-pass cap of every adaptive run, as a multiple of the pass's mean
    /// (0: none; default: that of the method that makes the maps).
    #[arg(long, value_parser = adaptive::parse_pass_cap)]
    pass_cap: Option<f64>,
    /// Method option key=value for every reconstruction (repeatable).
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
    /// Also, per scene and method, an open-ended adaptive render
    /// (`--target-error`) whose target is the uniform run's true rMSE at the
    /// largest `--spp` (less the reference's error), bounded at 4× that spp:
    /// the estimate and the true rMSE where it stopped, its spp, and the
    /// uniform spp that reaches the same true rMSE (log-log between the two
    /// uniform points).
    #[arg(long)]
    target: bool,
    /// `--target` without the equal-sample table: each row renders only
    /// its uniform run, which the targets and the interpolation need.
    #[arg(long)]
    target_only: bool,
    /// Also write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Working folder for statistics and OIDN outputs.
    #[arg(long, default_value = "target/equal_samples")]
    work: PathBuf,
}

/// One method's results on one scene and spp.
#[derive(Clone, Debug, Default, Serialize)]
struct MethodRow {
    method: String,
    uniform: f64,
    uniform_estimate: f64,
    adaptive: f64,
    adaptive_estimate: f64,
    /// (adaptive − ref_err) / (uniform − ref_err).
    ratio: f64,
    /// Render rate of the uniform and the adaptive run, samples per second
    /// of GPU time.
    uniform_rate: f64,
    adaptive_rate: f64,
    /// GPU seconds of the adaptive run (renders, reconstructions, maps).
    adaptive_gpu: f64,
    /// The uniform run given that time: its spp and rMSE.
    equal_time_spp: Option<u32>,
    equal_time: Option<f64>,
    /// (adaptive − ref_err) / (equal_time − ref_err).
    equal_time_ratio: Option<f64>,
    /// OIDN on this method's adaptive statistics.
    oidn_adaptive: Option<f64>,
    /// The share of each adaptive pass that followed its map (MAP-CHECK).
    map_weights: Vec<f64>,
}

/// One scene and method rendered to a target error.
#[derive(Clone, Debug, Default, Serialize)]
struct TargetRow {
    scene: String,
    method: String,
    target: f64,
    /// The stop rule's estimate at the stop.
    estimate: f64,
    /// The true rMSE at the stop, less the reference's error.
    truth: f64,
    /// Average spp spent.
    spp: f64,
    /// Uniform spp that reach `truth` (interpolated).
    uniform_spp: f64,
}

/// One scene and spp.
#[derive(Clone, Debug, Default, Serialize)]
struct Row {
    scene: String,
    spp: u32,
    /// Estimated rMSE of the reference (the mean of the renders) itself.
    ref_err: f64,
    /// Reference renders of `--reference` spp averaged.
    ref_renders: u32,
    /// The uniform Monte Carlo mean.
    input: f64,
    oidn_uniform: Option<f64>,
    methods: Vec<MethodRow>,
}

fn loop_config(a: &Args, method: Method, spp: u32, options: &Options) -> LoopConfig {
    let base = LoopConfig::new(method, spp, true)
        .with_map_method(a.map_method)
        .with_pass_cap(a.pass_cap);
    LoopConfig {
        options: options.clone(),
        passes: a.passes,
        coarse_maps: a.coarse_maps,
        map_check: a.map_check.unwrap_or(base.map_check),
        ..base
    }
}

/// `on` or `off`.
fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("{s}: on or off")),
    }
}

/// `--reference-renders`: an even count of at least 2.
fn parse_renders(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(n) if n >= 2 && n % 2 == 0 => Ok(n),
        _ => Err(format!("{s}: an even number of at least 2")),
    }
}

/// A final reconstruction of `renderer`'s planes by `method`, and its GPU
/// seconds.
fn reconstruct(
    ctx: &Arc<GpuContext>,
    renderer: &Renderer,
    method: Method,
    options: &Options,
) -> anyhow::Result<(mcdenoise::Frame, f64)> {
    let mut c = Config::new(method);
    c.pass = Pass::Final;
    c.options = options.clone();
    c.low_spp = false;
    let d = Denoiser::new(ctx, Source::Accum(renderer.layout()), c)?;
    let mut b = Batch::new(ctx)?;
    d.record(&mut b, Some(renderer.accum()), None)?;
    let gpu_ms: f64 = b.finish()?.iter().map(|k| k.nanoseconds / 1e6).sum();
    Ok((d.read()?, gpu_ms / 1e3))
}

/// `(seconds of render GPU time per sample)` of a batch's timings.
fn render_ms(t: &[mcdenoise::KernelTiming]) -> f64 {
    t.iter()
        .filter(|k| k.kernel.starts_with("render_"))
        .map(|k| k.nanoseconds / 1e6)
        .sum()
}

/// Runs OIDN on `(input, output)` pairs and returns the outputs' rMSE
/// against `r`.
fn oidn(pairs: &[(PathBuf, PathBuf)], r: &RgbImage) -> anyhow::Result<Vec<f64>> {
    mcdenoise_tools::oidn(pairs)?;
    pairs
        .iter()
        .map(|(_, o)| Ok(metrics::rmse(&io::read_rgb(o)?, r)))
        .collect()
}

fn scene_rows(
    ctx: &Arc<GpuContext>,
    a: &Args,
    name: &str,
    methods: &[Method],
    options: &Options,
) -> anyhow::Result<(Vec<Row>, Vec<TargetRow>)> {
    let scene = Scene::by_name_or_file(name)?;
    let t = Instant::now();
    let (refs, r, ref_err) = references(
        ctx,
        &scene,
        a.size,
        a.reference,
        a.reference_renders,
        a.reference_seed,
    )?;
    let paths: Vec<String> = refs.iter().map(|r| r.path.display().to_string()).collect();
    eprintln!(
        "{name}: references {} ({:.0} s), estimated error of their mean {ref_err:.2e}",
        paths.join(", "),
        t.elapsed().as_secs_f64()
    );
    let stem = Path::new(name)
        .file_stem()
        .unwrap()
        .to_string_lossy()
        .to_string();
    let mut rows = Vec::new();
    for &n in &a.spp {
        let runs: Vec<Row> = a
            .seeds
            .iter()
            .map(|&seed| one_seed(ctx, a, &scene, &stem, n, seed, &r, methods, options))
            .collect::<anyhow::Result<_>>()?;
        let mut row = average(runs);
        row.ref_err = ref_err;
        row.ref_renders = a.reference_renders;
        for mr in row.methods.iter_mut().filter(|_| !a.target_only) {
            mr.ratio = corrected(mr.adaptive, ref_err) / corrected(mr.uniform, ref_err);
            mr.equal_time_ratio = mr
                .equal_time
                .map(|t| corrected(mr.adaptive, ref_err) / corrected(t, ref_err));
            eprintln!(
                "  {stem} spp{n} {}: uniform {:.5} adaptive {:.5} ratio {:.2} (rates {:.0}/{:.0} ks/s)",
                mr.method,
                mr.uniform,
                mr.adaptive,
                mr.ratio,
                mr.uniform_rate / 1e3,
                mr.adaptive_rate / 1e3
            );
        }
        rows.push(row);
    }
    let targets = if a.target {
        target_rows(ctx, a, &scene, &rows, &r, ref_err, methods, options)?
    } else {
        Vec::new()
    };
    Ok((rows, targets))
}

/// `--target`: per method, the open-ended render to the uniform run's
/// rMSE at the largest spp (see [`Args::target`]).
#[allow(clippy::too_many_arguments)] // the scene's pieces, as scene_rows holds them
fn target_rows(
    ctx: &Arc<GpuContext>,
    a: &Args,
    scene: &Scene,
    rows: &[Row],
    r: &RgbImage,
    ref_err: f64,
    methods: &[Method],
    options: &Options,
) -> anyhow::Result<Vec<TargetRow>> {
    let (lo, hi) = (
        rows.iter().min_by_key(|x| x.spp).context("rows")?,
        rows.iter().max_by_key(|x| x.spp).context("rows")?,
    );
    let (w, h) = a.size;
    let stop = AtomicBool::new(false);
    let mut out = Vec::new();
    for (k, &m) in methods.iter().enumerate() {
        let el = corrected(lo.methods[k].uniform, ref_err);
        let eh = corrected(hi.methods[k].uniform, ref_err);
        let renderer = Renderer::new(ctx, scene, w, h, a.seeds[0])?;
        let cfg = LoopConfig {
            stop: Some(adaptive::StopRules {
                target_error: Some(eh),
                time_limit: None,
                max_spp: 4 * hi.spp,
            }),
            ..loop_config(a, m, hi.spp, options)
        };
        let res = adaptive::render(ctx, &renderer, &cfg, &stop, |_| {})?;
        let truth = corrected(metrics::rmse(&res.frame.color, r), ref_err);
        // Uniform: e ∝ n^-α through (lo.spp, el) and (hi.spp, eh).
        let alpha = (el / eh).ln() / (hi.spp as f64 / lo.spp as f64).ln();
        let uniform_spp = hi.spp as f64 * (eh / truth).powf(1.0 / alpha);
        let t = TargetRow {
            scene: hi.scene.clone(),
            method: m.name().into(),
            target: eh,
            estimate: res.estimate.context("an open-ended render's estimate")?,
            truth,
            spp: res.samples as f64 / (w * h) as f64,
            uniform_spp,
        };
        eprintln!(
            "  {} {} to {:.5}: estimate {:.5}, true {:.5} at {:.1} spp (uniform needs {:.1})",
            t.scene, t.method, t.target, t.estimate, t.truth, t.spp, t.uniform_spp
        );
        out.push(t);
    }
    Ok(out)
}

/// The mean of per-seed rows (every number averaged; OIDN's where present).
fn average(runs: Vec<Row>) -> Row {
    let k = runs.len() as f64;
    let mean = |f: &dyn Fn(&Row) -> f64| runs.iter().map(f).sum::<f64>() / k;
    let mean_opt = |f: &dyn Fn(&Row) -> Option<f64>| {
        let v: Option<Vec<f64>> = runs.iter().map(f).collect();
        v.map(|v| v.iter().sum::<f64>() / k)
    };
    let mut row = runs[0].clone();
    row.input = mean(&|r| r.input);
    row.oidn_uniform = mean_opt(&|r| r.oidn_uniform);
    for (j, mr) in row.methods.iter_mut().enumerate() {
        let m = |f: &dyn Fn(&MethodRow) -> f64| mean(&|r: &Row| f(&r.methods[j]));
        let mo = |f: &dyn Fn(&MethodRow) -> Option<f64>| mean_opt(&|r: &Row| f(&r.methods[j]));
        mr.uniform = m(&|x| x.uniform);
        mr.uniform_estimate = m(&|x| x.uniform_estimate);
        mr.adaptive = m(&|x| x.adaptive);
        mr.adaptive_estimate = m(&|x| x.adaptive_estimate);
        mr.uniform_rate = m(&|x| x.uniform_rate);
        mr.adaptive_rate = m(&|x| x.adaptive_rate);
        mr.adaptive_gpu = m(&|x| x.adaptive_gpu);
        mr.equal_time = mo(&|x| x.equal_time);
        mr.oidn_adaptive = mo(&|x| x.oidn_adaptive);
    }
    row
}

/// One seed's uniform render (every method) and adaptive runs at `n` spp.
#[allow(clippy::too_many_arguments)] // the scene's pieces, as scene_rows holds them
fn one_seed(
    ctx: &Arc<GpuContext>,
    a: &Args,
    scene: &Scene,
    stem: &str,
    n: u32,
    seed: u64,
    r: &RgbImage,
    methods: &[Method],
    options: &Options,
) -> anyhow::Result<Row> {
    let (w, h) = a.size;
    let px = (w * h) as f64;
    let stop = AtomicBool::new(false);
    let mut row = Row {
        scene: stem.to_string(),
        spp: n,
        ..Default::default()
    };
    let tag = format!("{stem}-{n}-s{seed}");
    // Uniform: one render, every method.
    let uniform = Renderer::new(ctx, scene, w, h, seed)?;
    let mut b = Batch::new(ctx)?;
    uniform.record_clear(&mut b);
    uniform.record_pass(&mut b, Samples::Uniform(n))?;
    let uniform_secs = render_ms(&b.finish()?) / 1e3;
    let uniform_rate = n as f64 * px / uniform_secs;
    let stats = uniform.statistics()?;
    row.input = metrics::rmse(&colour_of(&stats), r);
    let stats_path = a.work.join(format!("{tag}-uniform.exr"));
    io::write_stats(&stats_path, &stats)?;
    let mut oidn_pairs = vec![(stats_path, a.work.join(format!("{tag}-uniform-oidn.exr")))];
    for &m in methods {
        let (frame, recon_secs) = reconstruct(ctx, &uniform, m, options)?;
        let mut mr = MethodRow {
            method: m.name().into(),
            uniform: metrics::rmse(&frame.color, r),
            uniform_estimate: metrics::estimated_rmse(&frame.color, &frame.error),
            uniform_rate,
            ..Default::default()
        };
        if a.target_only {
            row.methods.push(mr);
            continue;
        }
        // Adaptive, same seed and total.
        let ar = Renderer::new(ctx, scene, w, h, seed)?;
        let out = adaptive::render(ctx, &ar, &loop_config(a, m, n, options), &stop, |_| {})?;
        let sp = &out.split;
        mr.adaptive_gpu = (sp.render_ms + sp.reconstruction_ms + sp.sampling_ms) / 1e3;
        mr.adaptive = metrics::rmse(&out.frame.color, r);
        mr.adaptive_estimate = metrics::estimated_rmse(&out.frame.color, &out.frame.error);
        mr.adaptive_rate = out.samples as f64 / (out.split.render_ms / 1e3);
        mr.map_weights = out.map_weights.clone();
        if a.oidn {
            let p = a.work.join(format!("{tag}-{}-adaptive.exr", m.name()));
            io::write_stats(&p, &ar.statistics()?)?;
            oidn_pairs.push((
                p,
                a.work.join(format!("{tag}-{}-adaptive-oidn.exr", m.name())),
            ));
        }
        if a.equal_time {
            // The uniform render's GPU seconds per sample and this method's
            // reconstruction: what fits in the adaptive run's GPU time.
            let per_sample = uniform_secs / (n as f64 * px);
            let spp = ((mr.adaptive_gpu - recon_secs) / per_sample / px)
                .floor()
                .max(1.0) as u32;
            let eq = Renderer::new(ctx, scene, w, h, seed)?;
            let mut b = Batch::new(ctx)?;
            eq.record_clear(&mut b);
            eq.record_pass(&mut b, Samples::Uniform(spp))?;
            b.finish()?;
            let (frame, _) = reconstruct(ctx, &eq, m, options)?;
            mr.equal_time_spp = Some(spp);
            mr.equal_time = Some(metrics::rmse(&frame.color, r));
        }
        row.methods.push(mr);
    }
    if a.oidn && !a.target_only {
        let scores = oidn(&oidn_pairs, r)?;
        row.oidn_uniform = Some(scores[0]);
        for (mr, s) in row.methods.iter_mut().zip(&scores[1..]) {
            mr.oidn_adaptive = Some(*s);
        }
    }
    Ok(row)
}

fn fmt(v: Option<f64>) -> String {
    v.map_or("–".into(), |x| format!("{x:.5}"))
}

fn markdown(rows: &[Row], a: &Args, methods: &[Method]) -> String {
    let mut s = String::new();
    let mut head = "| scene | spp | ref. error | uniform MC |".to_string();
    if a.oidn {
        head += " OIDN |";
    }
    for m in methods {
        let n = m.name();
        head += &format!(" {n} uniform | {n} adaptive | ratio |");
        if a.equal_time {
            head += &format!(" {n} equal time (spp; adaptive ÷ it) |");
        }
        if a.oidn {
            head += &format!(" OIDN on {n} adaptive |");
        }
    }
    s += &head;
    s += "\n";
    let columns = head.matches('|').count() - 1;
    s += &"|---".repeat(columns);
    s += "|\n";
    for r in rows {
        let mut line = format!(
            "| {} | {} | {:.1e} | {:.5} |",
            r.scene, r.spp, r.ref_err, r.input
        );
        if a.oidn {
            line += &format!(" {} |", fmt(r.oidn_uniform));
        }
        for m in &r.methods {
            line += &format!(" {:.5} | {:.5} | {:.2} |", m.uniform, m.adaptive, m.ratio);
            if a.equal_time {
                line += &format!(
                    " {} ({} spp; {}) |",
                    fmt(m.equal_time),
                    m.equal_time_spp.unwrap_or(0),
                    m.equal_time_ratio.map_or("–".into(), |x| format!("{x:.2}"))
                );
            }
            if a.oidn {
                line += &format!(" {} |", fmt(m.oidn_adaptive));
            }
        }
        s += &line;
        s += "\n";
    }
    // Summary per method and spp: mean ratio, the worst, losses.
    s += "\n| method | spp | mean adaptive/uniform | worst | scenes above 1.0 | mean adaptive rate / uniform rate |";
    s += if a.equal_time {
        " mean adaptive/equal time | equal time above 1.0 |\n|---|---|---|---|---|---|---|---|\n"
    } else {
        "\n|---|---|---|---|---|---|\n"
    };
    for (k, m) in methods.iter().enumerate() {
        for &n in &a.spp {
            let rs: Vec<&MethodRow> = rows
                .iter()
                .filter(|r| r.spp == n)
                .map(|r| &r.methods[k])
                .collect();
            if rs.is_empty() {
                continue;
            }
            let ratios: Vec<f64> = rs.iter().map(|x| x.ratio).collect();
            let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
            let worst = ratios.iter().copied().fold(0.0, f64::max);
            let above = ratios.iter().filter(|&&x| x > 1.0).count();
            let rate = rs
                .iter()
                .map(|x| x.adaptive_rate / x.uniform_rate)
                .sum::<f64>()
                / rs.len() as f64;
            s += &format!(
                "| {} | {n} | {mean:.3} | {worst:.2} | {above} of {} | {rate:.2} |",
                m.name(),
                ratios.len()
            );
            let et: Vec<f64> = rs.iter().filter_map(|x| x.equal_time_ratio).collect();
            if a.equal_time && et.is_empty() {
                s += " – | – |";
            } else if a.equal_time {
                let above = et.iter().filter(|&&x| x > 1.0).count();
                s += &format!(
                    " {:.3} | {above} of {} |",
                    et.iter().sum::<f64>() / et.len() as f64,
                    et.len()
                );
            }
            s += "\n";
        }
    }
    s
}

fn main() -> anyhow::Result<()> {
    let mut a = Args::parse();
    a.target |= a.target_only;
    if a.passes.is_some() && a.target {
        anyhow::bail!(
            "--passes sets the fixed schedule; the --target runs size their passes themselves"
        );
    }
    let methods = a.methods.clone();
    let options = Options::parse(&a.opts)?;
    let scenes: Vec<String> = if a.scenes.is_empty() {
        Scene::builtin_still_names()
            .into_iter()
            .map(String::from)
            .collect()
    } else {
        a.scenes.clone()
    };
    std::fs::create_dir_all(&a.work)?;
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let (mut rows, mut targets) = (Vec::new(), Vec::new());
    for s in &scenes {
        let (r, t) = scene_rows(&ctx, &a, s, &methods, &options)?;
        rows.extend(r);
        targets.extend(t);
        if let Some(p) = &a.json {
            let json = serde_json::json!({ "rows": rows, "targets": targets, "passes": a.passes, "coarse_maps": a.coarse_maps, "map_check": a.map_check });
            std::fs::write(p, serde_json::to_string_pretty(&json)? + "\n")?;
        }
    }
    if !a.target_only {
        print!("{}", markdown(&rows, &a, &methods));
    }
    if !targets.is_empty() {
        println!("\n| scene | method | target | estimate at stop | true at stop | true / target | spp | uniform spp for the same true rMSE |\n|---|---|---|---|---|---|---|---|");
        for t in &targets {
            println!(
                "| {} | {} | {:.5} | {:.5} | {:.5} | {:.2} | {:.1} | {:.1} |",
                t.scene,
                t.method,
                t.target,
                t.estimate,
                t.truth,
                t.truth / t.target,
                t.spp,
                t.uniform_spp
            );
        }
    }
    Ok(())
}
