//! Developer probe: how much would cleaner features help a method? Denoises
//! the colour of one file with the feature layers (and their variances) of
//! another (e.g. the same scene at 4x the spp), on the CPU twins, and prints
//! the rMSE against a reference for both.
//!
//! `cargo run --release -p mcdenoise-tools --bin feature_swap -- colour.exr features.exr reference.exr [wlr|lp]`

use mcdenoise::image::Layer;
use mcdenoise::methods::{denoise, Backend, DenoiseRequest, Method};

const USAGE: &str = "usage: feature_swap colour.exr features.exr reference.exr [wlr|lp]";

fn main() -> mcdenoise::error::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    mcdenoise_tools::require_args(USAGE, 3);
    let a: Vec<String> = std::env::args().collect();
    let p = |i: usize| std::path::PathBuf::from(&a[i]);
    let colour = mcdenoise::io::read_stats(&p(1))?;
    let feats = mcdenoise::io::read_stats(&p(2))?;
    let reference = mcdenoise::io::read_rgb(&p(3))?;
    let method = match a.get(4).map(|s| s.as_str()) {
        Some("lp") => Method::Lp,
        _ => Method::Wlr,
    };
    let mut swapped = colour.clone();
    for l in [
        Layer::Normal,
        Layer::NormalVariance,
        Layer::Albedo,
        Layer::AlbedoVariance,
        Layer::Depth,
        Layer::DepthVariance,
    ] {
        if let Some(v) = feats.get(l) {
            swapped.set(l, v.to_vec());
        }
    }
    let mut req = DenoiseRequest::new(method);
    req.backend = Backend::Cpu;
    for (what, img) in [("own features", &colour), ("swapped features", &swapped)] {
        let out = denoise(None, img, &req)?;
        let m = mcdenoise::metrics::compare(&out.color, &reference)?;
        println!("{what}: rMSE {:.5}", m.rmse);
    }
    // The G-buffer prefilter (spec §6) on the file's own features.
    let (mut clean, _) = mcdenoise::methods::prepare::prepare_cpu(&colour);
    let maps = mcdenoise::methods::gbf::run_cpu(
        &mut clean,
        mcdenoise::methods::gbf::GbfSettings::new(&req.options, req.method, req.pass)?,
    )?;
    let mean = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
    println!(
        "gbf: mean h_opt {:.3}, mean hbar {:.3}",
        mean(&maps.h_opt),
        mean(&maps.hbar)
    );
    let color = match method {
        Method::Lp => {
            mcdenoise::methods::lp::run_cpu(
                &clean,
                mcdenoise::methods::lp::LpParams::new(&Default::default())?,
                false,
            )?
            .color
        }
        _ => {
            mcdenoise::methods::wlr::run_cpu(
                &clean,
                mcdenoise::methods::wlr::WlrParams::new(
                    mcdenoise::methods::Pass::Final,
                    &Default::default(),
                )?,
            )?
            .color
        }
    };
    let m = mcdenoise::metrics::compare(&color, &reference)?;
    println!("gbf-prefiltered features: rMSE {:.5}", m.rmse);
    Ok(())
}
