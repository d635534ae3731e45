//! What the tools share: method names on the command line, OIDN, the
//! mean of reference renders with their own error taken off, and an
//! animated scene's frames with two references each.

use std::path::PathBuf;

use anyhow::{bail, Context};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use mcdenoise::render::{reference, Scene};
use mcdenoise::{GpuContext, Method, RgbImage};

/// Prints `usage` and returns true when the command line asks for help
/// (`-h` or `--help` anywhere): the tools that read their arguments by hand
/// call it first, so that `--help` is never taken for a file name.
pub fn asked_for_help(usage: &str) -> bool {
    let asked = std::env::args().skip(1).any(|a| a == "-h" || a == "--help");
    if asked {
        println!("{usage}");
    }
    asked
}

/// Exits with status 2 after printing `usage` on stderr when the command
/// line has fewer than `n` arguments (not counting the program), instead of
/// a panic at the first missing one.
pub fn require_args(usage: &str, n: usize) {
    if std::env::args().len() <= n {
        eprintln!("{usage}");
        std::process::exit(2);
    }
}

/// A method by name, for clap's `value_parser` (`--methods wlr,lp`).
pub fn parse_method(name: &str) -> Result<Method, String> {
    Method::from_name(name).ok_or_else(|| format!("no method {name:?}"))
}

/// A G-buffer prefilter by the CLI's names (`render --prefilter`): `auto`,
/// `gbf` or `none`.
pub fn parse_prefilter(name: &str) -> Result<mcdenoise::Prefilter, String> {
    match name {
        "auto" => Ok(mcdenoise::Prefilter::Auto),
        "gbf" => Ok(mcdenoise::Prefilter::On),
        "none" => Ok(mcdenoise::Prefilter::Off),
        _ => Err(format!("no prefilter {name:?}: auto, gbf or none")),
    }
}

