//! `mcdenoise demo`: the built-in example, a 64×64 crop of a public 16-spp
//! scene and its reference compiled into the binary
//! (`tests/fixtures/dof_checker_64_*.exr`), denoised with WLR.

use std::path::PathBuf;

use anyhow::Context;
use mcdenoise::{colour_of, has_low_spp, io, metrics, Config, Denoiser, Method, Source};

use crate::common::{context, print_report};
use crate::Cli;

const INPUT: &[u8] = include_bytes!("../../../../tests/fixtures/dof_checker_64_spp16.exr");
const REFERENCE: &[u8] = include_bytes!("../../../../tests/fixtures/dof_checker_64_ref.exr");

#[derive(clap::Args)]
pub struct Args {
    /// Folder for the example's files and outputs.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
}

pub fn run(cli: &Cli, a: &Args) -> anyhow::Result<bool> {
    let out = &a.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let input = out.join("input.exr");
    let reference = out.join("reference.exr");
    std::fs::write(&input, INPUT).with_context(|| input.display().to_string())?;
    std::fs::write(&reference, REFERENCE).with_context(|| reference.display().to_string())?;
    let img = io::read_stats(&input)?;
    println!("{}", io::format_report(&input, &img).trim_end());
    println!();
    let ctx = context(cli)?;
    println!("device: {}", ctx.info().name);
    let r = io::read_rgb(&reference)?;
    let input_metrics = metrics::compare(&colour_of(&img), &r)?;
    let mut config = Config::new(Method::Wlr);
    config.debug = true;
    config.low_spp = has_low_spp(&img);
    let denoiser = Denoiser::new(&ctx, Source::of_image(&img), config)?;
    let t0 = std::time::Instant::now();
    let result = denoiser.denoise(&img, None)?;
    let secs = t0.elapsed().as_secs_f64();
    print_report(&result.report, &input);
    let output = out.join("output.exr");
    let preview = out.join("output.png");
    io::write_output(
        &output,
        &io::OutputImage {
            color: result.color.clone(),
            error: Some(result.error.clone()),
            samples: None,
            debug: result.debug.clone(),
        },
    )?;
    io::write_png_preview(&preview, &result.color)?;
    io::write_png_preview(&out.join("input.png"), &colour_of(&img))?;
    println!(
        "WLR on the GPU in {secs:.2} s (the first run on lavapipe also compiles the kernels) -> {} (color, error, debug layers), {}",
        output.display(),
        preview.display()
    );
    let gpu_ms: f64 = result.timings.iter().map(|t| t.nanoseconds).sum::<f64>() / 1e6;
    for (k, ns, n) in mcdenoise::timings_per_kernel(&result.timings) {
        println!("  {k:<18} {:>9.1} ms  ({n} dispatches)", ns / 1e6);
    }
    println!("  {:<18} {gpu_ms:>9.1} ms", "total GPU");
    let m = metrics::compare(&result.color, &r)?;
    println!("\nagainst {}:          input     WLR", reference.display());
    println!(
        "  rMSE            {:>9.5} {:>9.5}",
        input_metrics.rmse, m.rmse
    );
    println!(
        "  relMSE          {:>9.5} {:>9.5}",
        input_metrics.relmse, m.relmse
    );
    println!(
        "  PSNR (dB)       {:>9.2} {:>9.2}",
        input_metrics.psnr, m.psnr
    );
    println!(
        "  SSIM            {:>9.4} {:>9.4}",
        input_metrics.ssim, m.ssim
    );
    Ok(true)
}
