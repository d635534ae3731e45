//! Where the LP temporal filter (spec §10.1) gains and loses, per class of
//! pixel: on an animated scene, each method's every frame alone and with
//! the filter (one denoiser carrying its state, as `sequence_table
//! --temporal`), each frame against the first of `sequence_table`'s two
//! references (the same seeds, so its cache serves both). A pixel of a
//! frame is `bright` where the reference exceeds 1 in some frame and
//! channel (lights and their rims), `changing` where the reference moves
//! by more than 0.02 (rMSE's relative square) since the last frame, and
//! only then (not in the frame before, nor in the next), `ramp` where it
//! does so in consecutive frames, `recent` where it did within the four
//! frames before, `static` otherwise. Of each pixel's ramp frames that
//! follow another ramp frame, printed first: how often the two changes
//! of the channels' mean agree in sign, and the later change's mean
//! relative square (over `r_t² + 0.01`, `r` the channels' mean) before and
//! after predicting it as the earlier one (a line in time). Printed per
//! class: its share of the pixels and its part of the mean rMSE and of the
//! temporal error (`metrics::temporal_error`, uncorrected), alone and
//! filtered, so a column's classes sum to the image's figure. Written to `--out`: per method the sum over frames of
//! the filter's change of the per-pixel rMSE (`<method>_rmse_delta.png`:
//! red where the filter raises it, green where it lowers it, full scale at
//! `--scale`) and the filtered output's per-pixel temporal error
//! (`<method>_temporal.png`, heat map, full scale at the 99th percentile),
//! and per pixel its number of ramp frames (`ramps.png`, full scale at a
//! quarter of the frames).
//! With `--two-way`, a third column: the two-way filter
//! (`--temporal lp-smooth`, TEMPORAL-SMOOTH); with `--oidn`, OIDN on every
//! frame (`benches/oidn.sh`) in the "alone" column.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin temporal_probe -- \
//!     [--scene moving_box] [--methods wlr,auto] [--size 128x128] [--spp 16] \
//!     [--frames 24] [--reference 512] [--seed 1] [--out target/temporal_probe] [--scale 0.05] \
//!     [--two-way] [--oidn] [--opt key=value] [--prefilter auto|gbf|none]
//! ```

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use clap::Parser;
use mcdenoise::render::Scene;
use mcdenoise::{io, metrics, ContextOptions, GpuContext, Method, RgbImage};
use mcdenoise_tools::{parse_method, parse_prefilter, SequenceWithReferences, TwoWay};

#[derive(Parser)]
struct Args {
    /// An animated scene (built-in name or file).
    #[arg(long, default_value = "moving_box")]
    scene: String,
    /// Methods, each with its default configuration.
    #[arg(long, value_delimiter = ',', default_value = "wlr,auto", value_parser = parse_method)]
    methods: Vec<Method>,
    #[arg(long, default_value = "128x128", value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
    size: (usize, usize),
    /// Samples per pixel of every frame (uniform).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Frames from 0 (at most the scene's).
    #[arg(long, default_value_t = 24)]
    frames: u32,
    /// Samples per pixel of each frame's reference.
    #[arg(long, default_value_t = 512)]
    reference: u32,
    /// Seed of the sequence and of its references (`sequence_table --seed`).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Folder of the maps.
    #[arg(long, default_value = "target/temporal_probe")]
    out: PathBuf,
    /// The summed rMSE change that saturates the delta map.
    #[arg(long, default_value_t = 0.05)]
    scale: f32,
    /// Method option key=value for every reconstruction (repeatable).
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
    /// Also the two-way filter (`Temporal::LpSmooth`).
    #[arg(long)]
    two_way: bool,
    /// Also OIDN on every frame (`benches/oidn.sh`), in the "alone" column.
    #[arg(long)]
    oidn: bool,
    /// The G-buffer prefilter (spec §6) of every reconstruction: `auto`
    /// (each method's default), `gbf` or `none`, as `render --prefilter`.
    #[arg(long, default_value = "auto", value_parser = parse_prefilter)]
    prefilter: mcdenoise::Prefilter,
    /// The frames' features from samples of their own
    /// (`render --feature-samples independent`, RENDER-FEATURE-SAMPLES).
    #[arg(long)]
    independent_features: bool,
}