/// Runs OIDN 2.5 (`benches/oidn.sh`: albedo and normal, installed on first
/// use) on `(statistics EXR, output EXR)` pairs, from the repository root.
pub fn oidn(pairs: &[(PathBuf, PathBuf)]) -> anyhow::Result<()> {
    let mut cmd = std::process::Command::new("bash");
    cmd.arg("benches/oidn.sh");
    for (i, o) in pairs {
        cmd.arg(i).arg(o);
    }
    let out = cmd.output().context("running benches/oidn.sh")?;
    if !out.status.success() {
        bail!("oidn.sh failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    Ok(())
}

/// OIDN ([`oidn`]) on every frame of a sequence: each frame's statistics
/// written to `dir` (`in_0000.exr`, …), OIDN's outputs beside them
/// (`oidn_0000.exr`, …) and read back, in frame order.
pub fn oidn_frames(
    stats: &[mcdenoise::StatsImage],
    dir: &std::path::Path,
) -> anyhow::Result<Vec<RgbImage>> {
    std::fs::create_dir_all(dir)?;
    let mut pairs = Vec::new();
    for (k, s) in stats.iter().enumerate() {
        let (i, o) = (
            dir.join(format!("in_{k:04}.exr")),
            dir.join(format!("oidn_{k:04}.exr")),
        );
        mcdenoise::io::write_stats(&i, s)?;
        pairs.push((i, o));
    }
    oidn(&pairs)?;
    Ok(pairs
        .iter()
        .map(|(_, o)| mcdenoise::io::read_rgb(o))
        .collect::<mcdenoise::Result<Vec<_>>>()?)
}

/// The pixel-wise mean of `images` (at least one, all of one size).
pub fn mean_image<'a>(images: impl IntoIterator<Item = &'a RgbImage>) -> RgbImage {
    let images: Vec<&RgbImage> = images.into_iter().collect();
    let first = images[0];
    let k = 1.0 / images.len() as f32;
    let planes = std::array::from_fn(|c| {
        (0..first.planes[c].len())
            .map(|i| images.iter().map(|m| m.planes[c][i]).sum::<f32>() * k)
            .collect()
    });
    RgbImage::from_planes(first.width, first.height, planes)
}

/// The rMSE of an output against a reference with the reference's own
/// estimated error taken off (never below a tenth of the raw value).
pub fn corrected(raw: f64, ref_err: f64) -> f64 {
    (raw - ref_err).max(0.1 * raw)
}

/// `renders` references of `spp` spp of `scene` (cached; render k's seed is
/// `reference_seed(seed) ^ 2k`, so k = 0 and 1 are the pair every
/// two-render table uses), their mean `r`, and the mean's own estimated
/// error `rMSE(h₀, r)`, h₀ and h₁ the means of the even- and odd-numbered
/// renders: E[(r − t)²] = E[(h₀ − h₁)²]/4 = E[(h₀ − r)²], weighted as the
/// metric weighs an output's error.
pub fn references(
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    size: (usize, usize),
    spp: u32,
    renders: u32,
    seed: u64,
) -> mcdenoise::Result<(Vec<reference::Reference>, RgbImage, f64)> {
    let stop = AtomicBool::new(false);
    let refs = (0..u64::from(renders))
        .map(|k| {
            let s = reference::reference_seed(seed) ^ (2 * k);
            reference::reference(ctx, scene, size, spp, s, &stop, |_, _| {})
        })
        .collect::<mcdenoise::Result<Vec<_>>>()?;
    let half = |parity: usize| mean_image(refs.iter().skip(parity).step_by(2).map(|r| &r.image));
    let h0 = half(0);
    let r = mean_image([&h0, &half(1)]);
    let err = mcdenoise::metrics::rmse(&h0, &r);
    Ok((refs, r, err))
}

/// An animated scene's frames `0..frames` (at most the scene's), each
/// rendered once, uniformly at `spp` with its own seed
/// (`render::sequence`), and two `reference`-spp references of every
/// frame with independent seeds derived from `reference_seed`'s sequence
/// (cached). Half the second references' error against the first is the
/// references' own.
pub struct SequenceWithReferences {
    /// Every frame's statistics.
    pub stats: Vec<mcdenoise::StatsImage>,
    /// Every frame's reference.
    pub refs: Vec<RgbImage>,
    /// Every frame's second reference, of another seed.
    pub second: Vec<RgbImage>,
}

impl SequenceWithReferences {
    /// Renders (or reads from the cache) the frames, their features from
    /// `feature_samples`, and their references.
    pub fn render(
        ctx: &Arc<GpuContext>,
        scene: &Scene,
        frames: u32,
        size: (usize, usize),
        (spp, reference): (u32, u32),
        (seed, reference_seed): (u64, u64),
        feature_samples: mcdenoise::render::FeatureSamples,
    ) -> mcdenoise::Result<SequenceWithReferences> {
        use mcdenoise::render::{adaptive::LoopConfig, sequence};
        let stop = AtomicBool::new(false);
        let cfg = LoopConfig {
            feature_samples,
            ..LoopConfig::new(Method::None, spp, false)
        };
        let mut s = SequenceWithReferences {
            stats: Vec::new(),
            refs: Vec::new(),
            second: Vec::new(),
        };
        let off = mcdenoise::Temporal::Off;
        let frames = 0..frames.min(scene.frames());
        sequence::render_frames(ctx, scene, frames, size, seed, &cfg, off, &stop, |f| {
            let base = sequence::frame_seed(reference_seed, f.number);
            for (seed, out) in [(base, &mut s.refs), (!base, &mut s.second)] {
                let seed = reference::reference_seed(seed);
                let r =
                    reference::reference(ctx, &f.scene, size, reference, seed, &stop, |_, _| {})?;
                out.push(r.image);
            }
            s.stats.push(f.stats);
            Ok(())
        })?;
        Ok(s)
    }
}

/// The renderer's features: from samples of their own when `independent`
/// (the tools' `--independent-features`), else the colour's.
pub fn feature_samples(independent: bool) -> mcdenoise::render::FeatureSamples {
    if independent {
        mcdenoise::render::FeatureSamples::Independent
    } else {
        mcdenoise::render::FeatureSamples::Shared
    }
}

/// A method's frames of a sequence alone, through the LP temporal filter
/// (§10.1) in frame order, and when asked through the two-way filter
/// (TEMPORAL-SMOOTH, [`mcdenoise::Temporal::LpSmooth`]).
pub struct TwoWay {
    /// Every frame alone.
    pub alone: Vec<RgbImage>,
    /// Every frame through the filter in frame order.
    pub forward: Vec<RgbImage>,
    /// Every frame through the two-way filter (empty unless asked for).
    pub combined: Vec<RgbImage>,
}

impl TwoWay {
    /// Runs `method` (its default configuration with `options` and
    /// `prefilter`) on `stats`, a sequence's frames in order: alone,
    /// through the filter, and with `two_way` through the two-way filter.
    pub fn run(
        ctx: &Arc<GpuContext>,
        method: Method,
        options: &mcdenoise::Options,
        prefilter: mcdenoise::Prefilter,
        stats: &[mcdenoise::StatsImage],
        two_way: bool,
    ) -> anyhow::Result<TwoWay> {
        use mcdenoise::{Config, Denoiser, SequenceDenoiser, Source, Temporal};
        let source = Source::of_image(&stats[0]);
        let config = |temporal: Temporal| {
            let mut c = Config::new(method);
            c.temporal = temporal;
            c.options = options.clone();
            c.prefilter = prefilter;
            c
        };
        let run = |temporal: Temporal| -> mcdenoise::Result<Vec<RgbImage>> {
            let d = Denoiser::new(ctx, source.clone(), config(temporal))?;
            stats
                .iter()
                .map(|s| Ok(d.denoise(s, None)?.color))
                .collect()
        };
        let combined = if two_way {
            let mut seq = SequenceDenoiser::new(ctx, source.clone(), config(Temporal::LpSmooth))?;
            for s in stats {
                seq.push(s)?;
            }
            seq.finish()?.into_iter().map(|(_, f)| f.color).collect()
        } else {
            Vec::new()
        };
        Ok(TwoWay {
            alone: run(Temporal::Off)?,
            forward: run(Temporal::Lp)?,
            combined,
        })
    }
}

/// Each pixel's samples after a uniform first pass of `first` spp (what
/// an adaptive render's maps gave it), from a renderer's downloaded
/// accumulation planes.
pub fn samples_after_first(
    planes: &[Vec<f32>],
    layout: &mcdenoise::AccumLayout,
    first: u32,
) -> Vec<u32> {
    planes[layout.count_plane()]
        .iter()
        .map(|&c| c as u32 - first)
        .collect()
}
