//! `mcdenoise inspect`: a render-statistics file's layers and ranges.

use std::path::PathBuf;

use mcdenoise::io;

#[derive(clap::Args)]
pub struct Args {
    file: PathBuf,
}

pub fn run(a: &Args) -> anyhow::Result<bool> {
    let img = io::read_stats(&a.file)?;
    println!("{}", io::format_report(&a.file, &img).trim_end());
    Ok(true)
}
