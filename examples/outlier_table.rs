//! The outlier stage's table (issue #11): for each (statistics, reference)
//! pair given as `STATS=REF` arguments, the input's rMSE and each method's
//! rMSE (WLR, LP, APR) with the stage off and on, with the output's image mean relative to
//! the input's. GPU, f32, prefilter auto. Used by `benches/outliers.sh`.
//!
//!     cargo run --release --example outlier_table -- a.exr=ref.exr ...

use std::path::Path;
use std::sync::Arc;

use mcdenoise::metrics::rmse;
use mcdenoise::{Config, ContextOptions, Denoiser, GpuContext, Method, Outliers, Source};

fn mean(img: &mcdenoise::RgbImage) -> f64 {
    let n = img.planes[0].len() * 3;
    img.planes.iter().flatten().map(|&v| v as f64).sum::<f64>() / n as f64
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    println!("| case | input | wlr off | wlr on | lp off | lp on | apr off | apr on | mean ratio wlr off / on | mean ratio lp off / on | mean ratio apr off / on |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for arg in std::env::args().skip(1) {
        let (s, r) = arg.split_once('=').ok_or("arguments are STATS=REF")?;
        let img = mcdenoise::io::read_stats(Path::new(s))?;
        let reference = mcdenoise::io::read_rgb(Path::new(r))?;
        let input = mcdenoise::colour_of(&img);
        let p = Path::new(s);
        let scene = p.parent().and_then(|d| d.file_name()).unwrap_or_default();
        let mut row = format!(
            "| {}/{} | {:.5} |",
            scene.to_string_lossy(),
            p.file_stem().unwrap().to_string_lossy(),
            rmse(&input, &reference)
        );
        let mut ratios = String::new();
        for m in [Method::Wlr, Method::Lp, Method::Apr] {
            for o in [Outliers::Off, Outliers::On] {
                let mut cfg = Config::new(m);
                cfg.outliers = o;
                let out = Denoiser::new(&ctx, Source::of_image(&img), cfg)?.denoise(&img, None)?;
                row += &format!(" {:.5} |", rmse(&out.color, &reference));
                let ratio = mean(&out.color) / mean(&input);
                ratios += &if o == Outliers::On {
                    format!(" {ratio:.4} |")
                } else {
                    format!(" {ratio:.4} /")
                };
            }
        }
        println!("{row}{ratios}");
    }
    Ok(())
}
