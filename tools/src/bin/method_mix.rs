//! Probe for `--method auto` (issue #41): every method's reconstruction and
//! error estimate on the same uniform inputs, and how well rules that
//! combine them per pixel by their estimated errors do against the best
//! single method and against an oracle that picks per 8×8 tile by the true
//! error.
//!
//! Cases: the public scenes (`--public DIR`: `DIR/<scene>/spp{4,16,64}.exr`
//! against `reference.exr`) and built-in scenes rendered uniformly (`--seed`, 3 by default)
//! against the mean of two K-spp references (cached). Prints one JSON line
//! per case with every method's and every rule's rMSE (raw: the references'
//! own error is not subtracted, it is the same for every row of a case).
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin method_mix -- \
//!     [--public ../shared/data/scenes] [--scenes a,b] [--size 128x128] [--spp 4,16,64] [--reference 1024] \
//!     [--methods wlr,lp] [--no-mix] [--opt key=value] [--no-input-blend] [--no-pyramid] [--prefilter-on]
//! ```

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use clap::Parser;
use mcdenoise::render::{reference, Renderer, Samples, Scene};
use mcdenoise::{
    colour_of, io, metrics, Batch, Config, ContextOptions, Denoiser, GpuContext, Method, Options,
    RgbImage, Source, StatsImage,
};
use mcdenoise_tools::parse_method;

#[derive(Parser)]
struct Args {
    #[arg(long)]
    public: Option<PathBuf>,
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    #[arg(long, default_value = "128x128", value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
    size: (usize, usize),
    #[arg(long, value_delimiter = ',', default_value = "4,16,64")]
    spp: Vec<u32>,
    #[arg(long, default_value_t = 1024)]
    reference: u32,
    #[arg(long, value_delimiter = ',', default_value = "wlr,lp,apr,aos", value_parser = parse_method)]
    methods: Vec<Method>,
    /// Only the methods' own rows (rMSE, image mean over the reference's),
    /// no blending rules.
    #[arg(long)]
    no_mix: bool,
    /// Folder for the uniform statistics (for OIDN).
    #[arg(long, default_value = "target/method_mix")]
    work: PathBuf,
    /// The uniform inputs' seed (the references' are fixed).
    #[arg(long, default_value_t = 3)]
    seed: u64,
    /// Method option key=value (repeatable), for every method.
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
    /// Run every method without the input blend (as `auto`'s members run).
    #[arg(long)]
    no_input_blend: bool,
    /// Run every method without the pyramid's low band.
    #[arg(long)]
    no_pyramid: bool,
    /// Run every method with the pyramid's low band (by default `auto`
    /// only: PYRAMID-AUTO); not with `none`, which has no low band.
    #[arg(long, conflicts_with = "no_pyramid")]
    pyramid_on: bool,
    /// Run every method on prefiltered features, AOS too (inside `auto`
    /// AOS reads them unprefiltered: AUTO-AOS).
    #[arg(long)]
    prefilter_on: bool,
}

struct Out {
    color: RgbImage,
    error: RgbImage,
    /// Per-pixel relative error estimate, summed over channels.
    rel: Vec<f64>,
    /// The factor a stop rule would scale this configuration's estimate by
    /// (ERROR-SCALE, PYRAMID-ERROR-SCALE): the blends' "cal" rules use it.
    scale: f64,
}

fn box_blur(w: usize, h: usize, v: &[f64], r: usize) -> Vec<f64> {
    if r == 0 {
        return v.to_vec();
    }
    let mut out = vec![0.0; v.len()];
    for y in 0..h {
        for x in 0..w {
            let (mut s, mut n) = (0.0, 0.0);
            for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    s += v[yy * w + xx];
                    n += 1.0;
                }
            }
            out[y * w + x] = s / n;
        }
    }
    out
}

/// Weights ∝ 1/ê^p of each method's box-smoothed relative error.
fn blend(outs: &[&Out], scale: &[f64], r: usize, p: f64) -> RgbImage {
    let c0 = &outs[0].color;
    let (w, h) = (c0.width, c0.height);
    let sm: Vec<Vec<f64>> = outs
        .iter()
        .zip(scale)
        .map(|(o, s)| box_blur(w, h, &o.rel.iter().map(|e| e * s).collect::<Vec<_>>(), r))
        .collect();
    let mut img = RgbImage::new(w, h);
    for i in 0..w * h {
        let ws: Vec<f64> = sm.iter().map(|e| 1.0 / (e[i].max(1e-12)).powf(p)).collect();
        let tot: f64 = ws.iter().sum();
        for c in 0..3 {
            let v: f64 = outs
                .iter()
                .zip(&ws)
                .map(|(o, wt)| o.color.planes[c][i] as f64 * wt)
                .sum();
            img.planes[c][i] = (v / tot) as f32;
        }
    }
    img
}

