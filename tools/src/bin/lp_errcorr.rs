//! Error-estimate quality of LP and WLR with the G-buffer prefilter on and
//! off (issue #9): for every scene of a quality folder, every requested spp
//! and method, the rMSE and `err corr` of `mcdenoise bench`
//! ([`error_correlation`]: Pearson correlation of the 8×8 tile means of the
//! estimated and the actual squared error), then the mean over the scenes.
//! `mcdenoise bench --quality` has no `--opt`, hence this probe.
//!
//! `cargo run --release -p mcdenoise-tools --bin lp_errcorr -- DIR [--methods lp,wlr]
//! [--spp 16,64] [--prefilter on,off] [--backend gpu|cpu] [--opt KEY=VALUE]...`

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use mcdenoise::bench::{discover_scenes, error_correlation};
use mcdenoise::gpu::{ContextOptions, GpuContext};
use mcdenoise::methods::{denoise, Backend, DenoiseRequest, Method};
use mcdenoise::options::Options;

const USAGE: &str = "usage: lp_errcorr DIR [--methods lp,wlr] [--spp 16,64] [--prefilter on,off] [--backend gpu|cpu] [--opt KEY=VALUE]...";

fn main() -> mcdenoise::error::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    mcdenoise_tools::require_args(USAGE, 1);
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().expect("checked by require_args"));
    let (mut methods, mut spps, mut pre) =
        ("lp".to_string(), "16,64".to_string(), "on,off".to_string());
    let mut backend = Backend::Gpu;
    let mut extra: Vec<String> = Vec::new();
    while let Some(a) = args.next() {
        let mut v = || args.next().expect("option value");
        match a.as_str() {
            "--methods" => methods = v(),
            "--spp" => spps = v(),
            "--prefilter" => pre = v(),
            "--backend" => {
                backend = match v().as_str() {
                    "cpu" => Backend::Cpu,
                    _ => Backend::Gpu,
                }
            }
            "--opt" => extra.push(v()),
            other => panic!("unknown argument {other}"),
        }
    }
    let ctx = match backend {
        Backend::Gpu => Some(Arc::new(GpuContext::new(&ContextOptions::default())?)),
        _ => None,
    };
    let scenes = discover_scenes(&dir)?;
    let spps: Vec<u32> = spps.split(',').map(|s| s.parse().expect("spp")).collect();
    println!("| method | prefilter | spp | scene | rMSE | err corr |");
    println!("| --- | --- | ---: | --- | ---: | ---: |");
    let mut means: BTreeMap<(String, String, u32), Vec<f64>> = BTreeMap::new();
    for m in methods.split(',') {
        let method = match m {
            "wlr" => Method::Wlr,
            _ => Method::Lp,
        };
        for p in pre.split(',') {
            let opts = extra.clone();
            let prefilter = if p == "off" {
                mcdenoise::Prefilter::Off
            } else {
                mcdenoise::Prefilter::Auto
            };
            for &spp in &spps {
                for sc in &scenes {
                    let Some((_, path)) = sc.inputs.iter().find(|(n, _)| *n == spp) else {
                        continue;
                    };
                    let img = mcdenoise::io::read_stats(path)?;
                    let reference = mcdenoise::io::read_rgb(&sc.reference)?;
                    let mut req = DenoiseRequest::new(method);
                    req.backend = backend;
                    req.error = true;
                    req.options = Options::parse(&opts)?;
                    req.prefilter = prefilter;
                    let out = denoise(ctx.as_ref(), &img, &req)?;
                    let rmse = mcdenoise::metrics::rmse(&out.color, &reference);
                    let corr =
                        error_correlation(out.error.as_ref().unwrap(), &out.color, &reference);
                    println!(
                        "| {m} | {p} | {spp} | {} | {rmse:.5} | {corr:.3} |",
                        sc.name
                    );
                    means
                        .entry((m.to_string(), p.to_string(), spp))
                        .or_default()
                        .push(corr);
                }
            }
        }
    }
    println!();
    println!("| method | prefilter | spp | mean err corr | min err corr |");
    println!("| --- | --- | ---: | ---: | ---: |");
    for ((m, p, spp), v) in &means {
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let min = v.iter().cloned().fold(f64::INFINITY, f64::min);
        println!("| {m} | {p} | {spp} | {mean:.3} | {min:.3} |");
    }
    Ok(())
}
