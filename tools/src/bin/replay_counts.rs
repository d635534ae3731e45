//! Selection bias of adaptive sampling: an adaptive render's final sample
//! counts (WLR's maps, seed A) rendered again with independent samples
//! (seed B): a 4-spp first pass, then one pass of the same counts. The
//! counts no longer depend on the values they average, so the difference
//! between the two renders' reconstructions is what the dependence costs.
//! Writes both statistics files.
//!
//! `cargo run --release -p mcdenoise-tools --bin replay_counts -- SCENE SIZE SPP SEED_A SEED_B adaptive.exr replayed.exr`
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use mcdenoise::gpu::GpuBuffer;
use mcdenoise::render::adaptive::{render, LoopConfig};
use mcdenoise::render::{Renderer, Samples, Scene};
use mcdenoise::{Batch, ContextOptions, GpuContext, Method, Precision, Validation};

const USAGE: &str = "usage: replay_counts SCENE SIZE SPP SEED_A SEED_B adaptive.exr replayed.exr";

fn main() -> anyhow::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 8 {
        anyhow::bail!("{USAGE}");
    }
    let scene = Scene::by_name_or_file(&a[1])?;
    let size: usize = a[2].parse()?;
    let spp: u32 = a[3].parse()?;
    let (seed_a, seed_b): (u64, u64) = (a[4].parse()?, a[5].parse()?);
    let ctx = Arc::new(GpuContext::new(&ContextOptions {
        device: None,
        validation: Validation::Off,
        ..Default::default()
    })?);
    let cfg = LoopConfig::new(Method::Wlr, spp, true);
    let r = Renderer::new(&ctx, &scene, size, size, seed_a)?;
    let result = render(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {})?;
    let first = result.schedule.as_ref().map_or(4, |s| s.initial_spp);
    mcdenoise::io::write_stats(
        std::path::Path::new(&a[6]),
        &r.statistics_at(Precision::F32)?,
    )?;
    let counts = mcdenoise_tools::samples_after_first(&r.download()?, &r.layout(), first);
    let total: u32 = counts.iter().sum();
    let map = GpuBuffer::from_slice(&ctx, "replay.map", &counts)?;
    let r2 = Renderer::new(&ctx, &scene, size, size, seed_b)?;
    let mut b = Batch::new(&ctx)?;
    r2.record_pass(&mut b, Samples::Uniform(first))?;
    b.finish()?;
    let mut b = Batch::new(&ctx)?;
    r2.record_pass(
        &mut b,
        Samples::Map {
            map: map.slice(),
            total,
        },
    )?;
    b.finish()?;
    mcdenoise::io::write_stats(
        std::path::Path::new(&a[7]),
        &r2.statistics_at(Precision::F32)?,
    )?;
    Ok(())
}
