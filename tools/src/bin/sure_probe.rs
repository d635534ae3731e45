//! Probe: how well does Stein's unbiased risk estimate, with the divergence
//! from one random perturbation (Monte-Carlo SURE), estimate a method's
//! true rMSE, against the method's own estimate?
//!
//! For statistics `y` (colour means, variances `v`), a method `F`:
//! `SURE = mean_i w_i [(F(y)_i − y_i)² − v_i + 2 v_i b_i (F(y + ε σ b)_i − F(y)_i) / (ε σ_i)]`
//! with `σ_i = √v_i`, `b` random ±1 per pixel and channel, `w_i = 1/(F(y)_i² + 0.01)`.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin sure_probe -- STATS.exr REF1.exr [REF2.exr] [--methods wlr,lp] [--eps 0.01]
//! ```

use std::sync::Arc;

use anyhow::Context;
use mcdenoise::{
    io, metrics, Config, ContextOptions, Denoiser, GpuContext, Layer, Method, RgbImage, Source,
    StatsImage,
};

fn denoise(
    ctx: &Arc<GpuContext>,
    img: &StatsImage,
    m: Method,
) -> anyhow::Result<(RgbImage, RgbImage)> {
    let mut c = Config::new(m);
    c.low_spp = mcdenoise::has_low_spp(img);
    let d = Denoiser::new(ctx, Source::of_image(img), c)?;
    let r = d.denoise(img, None)?;
    Ok((r.color, r.error))
}

fn hash(mut x: u64) -> u64 {
    x ^= x >> 33;
    x = x.wrapping_mul(0xff51afd7ed558ccd);
    x ^= x >> 33;
    x = x.wrapping_mul(0xc4ceb9fe1a85ec53);
    x ^ (x >> 33)
}

const USAGE: &str =
    "usage: sure_probe STATS.exr REF1.exr [REF2.exr] [--methods wlr,lp] [--eps 0.01]";

fn main() -> anyhow::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    mcdenoise_tools::require_args(USAGE, 2);
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut files = Vec::new();
    let mut methods = vec![Method::Wlr, Method::Lp, Method::Apr, Method::Aos];
    let mut eps = 0.01f64;
    let mut i = 0;
    while i < args.len() {
        match args[i].as_str() {
            "--methods" => {
                methods = args[i + 1]
                    .split(',')
                    .map(|n| Method::from_name(n).context("method"))
                    .collect::<anyhow::Result<_>>()?;
                i += 1;
            }
            "--eps" => {
                eps = args[i + 1].parse()?;
                i += 1;
            }
            f => files.push(f.to_string()),
        }
        i += 1;
    }
    let y = io::read_stats(std::path::Path::new(&files[0]))?;
    let refs: Vec<RgbImage> = files[1..]
        .iter()
        .map(|f| io::read_rgb(std::path::Path::new(f)))
        .collect::<Result<_, _>>()?;
    let r = if refs.len() == 2 {
        let p = std::array::from_fn(|c| {
            refs[0].planes[c]
                .iter()
                .zip(&refs[1].planes[c])
                .map(|(a, b)| 0.5 * (a + b))
                .collect()
        });
        RgbImage::from_planes(y.width, y.height, p)
    } else {
        refs[0].clone()
    };
    let ref_err = if refs.len() == 2 {
        metrics::rmse(&refs[0], &r)
    } else {
        0.0
    };
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let n = y.width * y.height;
    let col = y.get(Layer::Color).context("color")?.to_vec();
    let var = y.get(Layer::ColorVariance).context("variance")?.to_vec();
    // The perturbed input: colour + ε σ b.
    let mut yp = y.clone();
    let mut b = vec![vec![0.0f32; n]; 3];
    {
        let pc = yp.get_mut(Layer::Color).unwrap();
        for c in 0..3 {
            for i in 0..n {
                let s = if hash((c * n + i) as u64 + 12345) & 1 == 0 {
                    1.0
                } else {
                    -1.0
                };
                b[c][i] = s;
                pc[c][i] += (eps * (var[c][i].max(0.0) as f64).sqrt() * s as f64) as f32;
            }
        }
    }
    // A second input with noise of the input's own variance added:
    // y + √v g, g ~ N(0, 1) (Box-Muller on the hash).
    let mut yb = y.clone();
    {
        let pc = yb.get_mut(Layer::Color).unwrap();
        for c in 0..3 {
            for i in 0..n {
                let h = hash((c * n + i) as u64 + 999);
                let u1 = ((h >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
                let u2 = (hash(h) >> 11) as f64 / (1u64 << 53) as f64;
                let g = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                pc[c][i] += ((var[c][i].max(0.0) as f64).sqrt() * g) as f32;
            }
        }
    }
    println!("reference error (mean of two) {ref_err:.2e}");
    println!("method  true      own est   SURE      boot      own/true  SURE/true boot/true (fit term, div term)");
    for &m in &methods {
        let (f, e) = denoise(&ctx, &y, m)?;
        let (fp, _) = denoise(&ctx, &yp, m)?;
        let (fb, _) = denoise(&ctx, &yb, m)?;
        let boot = metrics::rmse(&fb, &f);
        let truth = metrics::rmse(&f, &r) - ref_err;
        let own = metrics::estimated_rmse(&f, &e);
        let (mut fit, mut div, mut cnt) = (0.0f64, 0.0f64, 0usize);
        for c in 0..3 {
            for i in 0..n {
                let (fi, yi, vi) = (
                    f.planes[c][i] as f64,
                    col[c][i] as f64,
                    var[c][i].max(0.0) as f64,
                );
                let w = 1.0 / (fi * fi + 0.01);
                let s = vi.sqrt();
                let d = if s > 0.0 {
                    b[c][i] as f64 * (fp.planes[c][i] as f64 - fi) / (eps * s)
                } else {
                    0.0
                };
                let t_fit = w * ((fi - yi).powi(2) - vi);
                let t_div = w * 2.0 * vi * d;
                if (t_fit + t_div).is_finite() {
                    fit += t_fit;
                    div += t_div;
                    cnt += 1;
                }
            }
        }
        let sure = (fit + div) / cnt as f64;
        println!(
            "{:<6} {truth:.6} {own:.6} {sure:.6} {boot:.6} {:8.2} {:9.2} {:9.2}  ({:.6}, {:.6})",
            m.name(),
            own / truth,
            sure / truth,
            boot / truth,
            fit / cnt as f64,
            div / cnt as f64
        );
    }
    Ok(())
}
