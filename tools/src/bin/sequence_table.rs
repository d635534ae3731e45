//! Issue #39's baseline: on the animated built-in scenes, each method's
//! mean per-frame rMSE and temporal error (`metrics::temporal_error`) with
//! every frame denoised alone, the input's (the Monte Carlo mean), which
//! the last column divides by, and OIDN's (`benches/oidn.sh`, albedo and
//! normal) on the same statistics. Each frame is rendered once, uniformly,
//! with its own seed (`render::sequence`); every denoiser gets the same
//! statistics; each frame has its own reference, and a second one with
//! another seed: half their rMSE and temporal error against each other is
//! the references' own, which the corrected columns subtract; the
//! references' seeds follow `--seed` unless `--reference-seed` names
//! another sequence seed, whose cached references a run then reuses. With
//! `--temporal`, each method also with the LP temporal filter (§10.1,
//! "+ 10.1"), one denoiser carrying its state through the frames, and
//! with the filter both ways ("+ two-way", TEMPORAL-SMOOTH, a
//! `SequenceDenoiser`). With
//! `--adaptive`, each method's adaptive renders of the sequence instead
//! (its loop's maps: WLR's for LP, APR, AOS and `auto`, MAP-WLR and
//! AUTO-MAPS):
//! alone, with the filter, and with maps that read the filter's state
//! (forwards, and both ways: "adaptive + two-way, TEMPORAL-MAP"; and
//! APR's also reconstructed by its temporal window, "adaptive + 10.2").
//! Every method runs without the pyramid's low band (`auto` too, whose
//! default has it: its rows say "without pyramid"); with `--pyramid`,
//! each method also with it (and, with `--temporal`, followed by the
//! filter). With `--window` (and `apr`
//! among the methods), also APR's temporal window (§10.2, "apr + 10.2",
//! one `SequenceDenoiser` for the sequence).
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin sequence_table -- \
//!     [--scenes pan_room,moving_box,moving_highlight] [--methods wlr,lp,apr,aos,auto] \
//!     [--size 64x64] [--spp 16] [--frames 24] [--reference 512] [--oidn] [--temporal]
//!     [--adaptive] [--pyramid] [--window] [--seed 1] [--reference-seed R]
//! ```

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::Context;
use clap::Parser;
use mcdenoise::render::adaptive::LoopConfig;
use mcdenoise::render::{sequence, Scene};
use mcdenoise::{
    metrics, Config, ContextOptions, Denoiser, GpuContext, Method, Pyramid, RgbImage,
    SequenceDenoiser, Source, StatsImage, Temporal,
};
use mcdenoise_tools::{parse_method, SequenceWithReferences};

