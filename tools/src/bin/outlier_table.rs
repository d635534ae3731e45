//! The outlier stage's table (issue #11): for each (statistics, reference)
//! pair given as `STATS=REF` arguments, the input's rMSE and each method's
//! rMSE (WLR, LP, APR, AOS, or those of `--methods a,b`) with the stage off
//! and on, with the output's image mean relative to the input's. GPU, f32,
//! prefilter auto. Used by `benches/outliers.sh`.
//!
//!     cargo run --release -p mcdenoise-tools --bin outlier_table -- [--methods wlr,lp] a.exr=ref.exr ...

use std::path::Path;
use std::sync::Arc;

use mcdenoise::metrics::rmse;
use mcdenoise::{Config, ContextOptions, Denoiser, GpuContext, Method, Outliers, Source};

fn mean(img: &mcdenoise::RgbImage) -> f64 {
    let n = img.planes[0].len() * 3;
    img.planes.iter().flatten().map(|&v| v as f64).sum::<f64>() / n as f64
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut methods = vec![Method::Wlr, Method::Lp, Method::Apr, Method::Aos];
    if args.first().is_some_and(|a| a == "--methods") {
        let list = args.get(1).ok_or("--methods needs a list")?.clone();
        let all = [Method::Wlr, Method::Lp, Method::Apr, Method::Aos];
        methods = list
            .split(',')
            .map(|m| {
                all.into_iter()
                    .find(|a| a.name() == m)
                    .ok_or(format!("--methods: unknown method {m}"))
            })
            .collect::<Result<_, _>>()?;
        args.drain(..2);
    }
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let names: Vec<&str> = methods.iter().map(|m| m.name()).collect();
    let mut head = String::from("| case | input |");
    for n in &names {
        head += &format!(" {n} off | {n} on |");
    }
    for n in &names {
        head += &format!(" mean ratio {n} off / on |");
    }
    println!("{head}");
    println!("|{}", "---|".repeat(2 + 3 * names.len()));
    for arg in args {
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
        for &m in &methods {
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
