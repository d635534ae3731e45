//! Crops a render-statistics EXR and its reference into small test fixtures,
//! with the crate's own reader and writers (so a fixture round-trips exactly).
//!
//! Usage: make_fixture <input.exr> <reference.exr> <x0> <y0> <w> <h> <out_stats.exr> <out_ref.exr>
//!
//! The committed fixtures `tests/fixtures/dof_checker_64_spp16.exr` and
//! `tests/fixtures/dof_checker_64_ref.exr` (the right half of the in-focus blue
//! sphere's silhouette against the sky, the sharp checker floor below it and
//! the defocused yellow sphere behind) were made from the crate root with:
//!
//! ```text
//! cargo run -p mcdenoise-tools --bin make_fixture -- \
//!     ../shared/data/scenes/dof_checker/spp16.exr \
//!     ../shared/data/scenes/dof_checker/reference.exr \
//!     120 104 64 64 \
//!     tests/fixtures/dof_checker_64_spp16.exr \
//!     tests/fixtures/dof_checker_64_ref.exr
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context};
use mcdenoise::io::{read_rgb, read_stats, write_rgb, write_stats};

fn run() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 8 {
        bail!("{USAGE}");
    }
    let number = |i: usize, what: &str| -> anyhow::Result<usize> {
        args[i]
            .parse()
            .with_context(|| format!("{what} must be a non-negative integer, got {:?}", args[i]))
    };
    let (x0, y0, w, h) = (
        number(2, "x0")?,
        number(3, "y0")?,
        number(4, "w")?,
        number(5, "h")?,
    );
    let (input, reference) = (PathBuf::from(&args[0]), PathBuf::from(&args[1]));
    let (out_stats, out_ref) = (PathBuf::from(&args[6]), PathBuf::from(&args[7]));

    let stats = read_stats(&input)?;
    let color = read_rgb(&reference)?;
    if (stats.width, stats.height) != (color.width, color.height) {
        bail!(
            "{} is {}x{} but {} is {}x{}",
            input.display(),
            stats.width,
            stats.height,
            reference.display(),
            color.width,
            color.height
        );
    }
    if w == 0 || h == 0 || x0 + w > stats.width || y0 + h > stats.height {
        bail!(
            "crop {w}x{h} at ({x0}, {y0}) does not fit in the {}x{} image",
            stats.width,
            stats.height
        );
    }
    write_stats(&out_stats, &stats.crop(x0, y0, w, h))?;
    write_rgb(&out_ref, &color.crop(x0, y0, w, h))?;
    for path in [&out_stats, &out_ref] {
        let bytes = std::fs::metadata(path)?.len();
        println!("wrote {} ({bytes} bytes)", path.display());
    }
    Ok(())
}

const USAGE: &str = "usage: make_fixture <input.exr> <reference.exr> <x0> <y0> <w> <h> <out_stats.exr> <out_ref.exr>";

fn main() -> ExitCode {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return ExitCode::SUCCESS;
    }
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("make_fixture: {e:#}");
            ExitCode::FAILURE
        }
    }
}