#[derive(Parser)]
struct Args {
    /// Animated scenes (built-in names or files).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "pan_room,moving_box,moving_highlight"
    )]
    scenes: Vec<String>,
    /// Methods, each on every frame alone.
    #[arg(long, value_delimiter = ',', default_value = "wlr,lp,apr,aos,auto", value_parser = parse_method)]
    methods: Vec<Method>,
    #[arg(long, default_value = "64x64", value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
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
    /// Seed of the sequence the denoisers get (each frame's own: `render::sequence::frame_seed`).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The sequence seed the references' seeds derive from (default:
    /// `--seed`): runs of other input seeds reuse one seed's cached
    /// references instead of rendering their own.
    #[arg(long)]
    reference_seed: Option<u64>,
    /// Also OIDN on every frame's statistics.
    #[arg(long)]
    oidn: bool,
    /// Also every method followed by the LP temporal filter (spec §10.1).
    #[arg(long)]
    temporal: bool,
    /// Also every method with the pyramid's low band (PYRAMID-LOWBAND),
    /// alone and, with `--temporal`, followed by the filter.
    #[arg(long, conflicts_with = "adaptive")]
    pyramid: bool,
    /// Instead of denoising the uniform frames: each method's adaptive
    /// renders of the sequence alone, with the temporal filter, and with
    /// the filter and sample maps that read its state (TEMPORAL-MAP).
    #[arg(long, conflicts_with_all = ["oidn", "temporal"])]
    adaptive: bool,
    /// Also APR's temporal window (spec §10.2) when apr is among the
    /// methods.
    #[arg(long, conflicts_with = "adaptive")]
    window: bool,
    /// Working folder for OIDN's inputs and outputs.
    #[arg(long, default_value = "target/sequence_table")]
    work: PathBuf,
    /// The frames' features from samples of their own
    /// (`render --feature-samples independent`, RENDER-FEATURE-SAMPLES).
    #[arg(long)]
    independent_features: bool,
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let stop = AtomicBool::new(false);
    let reference_seed = a.reference_seed.unwrap_or(a.seed);
    println!(
        "<!-- {}x{}, {} spp uniform, {} frames, {}-spp references of seed {}, seed {} -->",
        a.size.0, a.size.1, a.spp, a.frames, a.reference, reference_seed, a.seed
    );
    println!(
        "| scene | denoiser | mean rMSE | temporal error | corrected rMSE | corrected temporal | \
         corrected temporal / input's |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|");
    for name in &a.scenes {
        let scene = Scene::by_name_or_file(name)?;
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
            (a.seed, reference_seed),
            mcdenoise_tools::feature_samples(a.independent_features),
        )?;
        let r: Vec<&RgbImage> = refs.iter().collect();
        // The second reference against the first: twice the references'
        // own error, rMSE and temporal (independent seeds); half of it is
        // subtracted from every row's figures in the corrected columns.
        let second_refs: Vec<&RgbImage> = second.iter().collect();
        let own = (
            mean_rmse(&second_refs, &r) / 2.0,
            metrics::temporal_error(&second_refs, &r)?.context("two frames or more")? / 2.0,
        );
        println!(
            "| {name} | the references' own (half of two seeds') | {:.5} | {:.6} | | | |",
            own.0, own.1
        );
        let mut input_temporal = None;
        let mut row = |what: &str, outputs: &[RgbImage]| -> anyhow::Result<()> {
            let o: Vec<&RgbImage> = outputs.iter().collect();
            let mean = mean_rmse(&o, &r);
            let t = metrics::temporal_error(&o, &r)?.context("two frames or more")?;
            let (mc, tc) = (mean - own.0, t - own.1);
            let base = *input_temporal.get_or_insert(tc);
            println!(
                "| {name} | {what} | {mean:.5} | {t:.6} | {mc:.5} | {tc:.6} | {:.3} |",
                tc / base
            );
            Ok(())
        };
        let inputs: Vec<RgbImage> = stats.iter().map(mcdenoise::colour_of).collect();
        row("input", &inputs)?;
        if a.adaptive {
            // Each method's adaptive renders of the sequence (its loop's
            // maps): alone, with the filter, and with the filter and maps
            // that read its state.
            for &m in &a.methods {
                let window =
                    (m == Method::Apr).then_some(("adaptive + 10.2", Temporal::Apr, false));
                for (what, temporal, maps) in [
                    ("adaptive", Temporal::Off, false),
                    ("adaptive + 10.1", Temporal::Lp, false),
                    ("adaptive + 10.1, TEMPORAL-MAP", Temporal::Lp, true),
                    ("adaptive + two-way, TEMPORAL-MAP", Temporal::LpSmooth, true),
                ]
                .into_iter()
                .chain(window)
                {
                    let mut cfg = LoopConfig::new(m, a.spp, true);
                    cfg.temporal_maps = maps;
                    let mut outputs = Vec::new();
                    let frames = 0..a.frames.min(scene.frames());
                    sequence::render_frames(
                        &ctx,
                        &scene,
                        frames,
                        a.size,
                        a.seed,
                        &cfg,
                        temporal,
                        &stop,
                        |f| {
                            outputs.push(f.result.frame.color);
                            Ok(())
                        },
                    )?;
                    row(&format!("{} {what}", m.name()), &outputs)?;
                }
            }
            continue;
        }
        for &m in &a.methods {
            for pyramid in [false, true] {
                if pyramid && !a.pyramid {
                    continue;
                }
                // A method whose default has the pyramid (`auto`) says
                // so where it runs without.
                let name = match (pyramid, m.info().pyramid_auto) {
                    (true, _) => format!("{} + pyramid", m.name()),
                    (false, true) => format!("{} without pyramid", m.name()),
                    (false, false) => m.name().to_string(),
                };
                let config = |temporal: Temporal| {
                    let mut c = Config::new(m);
                    c.pyramid = if pyramid { Pyramid::On } else { Pyramid::Off };
                    c.temporal = temporal;
                    c
                };
                let mut outputs = Vec::with_capacity(stats.len());
                for s in &stats {
                    let d = Denoiser::new(&ctx, Source::of_image(s), config(Temporal::Off))?;
                    outputs.push(d.denoise(s, None)?.color);
                }
                row(&name, &outputs)?;
                if a.temporal {
                    // One denoiser for the sequence: the filter's state goes
                    // from frame to frame.
                    let d = Denoiser::new(&ctx, Source::of_image(&stats[0]), config(Temporal::Lp))?;
                    let outputs = stats
                        .iter()
                        .map(|s| Ok(d.denoise(s, None)?.color))
                        .collect::<mcdenoise::Result<Vec<_>>>()?;
                    row(&format!("{name} + 10.1"), &outputs)?;
                    // The filter both ways (TEMPORAL-SMOOTH).
                    let source = Source::of_image(&stats[0]);
                    let mut seq = SequenceDenoiser::new(&ctx, source, config(Temporal::LpSmooth))?;
                    for s in &stats {
                        seq.push(s)?;
                    }
                    let outputs: Vec<RgbImage> =
                        seq.finish()?.into_iter().map(|(_, f)| f.color).collect();
                    row(&format!("{name} + two-way"), &outputs)?;
                }
            }
            if a.window && m == Method::Apr {
                let mut c = Config::new(m);
                c.temporal = Temporal::Apr;
                let mut seq = SequenceDenoiser::new(&ctx, Source::of_image(&stats[0]), c)?;
                let mut frames = Vec::with_capacity(stats.len());
                let mut gpu_ms = 0.0;
                for s in &stats {
                    frames.extend(seq.push(s)?);
                }
                frames.extend(seq.finish()?);
                let mut outputs = Vec::with_capacity(stats.len());
                let mut errors = Vec::with_capacity(stats.len());
                for (_, f) in frames {
                    gpu_ms += f.timings.iter().map(|t| t.nanoseconds * 1e-6).sum::<f64>();
                    outputs.push(f.color);
                    errors.push(f.error);
                }
                row("apr + 10.2", &outputs)?;
                if a.temporal {
                    // The LP filter on the window's frames: each frame's
                    // statistics with the window's colour as the colour and
                    // its error estimate as the variance, through `none`.
                    let staged: Vec<StatsImage> = stats
                        .iter()
                        .zip(outputs.iter().zip(&errors))
                        .map(|(s, (o, e))| {
                            let mut s = s.clone();
                            s.set(mcdenoise::Layer::Color, o.planes.to_vec());
                            s.set(mcdenoise::Layer::ColorVariance, e.planes.to_vec());
                            s
                        })
                        .collect();
                    let mut c = Config::new(Method::None);
                    c.temporal = Temporal::Lp;
                    let d = Denoiser::new(&ctx, Source::of_image(&staged[0]), c)?;
                    let filtered = staged
                        .iter()
                        .map(|s| Ok(d.denoise(s, None)?.color))
                        .collect::<mcdenoise::Result<Vec<_>>>()?;
                    row("apr + 10.2 + 10.1", &filtered)?;
                }
                eprintln!(
                    "{name}: apr + 10.2, GPU {:.1} ms per frame (the calls that output one)",
                    gpu_ms / outputs.len() as f64
                );
            }
        }
        if a.oidn {
            let images = mcdenoise_tools::oidn_frames(&stats, &a.work.join(name))?;
            row("OIDN", &images)?;
        }
    }
    Ok(())
}

/// Mean over frames of each frame's rMSE against its reference.
fn mean_rmse(out: &[&RgbImage], refs: &[&RgbImage]) -> f64 {
    let sum: f64 = out.iter().zip(refs).map(|(o, r)| metrics::rmse(o, r)).sum();
    sum / out.len().max(1) as f64
}
