//! Developer probe for LP on one input: centre fraction per pass, the r_opt
//! histogram and the mean coverage (CPU twins), then with `gpu` the GPU time
//! of every dispatch (warm run).
//!
//! `cargo run --release -p mcdenoise-tools --bin lp_stats -- scene/spp16.exr [reference.exr] [gpu]`
//! (with a reference: the tiles of largest estimated and actual error).

use mcdenoise::gpu::{ContextOptions, GpuContext};
use mcdenoise::methods::{denoise, lp, prepare, DenoiseRequest, Method};
use mcdenoise::options::Options;

const USAGE: &str = "usage: lp_stats IN.exr [reference.exr] [gpu]";

fn main() -> mcdenoise::error::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    mcdenoise_tools::require_args(USAGE, 1);
    let path = std::env::args().nth(1).expect("checked by require_args");
    let img = mcdenoise::io::read_stats(std::path::Path::new(&path))?;
    let (clean, _) = prepare::prepare_cpu(&img);
    let r = lp::run_cpu(&clean, lp::LpParams::new(&Options::default())?, false)?;
    let n = r.centre_pass.len() as f64;
    println!(
        "centres: {:.2}% of {} pixels",
        100.0 * r.centre_fraction(),
        n
    );
    for pass in 1..=5 {
        let c = r.centre_pass.iter().filter(|&&p| p == pass as f32).count();
        println!("  pass {pass}: {c}");
    }
    let mut hist = [0usize; 10];
    for &v in r.r_opt.iter().filter(|&&v| v >= 0.0) {
        hist[v as usize] += 1;
    }
    println!("r_opt histogram: {hist:?}");
    let mut kh = [0usize; 10];
    for &v in r.rank.iter().filter(|&&v| v >= 0.0) {
        kh[v as usize] += 1;
    }
    println!("rank histogram: {kh:?}");
    let cov: f64 = r.coverage.iter().map(|&c| c as f64).sum::<f64>() / n;
    let max = r.coverage.iter().cloned().fold(0.0f32, f32::max);
    println!("mean coverage {cov:.2}, max {max}");
    let zero = r.error.planes[1].iter().filter(|&&e| e == 0.0).count();
    println!(
        "error estimate exactly 0 (clamped) at {:.1}% of pixels",
        100.0 * zero as f64 / n
    );
    if let Some(refp) = std::env::args().nth(2).filter(|a| a.ends_with(".exr")) {
        // The tiles with the largest estimated error, and their actual error.
        use mcdenoise::bench::{tile_means, CORRELATION_TILE};
        let reference = mcdenoise::io::read_rgb(std::path::Path::new(&refp))?;
        let (w, h) = (r.color.width, r.color.height);
        let est = tile_means(w, h, CORRELATION_TILE, |i| {
            r.error.planes.iter().map(|p| p[i] as f64).sum::<f64>() / 3.0
        });
        let act = tile_means(w, h, CORRELATION_TILE, |i| {
            (0..3)
                .map(|c| (r.color.planes[c][i] as f64 - reference.planes[c][i] as f64).powi(2))
                .sum::<f64>()
                / 3.0
        });
        let mut idx: Vec<usize> = (0..est.len()).collect();
        idx.sort_by(|&a, &b| est[b].total_cmp(&est[a]));
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        println!(
            "tiles: mean estimate {:.3e}, mean actual {:.3e}",
            mean(&est),
            mean(&act)
        );
        for &t in idx.iter().take(6) {
            println!("  tile {t}: estimate {:.3e}, actual {:.3e}", est[t], act[t]);
        }
        idx.sort_by(|&a, &b| act[b].total_cmp(&act[a]));
        for &t in idx.iter().take(4) {
            println!(
                "  worst actual tile {t}: estimate {:.3e}, actual {:.3e}",
                est[t], act[t]
            );
        }
    }
    if std::env::args().any(|a| a == "gpu") {
        let ctx = std::sync::Arc::new(GpuContext::new(&ContextOptions::default())?);
        let req = DenoiseRequest::new(Method::Lp);
        denoise(Some(&ctx), &img, &req)?;
        let out = denoise(Some(&ctx), &img, &req)?;
        for t in &out.timings {
            println!(
                "{:<12} rows {:>4}..{:<4} {:8.2} ms",
                t.kernel,
                t.rows.0,
                t.rows.1,
                t.nanoseconds / 1e6
            );
        }
    }
    Ok(())
}