/// Per `t`×`t` tile, the method with the least `score` summed over the tile.
fn select(outs: &[&Out], score: &[Vec<f64>], t: usize) -> RgbImage {
    let c0 = &outs[0].color;
    let (w, h) = (c0.width, c0.height);
    let mut img = RgbImage::new(w, h);
    for ty in (0..h).step_by(t) {
        for tx in (0..w).step_by(t) {
            let mut best = (f64::INFINITY, 0);
            for (m, s) in score.iter().enumerate() {
                let mut sum = 0.0;
                for y in ty..(ty + t).min(h) {
                    for x in tx..(tx + t).min(w) {
                        sum += s[y * w + x];
                    }
                }
                if sum < best.0 {
                    best = (sum, m);
                }
            }
            for y in ty..(ty + t).min(h) {
                for x in tx..(tx + t).min(w) {
                    for c in 0..3 {
                        img.planes[c][y * w + x] = outs[best.1].color.planes[c][y * w + x];
                    }
                }
            }
        }
    }
    img
}

fn true_rel(x: &RgbImage, r: &RgbImage) -> Vec<f64> {
    (0..x.width * x.height)
        .map(|i| {
            (0..3)
                .map(|c| {
                    let (a, b) = (x.planes[c][i] as f64, r.planes[c][i] as f64);
                    (a - b) * (a - b) / (b * b + 0.01)
                })
                .sum()
        })
        .collect()
}

fn run(ctx: &Arc<GpuContext>, stats: &StatsImage, m: Method, runs: &Runs) -> anyhow::Result<Out> {
    let mut c = Config::new(m);
    c.error = true;
    c.options = runs.opts.clone();
    if runs.no_input_blend {
        c.input_blend = mcdenoise::InputBlend::Off;
    }
    if runs.no_pyramid {
        c.pyramid = mcdenoise::Pyramid::Off;
    }
    if runs.pyramid_on {
        c.pyramid = mcdenoise::Pyramid::On;
    }
    if runs.prefilter_on {
        c.prefilter = mcdenoise::Prefilter::On;
    }
    let scale = c.error_scale(stats.width, stats.height);
    let d = Denoiser::new(ctx, Source::of_image(stats), c)?;
    let f = d.denoise(stats, None)?;
    let n = f.color.width * f.color.height;
    let rel = (0..n)
        .map(|i| {
            (0..3)
                .map(|c| {
                    let v = f.color.planes[c][i] as f64;
                    (f.error.planes[c][i].max(0.0) as f64) / (v * v + 0.01)
                })
                .sum()
        })
        .collect();
    Ok(Out {
        error: f.error,
        color: f.color,
        rel,
        scale,
    })
}

fn subsets(n: usize) -> Vec<Vec<usize>> {
    (1..(1u32 << n))
        .filter(|b| b.count_ones() >= 2)
        .map(|b| (0..n).filter(|i| b & (1 << i) != 0).collect())
        .collect()
}

fn dump(path: PathBuf, planes: &[&[f32]]) -> anyhow::Result<()> {
    let mut bytes = Vec::new();
    for p in planes {
        bytes.extend_from_slice(bytemuck::cast_slice(p));
    }
    std::fs::write(path, bytes)?;
    Ok(())
}

/// What every case runs: the methods, their options, and whether to try
/// the blending rules.
struct Runs<'a> {
    methods: &'a [Method],
    opts: &'a Options,
    no_mix: bool,
    no_input_blend: bool,
    no_pyramid: bool,
    pyramid_on: bool,
    prefilter_on: bool,
}