const CLASSES: [&str; 5] = ["static", "bright", "changing", "ramp", "recent"];
/// The index of `ramp` in [`CLASSES`].
const RAMP: usize = 3;

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let options = mcdenoise::Options::parse(&a.opts)?;
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let scene = Scene::by_name_or_file(&a.scene)?;
    let SequenceWithReferences {
        stats,
        refs,
        second,
    } = SequenceWithReferences::render(
        &ctx,
        &scene,
        a.frames,
        a.size,
        (a.spp, a.reference),
        (a.seed, a.seed),
        mcdenoise_tools::feature_samples(a.independent_features),
    )?;
    anyhow::ensure!(refs.len() >= 2, "{}: two frames or more", a.scene);
    let (w, h) = a.size;
    let n = w * h;
    let class = classes(&refs);
    let r = Ramps::new(&refs, &class);
    std::fs::create_dir_all(&a.out)?;
    let ramps: Vec<f32> = (0..n)
        .map(|i| class.iter().filter(|c| c[i] == RAMP).count() as f32)
        .collect();
    io::write_heatmap_png(
        &a.out.join("ramps.png"),
        w,
        h,
        &ramps,
        refs.len() as f32 / 4.0,
    )?;
    println!(
        "<!-- ramps: {} pairs of consecutive ramp frames, the changes agree in sign in {:.1} %; \
         their mean relative square {:.4}, less the last change {:.4} -->",
        r.pairs,
        100.0 * r.agree as f64 / r.pairs.max(1) as f64,
        r.change / r.pairs.max(1) as f64,
        r.after_line / r.pairs.max(1) as f64
    );
    println!(
        "<!-- {}, {w}x{h}, {} spp, {} frames, {}-spp references of seed {}; \
         the references' own: half of a second seed's -->",
        a.scene,
        a.spp,
        refs.len(),
        a.reference,
        a.seed
    );
    let columns: &[&str] = if a.two_way {
        &["alone", "+ 10.1", "two-way"]
    } else {
        &["alone", "+ 10.1"]
    };
    let head = |what: &str| {
        std::iter::once(format!("{what}: references' own"))
            .chain(columns.iter().map(|c| c.to_string()))
            .collect::<Vec<_>>()
            .join(" | ")
    };
    println!(
        "| method | class | share | {} | {} |",
        head("rMSE"),
        head("temporal error")
    );
    println!("|---|---|---:|{}", "---:|".repeat(2 + 2 * columns.len()));
    let own = Tally::new(&second, &refs, &class)?;
    let print = |name: &str, tallies: &[Tally]| {
        for k in 0..=CLASSES.len() {
            let class = CLASSES.get(k).copied().unwrap_or("all");
            let share = if k < CLASSES.len() { own.share[k] } else { 1.0 };
            let cells = |own: f64, of: &dyn Fn(&Tally) -> f64| {
                std::iter::once(format!("{:.6}", own / 2.0))
                    .chain((0..columns.len()).map(|c| {
                        tallies
                            .get(c)
                            .map_or("–".to_string(), |t| format!("{:.6}", of(t)))
                    }))
                    .collect::<Vec<_>>()
                    .join(" | ")
            };
            println!(
                "| {name} | {class} | {share:.3} | {} | {} |",
                cells(own.rmse[k], &|t| t.rmse[k]),
                cells(own.temporal[k], &|t| t.temporal[k])
            );
        }
    };
    for &m in &a.methods {
        let t = TwoWay::run(&ctx, m, &options, a.prefilter, &stats, a.two_way)?;
        let mut outputs = vec![t.alone, t.forward];
        if a.two_way {
            outputs.push(t.combined);
        }
        let tallies = outputs
            .iter()
            .map(|o| Tally::new(o, &refs, &class))
            .collect::<anyhow::Result<Vec<_>>>()?;
        print(m.name(), &tallies);
        let (alone, with) = (&tallies[0], &tallies[1]);
        let delta: Vec<f32> = with
            .rmse_map
            .iter()
            .zip(&alone.rmse_map)
            .map(|(a, b)| a - b)
            .collect();
        let scaled = |sign: f32| {
            delta
                .iter()
                .map(|v| (sign * v / a.scale).clamp(0.0, 1.0))
                .collect()
        };
        let path = a.out.join(format!("{}_rmse_delta.png", m.name()));
        let img = RgbImage::from_planes(w, h, [scaled(1.0), scaled(-1.0), vec![0.0; n]]);
        io::write_png_preview(&path, &img).with_context(|| path.display().to_string())?;
        let path = a.out.join(format!("{}_temporal.png", m.name()));
        // Full scale at the 99th percentile: the lamp's rim would leave the
        // rest black.
        let mut sorted = with.temporal_map.clone();
        sorted.sort_by(f32::total_cmp);
        let top = sorted[(sorted.len() - 1) * 99 / 100];
        io::write_heatmap_png(&path, w, h, &with.temporal_map, top)?;
    }
    if a.oidn {
        let images = mcdenoise_tools::oidn_frames(&stats, &a.out.join("oidn"))?;
        print("OIDN", &[Tally::new(&images, &refs, &class)?]);
    }
    Ok(())
}

