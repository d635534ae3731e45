//! Prints LP's centre statistics on one input (CPU twins): centre fraction
//! per pass, the r_opt histogram and the mean coverage.
//!
//! `cargo run --release --example lp_stats -- scene/spp16.exr`

use mcdenoise::methods::{lp, prepare};
use mcdenoise::options::Options;

fn main() -> mcdenoise::error::Result<()> {
    let path = std::env::args().nth(1).expect("usage: lp_stats IN.exr");
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
    let cov: f64 = r.coverage.iter().map(|&c| c as f64).sum::<f64>() / n;
    let max = r.coverage.iter().cloned().fold(0.0f32, f32::max);
    println!("mean coverage {cov:.2}, max {max}");
    Ok(())
}
