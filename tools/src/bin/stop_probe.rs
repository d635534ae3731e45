//! What an open-ended render's stop rule could judge by, pass by pass.
//!
//! Per scene, the adaptive loop runs to `--max-spp` (a target no render
//! reaches, so every pass doubles the samples) and each pass's final
//! reconstruction is compared with the references. One JSON line per
//! pass: the samples so far, the stop rule's estimate (STOP-CHANGE), the
//! method's estimate times its error scale, the true rMSE (raw, and with
//! the references' own error taken off), and the change since the previous
//! pass's reconstruction, `mean (F_{k−1} − F_k)² / (F_k² + 0.01)`, which
//! for an error falling as `1/N` equals the newer one's error times
//! `(N_k − N_{k−1}) / N_{k−1}`.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin stop_probe -- \
//!     --scenes a,b [--size 128x128] [--method wlr] [--seed 3] [--max-spp 256] [--reference 1024] [--uniform]
//! ```

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use clap::Parser;
use mcdenoise::render::adaptive::{self, LoopConfig};
use mcdenoise::render::{Renderer, Scene};
use mcdenoise::{metrics, ContextOptions, GpuContext, Method, RgbImage};
use mcdenoise_tools::{corrected, parse_method, references};

#[derive(Parser)]
struct Args {
    /// Scenes (built-in names or TOML files), comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    scenes: Vec<String>,
    /// Image size.
    #[arg(long, default_value = "128x128", value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
    size: (usize, usize),
    /// The reconstruction (and, by its default, the maps' method).
    #[arg(long, default_value = "wlr", value_parser = parse_method)]
    method: Method,
    /// The render's seed.
    #[arg(long, default_value_t = 3)]
    seed: u64,
    /// Where the render stops.
    #[arg(long, default_value_t = 256)]
    max_spp: u32,
    /// Samples per pixel of each of the two references.
    #[arg(long, default_value_t = 1024)]
    reference: u32,
    /// Uniform passes in place of adaptive ones.
    #[arg(long)]
    uniform: bool,
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    for name in &a.scenes {
        let scene = Scene::by_name_or_file(name)?;
        let (_, r, ref_err) = references(&ctx, &scene, a.size, a.reference, 2, 3)?;
        let renderer = Renderer::new(&ctx, &scene, a.size.0, a.size.1, a.seed)?;
        let cfg = LoopConfig {
            stop: Some(adaptive::StopRules {
                target_error: Some(1e-12),
                time_limit: None,
                max_spp: a.max_spp,
            }),
            ..LoopConfig::new(a.method, a.max_spp, !a.uniform)
        };
        let final_cfg = adaptive::final_config(&cfg, mcdenoise::Temporal::Off);
        let scale = final_cfg.error_scale(a.size.0, a.size.1);
        let mut previous: Option<(f64, RgbImage)> = None;
        let stop = AtomicBool::new(false);
        adaptive::render(&ctx, &renderer, &cfg, &stop, |p| {
            let (Some(frame), Some(estimate)) = (p.frame, p.estimate) else {
                return;
            };
            let raw = metrics::rmse(&frame.color, &r);
            let mut line = serde_json::json!({
                "scene": name,
                "method": a.method.name(),
                "spp": p.spp,
                "estimate": estimate,
                "method_estimate": adaptive::stop_estimate(&final_cfg, frame),
                "scale": scale,
                "true": raw,
                "true_corrected": corrected(raw, ref_err),
                "ref_err": ref_err,
            });
            if let Some((spp, f)) = &previous {
                line["change"] = serde_json::json!(metrics::rmse(f, &frame.color));
                line["previous_spp"] = serde_json::json!(spp);
            }
            println!("{line}");
            previous = Some((p.spp, frame.color.clone()));
        })?;
    }
    Ok(())
}