/// A sequence's rMSE and temporal error against its references, per class
/// (as parts of the image's mean, so the classes sum to it; the last entry
/// is the whole image) and per pixel (summed over frames).
struct Tally {
    /// Each class's share of the pixel-frames.
    share: Vec<f64>,
    rmse: Vec<f64>,
    temporal: Vec<f64>,
    rmse_map: Vec<f32>,
    temporal_map: Vec<f32>,
}

impl Tally {
    fn new(out: &[RgbImage], refs: &[RgbImage], class: &[Vec<usize>]) -> anyhow::Result<Tally> {
        let n = refs[0].width * refs[0].height;
        let k = CLASSES.len();
        let mut t = Tally {
            share: vec![0.0; k],
            rmse: vec![0.0; k + 1],
            temporal: vec![0.0; k + 1],
            rmse_map: vec![0.0; n],
            temporal_map: vec![0.0; n],
        };
        let frames = refs.len() as f64;
        let (pixels, pairs) = (frames * n as f64, (frames - 1.0) * n as f64);
        for f in 0..refs.len() {
            let e = metrics::rmse_heatmap(&out[f], &refs[f])?;
            for i in 0..n {
                let c = class[f][i];
                t.share[c] += 1.0 / pixels;
                t.rmse[c] += e[i] as f64 / pixels;
                t.rmse_map[i] += e[i];
            }
            if f > 0 {
                let d = metrics::temporal_heatmap(&out[f], &out[f - 1], &refs[f], &refs[f - 1])?;
                for i in 0..n {
                    t.temporal[class[f][i]] += d[i] as f64 / pairs;
                    t.temporal_map[i] += d[i];
                }
            }
        }
        t.rmse[k] = t.rmse[..k].iter().sum();
        t.temporal[k] = t.temporal[..k].iter().sum();
        Ok(t)
    }
}

/// Each frame's class of every pixel (an index into [`CLASSES`]).
fn classes(refs: &[RgbImage]) -> Vec<Vec<usize>> {
    let n = refs[0].width * refs[0].height;
    let bright: Vec<bool> = (0..n)
        .map(|i| refs.iter().any(|r| r.planes.iter().any(|p| p[i] > 1.0)))
        .collect();
    let mut moved = vec![vec![false; n]; refs.len()];
    for t in 1..refs.len() {
        let d = metrics::rmse_heatmap(&refs[t], &refs[t - 1]).expect("same sizes");
        moved[t] = d.iter().map(|&v| v > 0.02).collect();
    }
    (0..refs.len())
        .map(|t| {
            (0..n)
                .map(|i| {
                    if bright[i] {
                        1
                    } else if moved[t][i] {
                        let before = moved[t - 1][i];
                        let after = moved.get(t + 1).is_some_and(|m| m[i]);
                        if before || after {
                            RAMP
                        } else {
                            2
                        }
                    } else if (t.saturating_sub(4)..t).any(|k| moved[k][i]) {
                        4
                    } else {
                        0
                    }
                })
                .collect()
        })
        .collect()
}

/// The ramps' changes from frame to frame (the references' channel mean),
/// over the pairs of consecutive ramp frames of a pixel.
struct Ramps {
    pairs: usize,
    /// Pairs whose two changes agree in sign.
    agree: usize,
    /// Sums of the later change's relative square, and of its difference
    /// from the earlier one's.
    change: f64,
    after_line: f64,
}

impl Ramps {
    fn new(refs: &[RgbImage], class: &[Vec<usize>]) -> Ramps {
        let mean = |r: &RgbImage, i: usize| r.planes.iter().map(|p| p[i] as f64).sum::<f64>() / 3.0;
        let mut r = Ramps {
            pairs: 0,
            agree: 0,
            change: 0.0,
            after_line: 0.0,
        };
        for t in 2..refs.len() {
            for i in 0..class[t].len() {
                if class[t][i] != RAMP || class[t - 1][i] != RAMP {
                    continue;
                }
                let d1 = mean(&refs[t], i) - mean(&refs[t - 1], i);
                let d0 = mean(&refs[t - 1], i) - mean(&refs[t - 2], i);
                let scale = mean(&refs[t], i).powi(2) + 0.01;
                r.pairs += 1;
                r.agree += (d1 * d0 > 0.0) as usize;
                r.change += d1 * d1 / scale;
                r.after_line += (d1 - d0).powi(2) / scale;
            }
        }
        r
    }
}
