//! Developer probe: pipeline creation time per kernel, and the GPU time of the
//! sanitation passes on the committed fixture.
use mcdenoise::gpu::*;
use mcdenoise::image::Layer;
use mcdenoise::methods::{prepare::*, stats::GpuStats};
use std::sync::Arc;
fn main() {
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default()).unwrap());
    for d in mcdenoise::kernels::ALL {
        for p in [Precision::F32, Precision::F64] {
            let t = std::time::Instant::now();
            ctx.pipeline(d, p).unwrap();
            println!(
                "{}{}: {:.3} s",
                d.name,
                p.suffix(),
                t.elapsed().as_secs_f64()
            );
        }
    }
    let img = mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap();
    let layers: Vec<Layer> = img.layers().map(|(l, _)| l).collect();
    let stats = GpuStats::new(
        &ctx,
        "stats",
        img.width,
        img.height,
        &output_layers(&layers),
    )
    .unwrap();
    stats.upload_image(&img).unwrap();
    let scratch = PrepareScratch::new(&ctx, &stats, None).unwrap();
    let t = std::time::Instant::now();
    let mut batch = Batch::new(&ctx).unwrap();
    record_prepare(
        &mut batch,
        Precision::F32,
        &layers,
        &stats,
        &scratch,
        true,
        [0, 0],
    )
    .unwrap();
    let tim = batch.finish().unwrap();
    println!("wall {:.3}", t.elapsed().as_secs_f64());
    for t in tim.iter().take(6) {
        println!("{} {:?} {:.3} ms", t.kernel, t.rows, t.nanoseconds / 1e6);
    }
}
