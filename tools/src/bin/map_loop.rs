//! The adaptive loop (WLR's maps, its schedule) run by hand through the
//! facade on host statistics, so that what the maps see can be changed:
//! `plain` hands each pass's WLR the statistics as they are; `medvar`
//! replaces each pixel's colour variance of the mean by the median over
//! its 5×5 window of the per-sample variances (`vbar·n`), over its own
//! count — the map no longer follows one pixel's rare bright sample.
//! The final statistics are written as they are.
//!
//! `cargo run --release -p mcdenoise-tools --bin map_loop -- SCENE SIZE SPP SEED MODE out.exr`
use std::sync::Arc;

use mcdenoise::gpu::GpuBuffer;
use mcdenoise::render::{Renderer, Samples, Scene};
use mcdenoise::{
    Batch, Config, ContextOptions, Denoiser, GpuContext, InputBlend, Layer, Method, Pass,
    Precision, Pyramid, Schedule, Source, StatsImage, Validation,
};

const USAGE: &str = "usage: map_loop SCENE SIZE SPP SEED plain|medvar[:R] out.exr";

fn medvar(img: &mut StatsImage, radius: usize) {
    let (w, h) = (img.width, img.height);
    let n: Vec<f32> = img.get(Layer::Spp).unwrap()[0].clone();
    let planes = img.get_mut(Layer::ColorVariance).unwrap();
    for p in planes.iter_mut() {
        let per_sample: Vec<f32> = p.iter().zip(&n).map(|(v, &c)| v * c.max(1.0)).collect();
        let mut win = Vec::with_capacity((2 * radius + 1).pow(2));
        for y in 0..h {
            for x in 0..w {
                win.clear();
                for qy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
                    for qx in x.saturating_sub(radius)..(x + radius + 1).min(w) {
                        if n[qy * w + qx] >= 1.0 {
                            win.push(per_sample[qy * w + qx]);
                        }
                    }
                }
                if win.is_empty() {
                    continue;
                }
                win.sort_by(f32::total_cmp);
                let i = y * w + x;
                p[i] = win[win.len() / 2] / n[i].max(1.0);
            }
        }
    }
}

fn main() -> anyhow::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 7 {
        anyhow::bail!("{USAGE}");
    }
    let scene = Scene::by_name_or_file(&a[1])?;
    let size: usize = a[2].parse()?;
    let spp: u32 = a[3].parse()?;
    let seed: u64 = a[4].parse()?;
    let radius: Option<usize> = match a[5].as_str() {
        "plain" => None,
        m if m.starts_with("medvar") => Some(m.split(':').nth(1).map_or(Ok(2), |r| r.parse())?),
        m => anyhow::bail!("mode {m}"),
    };
    let ctx = Arc::new(GpuContext::new(&ContextOptions {
        device: None,
        validation: Validation::Off,
        ..Default::default()
    })?);
    let r = Renderer::new(&ctx, &scene, size, size, seed)?;
    // The schedule of WLR's loop (§9.3): 4 uniform spp, five passes.
    let s = Schedule::new(spp, size * size, 4, 5)?;
    let mut b = Batch::new(&ctx)?;
    r.record_pass(&mut b, Samples::Uniform(s.initial_spp))?;
    b.finish()?;
    let mut c = Config::new(Method::Wlr);
    c.pass = Pass::Intermediate;
    c.pyramid = Pyramid::Off;
    c.input_blend = InputBlend::Off;
    let mut bufs = Vec::new();
    for &budget in &s.budgets {
        let mut img = r.statistics_at(Precision::F32)?;
        if let Some(rad) = radius {
            medvar(&mut img, rad);
        }
        let d = Denoiser::new(&ctx, Source::of_image(&img), c.clone())?;
        let f = d.denoise(&img, Some(budget))?;
        let counts = f.samples.expect("a sample map");
        bufs.push(GpuBuffer::from_slice(&ctx, "loop.map", &counts)?);
        let mut b = Batch::new(&ctx)?;
        r.record_pass(
            &mut b,
            Samples::Map {
                map: bufs.last().unwrap().slice(),
                total: budget,
            },
        )?;
        b.finish()?;
    }
    mcdenoise::io::write_stats(
        std::path::Path::new(&a[6]),
        &r.statistics_at(Precision::F32)?,
    )?;
    Ok(())
}
