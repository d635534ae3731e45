//! Samples per second of the built-in renderer's map-driven passes against
//! a uniform pass, from GPU timestamps: for each built-in scene (or the ones
//! named), an adaptive render's sample counts (WLR, `--spp` on average)
//! are replayed as one map pass on a fresh renderer after the same 4-spp
//! first pass, next to a uniform pass of the same number of samples and a
//! map pass of the same counts shuffled over the pixels (the same crowding,
//! other pixels: what is left of the gap is the cost of the pixels the map
//! chose), and a uniform pass over only the pixels that see geometry (a
//! sample that sees the environment costs one short traversal, and an
//! adaptive map gives such pixels almost nothing). The last columns are
//! the uniform and the map pass's rays per sample (camera, bounce and
//! shadow rays, counted by the renderer: `Renderer::traversal`) and their
//! millions of rays per second: what a sample costs, and how fast the
//! renderer traces whichever samples it is given.
//!
//! Each pass is timed `--reps` times (default 5), the three kinds in turn,
//! and the median is reported: on a shared machine single timings vary by
//! tens of per cent.
//!
//! `cargo run --release -p mcdenoise-tools --bin render_rate -- [--size 256] [--spp 16] [--reps 5] [scene…]`

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use mcdenoise::gpu::GpuBuffer;
use mcdenoise::render::adaptive::{render, LoopConfig};
use mcdenoise::render::{Renderer, Samples, Scene, Traversal};
use mcdenoise::{Batch, ContextOptions, GpuContext, KernelTiming, Method, Validation};

/// GPU milliseconds of the renderer's kernels in `t`.
fn render_ms(t: &[KernelTiming]) -> f64 {
    t.iter()
        .filter(|k| k.kernel.starts_with("render_"))
        .map(|k| k.nanoseconds / 1e6)
        .sum()
}

/// The median of `v`.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A fresh renderer after a uniform first pass of 4 spp, then `samples`;
/// the GPU time of the second pass and its traversal work.
fn timed_pass(
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    size: usize,
    samples: impl Fn(&Renderer) -> Samples,
) -> anyhow::Result<(f64, Traversal)> {
    let r = Renderer::new(ctx, scene, size, size, 1)?;
    let mut b = Batch::new(ctx)?;
    r.record_pass(&mut b, Samples::Uniform(4))?;
    b.finish()?;
    let before = r.traversal()?;
    let mut b = Batch::new(ctx)?;
    r.record_pass(&mut b, samples(&r))?;
    let ms = render_ms(&b.finish()?);
    Ok((ms, r.traversal()? - before))
}

const USAGE: &str = "usage: render_rate [--size 256] [--spp 16] [--reps 5] [scene ...]";

fn main() -> anyhow::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    let mut size = 256usize;
    let mut spp = 16u32;
    let mut reps = 5usize;
    let mut names = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--size" => size = args.next().unwrap().parse()?,
            "--spp" => spp = args.next().unwrap().parse()?,
            "--reps" => reps = args.next().unwrap().parse()?,
            _ => names.push(a),
        }
    }
    if names.is_empty() {
        names = Scene::builtin_still_names()
            .iter()
            .map(|s| s.to_string())
            .collect();
    }
    let ctx = Arc::new(GpuContext::new(&ContextOptions {
        device: None,
        validation: Validation::Off,
        ..Default::default()
    })?);
    println!("device: {}", ctx.info().name);
    println!(
        "{:<14} {:>9} {:>11} {:>11} {:>11} {:>11} {:>11} {:>6} {:>6} {:>7} {:>7} {:>7} {:>7}",
        "scene",
        "samples",
        "adaptive/s",
        "uniform/s",
        "map/s",
        "shuffled/s",
        "geometry/s",
        "miss%",
        "map/u",
        "rays/u",
        "rays/m",
        "Mrays/u",
        "Mrays/m",
    );
    let pixels = size * size;
    let mut buffers: Vec<GpuBuffer> = Vec::new();
    for name in names {
        let scene = Scene::by_name_or_file(&name)?;
        let cfg = LoopConfig::new(Method::Wlr, spp, true);
        let r = Renderer::new(&ctx, &scene, size, size, 1)?;
        let result = render(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {})?;
        let adaptive_rate = result.samples as f64 / result.split.render_ms * 1e3;
        let first = result.schedule.as_ref().map_or(4, |s| s.initial_spp);
        let l = r.layout();
        let planes = r.download()?;
        let counts = mcdenoise_tools::samples_after_first(&planes, &l, first);
        let total: u32 = counts.iter().sum();
        let uniform_spp = total / pixels as u32;
        // A fixed permutation (multiplicative hash of the pixel index).
        let mut order: Vec<usize> = (0..pixels).collect();
        order.sort_by_key(|&p| (p as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 16);
        let shuffled: Vec<u32> = order.iter().map(|&p| counts[p]).collect();
        // Pixels none of whose samples hit anything (Σdepth = 0).
        let depth = &planes[l.sum_plane(9)];
        let hits: Vec<u32> = depth
            .iter()
            .map(|&d| if d > 0.0 { uniform_spp } else { 0 })
            .collect();
        let misses = hits.iter().filter(|&&c| c == 0).count();
        let variants: Vec<(Samples, u32)> = [&counts, &shuffled, &hits]
            .into_iter()
            .map(|c| {
                let total = c.iter().sum();
                let b = GpuBuffer::from_slice(&ctx, "rate.map", c)?;
                buffers.push(b);
                let map = buffers.last().unwrap().slice();
                Ok((Samples::Map { map, total }, total))
            })
            .collect::<anyhow::Result<_>>()?;
        let variants: Vec<(Samples, u32)> =
            std::iter::once((Samples::Uniform(uniform_spp), uniform_spp * pixels as u32))
                .chain(variants)
                .collect();
        let mut ms = vec![Vec::new(); variants.len()];
        // A pass's traversal work is the same in every repetition.
        let mut work = vec![Traversal::default(); variants.len()];
        for _ in 0..reps.max(1) {
            for (v, (samples, _)) in variants.iter().enumerate() {
                let (t, w) = timed_pass(&ctx, &scene, size, |_| *samples)?;
                ms[v].push(t);
                work[v] = w;
            }
        }
        let medians: Vec<f64> = ms.iter_mut().map(|t| median(t)).collect();
        let rates: Vec<f64> = variants
            .iter()
            .zip(&medians)
            .map(|((_, n), t)| *n as f64 / t * 1e3)
            .collect();
        let rays_per_sample = |v: usize| work[v].rays as f64 / variants[v].1.max(1) as f64;
        let mrays = |v: usize| work[v].rays as f64 / medians[v] / 1e3;
        println!(
            "{name:<14} {total:>9} {:>11.0} {:>11.0} {:>11.0} {:>11.0} {:>11.0} {:>6.1} {:>6.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2}",
            adaptive_rate,
            rates[0],
            rates[1],
            rates[2],
            rates[3],
            100.0 * misses as f64 / pixels as f64,
            rates[1] / rates[0],
            rays_per_sample(0),
            rays_per_sample(1),
            mrays(0),
            mrays(1),
        );
    }
    Ok(())
}
