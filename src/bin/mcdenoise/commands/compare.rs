//! `mcdenoise compare`: an image against a reference.

use std::path::PathBuf;

use anyhow::Context;
use mcdenoise::{io, metrics};

use crate::common::{check_error, check_outputs, print_metrics, read_colour};

#[derive(clap::Args)]
pub struct Args {
    image: PathBuf,
    reference: PathBuf,
    /// Write a per-pixel rMSE picture (PNG).
    #[arg(long)]
    heatmap: Option<PathBuf>,
    /// Exit with status 1 if rMSE exceeds this.
    #[arg(long, value_parser = crate::common::parse_max_error)]
    max_error: Option<f64>,
}

pub fn run(a: &Args) -> anyhow::Result<bool> {
    check_outputs(
        a.heatmap.as_deref(),
        &[a.image.as_path(), a.reference.as_path()],
    )?;
    let x = read_colour(&a.image)?;
    let r = read_colour(&a.reference)?;
    let m = metrics::compare(&x, &r)
        .with_context(|| format!("{} vs {}", a.image.display(), a.reference.display()))?;
    print_metrics(&m);
    if let Some(h) = &a.heatmap {
        let map = metrics::rmse_heatmap(&x, &r)?;
        let mut sorted: Vec<f32> = map.iter().copied().filter(|v| v.is_finite()).collect();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let p99 = sorted
            .get(sorted.len() * 99 / 100)
            .copied()
            .unwrap_or(1.0)
            .max(1e-8);
        io::write_heatmap_png(h, x.width, x.height, &map, p99)?;
        eprintln!(
            "heat map: {} (scale 0..{p99:.4}, the 99th percentile)",
            h.display()
        );
    }
    Ok(check_error(m.rmse, a.max_error))
}
