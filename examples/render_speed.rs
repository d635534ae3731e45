//! Renders every built-in scene (or the ones named) with the built-in path
//! tracer and reports samples per second; writes a PNG preview of each to
//! `--out DIR` when given.
//!
//! `cargo run --release --example render_speed -- [--size 256] [--spp 4] [--out DIR] [scene…]`

use std::sync::Arc;
use std::time::Instant;

use mcdenoise::io::write_png_preview;
use mcdenoise::render::{Renderer, Samples, Scene};
use mcdenoise::{Batch, ContextOptions, GpuContext, Layer, RgbImage, Validation};

fn main() -> anyhow::Result<()> {
    let mut size = 256usize;
    let mut spp = 4u32;
    let mut out: Option<std::path::PathBuf> = None;
    let mut names = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--size" => size = args.next().unwrap().parse()?,
            "--spp" => spp = args.next().unwrap().parse()?,
            "--out" => out = Some(args.next().unwrap().into()),
            _ => names.push(a),
        }
    }
    if names.is_empty() {
        names = Scene::builtin_names()
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
        "{:<14} {:>6} {:>5} {:>10} {:>12} {:>10}",
        "scene", "size", "spp", "seconds", "samples/s", "s per spp"
    );
    for name in names {
        let scene = Scene::by_name_or_file(&name)?;
        let r = Renderer::new(&ctx, &scene, size, size, 1)?;
        // Warm-up: the first dispatch compiles the pipeline (llvmpipe).
        let mut b = Batch::new(&ctx)?;
        r.record_pass(&mut b, Samples::Uniform(1))?;
        b.finish()?;
        let mut b = Batch::new(&ctx)?;
        r.record_clear(&mut b);
        let t = Instant::now();
        r.record_pass(&mut b, Samples::Uniform(spp))?;
        let timings = b.finish()?;
        let secs = t.elapsed().as_secs_f64();
        let samples = (size * size) as f64 * spp as f64;
        let bands = timings
            .iter()
            .filter(|k| k.kernel == "render_trace")
            .count();
        // GPU time per kernel: tracing against numbering and resolving.
        let kernels: Vec<String> = mcdenoise::gpu::batch::timings_per_kernel(&timings)
            .iter()
            .map(|(k, ns, _)| format!("{k} {:.0} ms", ns / 1e6))
            .collect();
        println!(
            "{name:<14} {:>6} {spp:>5} {secs:>10.2} {:>12.0} {:>10.3}   ({bands} bands; {})",
            format!("{size}²"),
            samples / secs,
            secs / spp as f64,
            kernels.join(", ")
        );
        if let Some(dir) = &out {
            std::fs::create_dir_all(dir)?;
            let st = r.statistics()?;
            let c = st.get(Layer::Color).unwrap();
            let img = RgbImage::from_planes(size, size, [c[0].clone(), c[1].clone(), c[2].clone()]);
            write_png_preview(&dir.join(format!("{name}.png")), &img)?;
        }
    }
    Ok(())
}