fn case(
    work: &std::path::Path,
    ctx: &Arc<GpuContext>,
    name: &str,
    spp: u32,
    stats: &StatsImage,
    r: &RgbImage,
    runs: &Runs,
) -> anyhow::Result<()> {
    let Runs {
        methods, no_mix, ..
    } = *runs;
    let mut line = serde_json::Map::new();
    line.insert("case".into(), format!("{name}@{spp}").into());
    let input = colour_of(stats);
    line.insert("input".into(), metrics::rmse(&input, r).into());
    let t = std::time::Instant::now();
    let outs: Vec<Out> = methods
        .iter()
        .map(|&m| run(ctx, stats, m, runs))
        .collect::<anyhow::Result<_>>()?;
    let tag = format!("{name}@{spp}-{}x{}", r.width, r.height);
    dump(work.join(format!("{tag}-ref.bin")), &r.plane_slices())?;
    dump(work.join(format!("{tag}-in.bin")), &input.plane_slices())?;
    for (m, o) in methods.iter().zip(&outs) {
        let planes = [o.color.plane_slices(), o.error.plane_slices()].concat();
        dump(work.join(format!("{tag}-{}.bin", m.name())), &planes)?;
        line.insert(m.name().into(), metrics::rmse(&o.color, r).into());
        line.insert(format!("{}.mean", m.name()), {
            let mean = |x: &RgbImage| x.planes.iter().flatten().map(|&v| v as f64).sum::<f64>();
            (mean(&o.color) / mean(r)).into()
        });
    }
    if no_mix {
        line.insert("secs".into(), t.elapsed().as_secs_f64().into());
        println!("{}", serde_json::Value::Object(line));
        return Ok(());
    }
    let scales: Vec<f64> = outs.iter().map(|o| o.scale).collect();
    let ones = vec![1.0; methods.len()];
    for s in subsets(methods.len()) {
        let key: Vec<&str> = s.iter().map(|&i| methods[i].name()).collect();
        let key = key.join("+");
        let o: Vec<&Out> = s.iter().map(|&i| &outs[i]).collect();
        let sc: Vec<f64> = s.iter().map(|&i| scales[i]).collect();
        for (cal, scv) in [("raw", &ones[..s.len()]), ("cal", &sc[..])] {
            for r_ in [0usize, 1, 2, 4] {
                for p in [1.0, 2.0] {
                    let img = blend(&o, scv, r_, p);
                    line.insert(
                        format!("{key}|w{cal}r{r_}p{p}"),
                        metrics::rmse(&img, r).into(),
                    );
                }
            }
            let score: Vec<Vec<f64>> = o
                .iter()
                .zip(scv)
                .map(|(x, k)| x.rel.iter().map(|e| e * k).collect())
                .collect();
            for t in [4usize, 8, 16] {
                line.insert(
                    format!("{key}|sel{cal}{t}"),
                    metrics::rmse(&select(&o, &score, t), r).into(),
                );
            }
        }
        let truth: Vec<Vec<f64>> = o.iter().map(|x| true_rel(&x.color, r)).collect();
        line.insert(
            format!("{key}|oracle8"),
            metrics::rmse(&select(&o, &truth, 8), r).into(),
        );
    }
    line.insert("secs".into(), t.elapsed().as_secs_f64().into());
    println!("{}", serde_json::Value::Object(line));
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let methods = a.methods.clone();
    let opts = Options::parse(&a.opts)?;
    let runs = Runs {
        methods: &methods,
        opts: &opts,
        no_mix: a.no_mix,
        no_input_blend: a.no_input_blend,
        no_pyramid: a.no_pyramid,
        pyramid_on: a.pyramid_on,
        prefilter_on: a.prefilter_on,
    };
    std::fs::create_dir_all(&a.work)?;
    if let Some(dir) = &a.public {
        for s in ["dof_checker", "glossy_cornell", "indirect_room"] {
            let r = io::read_rgb(&dir.join(s).join("reference.exr"))?;
            for &n in &a.spp {
                let stats = io::read_stats(&dir.join(s).join(format!("spp{n}.exr")))?;
                case(&a.work, &ctx, s, n, &stats, &r, &runs)?;
            }
        }
    }
    let stop = AtomicBool::new(false);
    for name in &a.scenes {
        let scene = Scene::by_name_or_file(name)?;
        let refs: Vec<RgbImage> = [0u64, 2]
            .iter()
            .map(|x| {
                reference::reference(
                    &ctx,
                    &scene,
                    a.size,
                    a.reference,
                    reference::reference_seed(3) ^ x,
                    &stop,
                    |_, _| {},
                )
                .map(|r| r.image)
            })
            .collect::<mcdenoise::Result<_>>()?;
        let mut r = refs[0].clone();
        for c in 0..3 {
            for (v, b) in r.planes[c].iter_mut().zip(&refs[1].planes[c]) {
                *v = 0.5 * (*v + b);
            }
        }
        for &n in &a.spp {
            let ren = Renderer::new(&ctx, &scene, a.size.0, a.size.1, a.seed)?;
            let mut b = Batch::new(&ctx)?;
            ren.record_clear(&mut b);
            ren.record_pass(&mut b, Samples::Uniform(n))?;
            b.finish()?;
            let stats = ren.statistics()?;
            io::write_stats(&a.work.join(format!("{name}-{n}.exr")), &stats)?;
            case(&a.work, &ctx, name, n, &stats, &r, &runs)?;
        }
    }
    Ok(())
}
