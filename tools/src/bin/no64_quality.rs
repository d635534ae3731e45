//! The cost in quality of running without 64-bit GPU types (issue #40):
//! each method's rMSE on the public scenes with a context that has
//! `shaderFloat64` / `shaderInt64` enabled and with one that leaves them
//! off (`ContextOptions::no_64bit`: WLR's steps 6-7 then run in
//! double-float, the `_dd` kernel variants), and their ratio.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin no64_quality -- \
//!     --public ../shared/data/scenes [--methods wlr,auto,lp,apr] [--spp 4,16,64]
//! ```

use std::path::PathBuf;
use std::sync::Arc;

use clap::Parser;
use mcdenoise::{io, metrics, Config, ContextOptions, Denoiser, GpuContext, Method, Source};

#[derive(Parser)]
struct Args {
    #[arg(long)]
    public: PathBuf,
    #[arg(long, value_delimiter = ',', default_value = "wlr,auto,lp,apr")]
    methods: Vec<String>,
    #[arg(long, value_delimiter = ',', default_value = "4,16,64")]
    spp: Vec<u32>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let context = |no_64bit| -> anyhow::Result<Arc<GpuContext>> {
        Ok(Arc::new(GpuContext::new(&ContextOptions {
            no_64bit,
            ..Default::default()
        })?))
    };
    let (full, small) = (context(false)?, context(true)?);
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&args.public)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("reference.exr").exists())
        .collect();
    scenes.sort();
    println!("| method | scene | spp | rMSE with 64-bit | rMSE without | ratio |");
    println!("|---|---|---:|---:|---:|---:|");
    for name in &args.methods {
        let method = Method::from_name(name).ok_or_else(|| anyhow::anyhow!("method {name}"))?;
        let mut ratios = Vec::new();
        for scene in &scenes {
            let reference = io::read_rgb(&scene.join("reference.exr"))?;
            for spp in &args.spp {
                let img = io::read_stats(&scene.join(format!("spp{spp}.exr")))?;
                let run = |ctx: &Arc<GpuContext>| -> anyhow::Result<f64> {
                    let d = Denoiser::new(ctx, Source::of_image(&img), Config::new(method))?;
                    Ok(metrics::rmse(&d.denoise(&img, None)?.color, &reference))
                };
                let (a, b) = (run(&full)?, run(&small)?);
                ratios.push(b / a);
                let scene_name = scene.file_name().unwrap().to_string_lossy();
                println!(
                    "| {name} | {scene_name} | {spp} | {a:.6} | {b:.6} | {:.5} |",
                    b / a
                );
            }
        }
        let worst = ratios.iter().fold(1.0f64, |m, &r| {
            if (r - 1.0).abs() > (m - 1.0).abs() {
                r
            } else {
                m
            }
        });
        println!("| {name} | worst | | | | {worst:.5} |");
    }
    Ok(())
}
