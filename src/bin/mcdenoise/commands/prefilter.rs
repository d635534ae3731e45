//! `mcdenoise prefilter`: statistics with G-buffer-prefiltered features
//! (spec §0.4, §6), for other denoisers.

use std::path::PathBuf;

use anyhow::Context;
use mcdenoise::{has_low_spp, io, Config, Denoiser, Method, Options, Prefilter, Source};

use crate::args::PrecisionArg;
use crate::common::{check_outputs, context, print_report};
use crate::Cli;

#[derive(clap::Args)]
pub struct Args {
    input: PathBuf,
    /// Output render-statistics EXR.
    #[arg(short, long)]
    output: PathBuf,
    /// Kernel arithmetic on the GPU.
    #[arg(long, value_enum, default_value = "f32")]
    precision: PrecisionArg,
    /// Device memory cap in MB: an image whose chain needs more is
    /// prefiltered in tiles that fit, each with the halo the windows
    /// need; the output is bit-identical to a whole run. Default: three
    /// quarters of the device's largest local heap.
    #[arg(long, value_name = "MB", value_parser = clap::value_parser!(u64).range(1..))]
    max_memory: Option<u64>,
    /// Prefilter in tiles of at most N×N pixels (plus halo) even when the
    /// whole image fits.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    tile: Option<u64>,
    /// Option key=value (repeatable), e.g. `gbf.second_below=0` for the
    /// spec's single filter pass; see `mcdenoise denoise --help`.
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
}

pub fn run(cli: &Cli, a: &Args) -> anyhow::Result<bool> {
    check_outputs([a.output.as_path()], &[&a.input])?;
    let img = crate::common::read_stats(&a.input)?;
    let mut config = Config::new(Method::None);
    config.prefilter = Prefilter::On;
    config.precision = a.precision.get();
    config.low_spp = has_low_spp(&img);
    config.max_memory = a.max_memory.map(|mb| mb.saturating_mul(1 << 20));
    config.tile = a.tile.map(|t| t as usize);
    config.options = Options::parse(&a.opts)?;
    crate::common::warn_unused_method_options(&config.options, &[]);
    let denoiser = Denoiser::new(&context(cli)?, Source::of_image(&img), config)
        .with_context(|| a.input.display().to_string())?;
    // Tiled when the image does not fit one chain: the statistics then come
    // from the tiles' interiors.
    let (result, stats) = denoiser.denoise_with_statistics(&img, None)?;
    drop(img);
    if !cli.quiet {
        print_report(&result.report, &a.input);
    }
    io::write_stats(&a.output, &stats)?;
    if !cli.quiet {
        eprintln!(
            "{}: sanitised statistics with G-buffer-prefiltered normal, albedo and depth",
            a.output.display()
        );
    }
    Ok(true)
}
