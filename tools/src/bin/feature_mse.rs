//! Feature MSE of render statistics against a reference's (issue #10): per
//! feature layer (normal, albedo, depth), the mean squared difference of the
//! per-pixel means over the pixels valid in both, for each statistics file
//! given after the reference. Used by `benches/prefilter_features.sh`.
//!
//!     cargo run --release -p mcdenoise-tools --bin feature_mse -- REF.exr A.exr [B.exr ...]

use std::path::Path;

use mcdenoise::Layer;

const USAGE: &str = "usage: feature_mse REF.exr A.exr [B.exr ...]";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (rf, rest) = args.split_first().ok_or(USAGE)?;
    let reference = mcdenoise::io::read_stats(Path::new(rf))?;
    for a in rest {
        let img = mcdenoise::io::read_stats(Path::new(a))?;
        if (img.width, img.height) != (reference.width, reference.height) {
            return Err(format!("{a}: size differs from {rf}").into());
        }
        let spp = |s: &mcdenoise::StatsImage, i: usize| s.get(Layer::Spp).unwrap()[0][i];
        let mut row = Vec::new();
        for l in [Layer::Normal, Layer::Albedo, Layer::Depth] {
            let (p, q) = (
                img.get(l).ok_or("missing layer")?,
                reference.get(l).ok_or("missing layer")?,
            );
            let (mut s, mut n) = (0.0f64, 0usize);
            for c in 0..p.len() {
                for i in 0..img.pixel_count() {
                    if spp(&img, i) >= 1.0 && spp(&reference, i) >= 1.0 {
                        s += (p[c][i] as f64 - q[c][i] as f64).powi(2);
                        n += 1;
                    }
                }
            }
            row.push(format!("{}={:.3e}", l.name(), s / n.max(1) as f64));
        }
        println!("{a}: {}", row.join(" "));
    }
    Ok(())
}
