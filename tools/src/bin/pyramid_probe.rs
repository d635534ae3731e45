//! Probe for issue #41's low-frequency residual noise: a method on the
//! statistics and on their 2×2-pooled half-resolution version, and rules
//! that take the low band of the result from the coarse reconstruction.
//!
//! Pooling: the stage's ([`mcdenoise::methods::pyramid::pool_cpu`]: means
//! weighted by the sample counts, variances and the position covariance as
//! `Σ n² v / N²`, counts summed), of the raw statistics. Low band
//! `L(x) = up(down(x))` (2×2 mean, bilinear back). Rules, per pixel:
//! `full`: `f − L(f) + up(c)`; `blend`: the low band mixed by the error
//! estimates, `α = Ê_f↓ / (Ê_f↓ + Ê_c)`, `f − α (L(f) − up(c))`.
//! Reads the uniform statistics and references `method_mix --work DIR`
//! dumped; prints one JSON line per case.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin pyramid_probe -- --work DIR [--method auto] [--stage-only] CASE...
//! ```
//! where CASE is `scene-spp` (the statistics `DIR/scene-spp.exr`, the
//! reference `DIR/scene@spp-WxH-ref.bin`).

use std::path::PathBuf;
use std::sync::Arc;

use clap::Parser;
use mcdenoise::{
    io, metrics, Config, ContextOptions, Denoiser, GpuContext, Layer, Method, RgbImage, Source,
    StatsImage,
};

#[derive(Parser)]
struct Args {
    #[arg(long)]
    work: PathBuf,
    #[arg(long, default_value = "auto")]
    method: String,
    /// Only the method with and without the chain's stage
    /// (`Config::pyramid`), with their image means over the reference's.
    #[arg(long)]
    stage_only: bool,
    cases: Vec<String>,
}

/// 2×2 mean of a full-resolution plane.
fn down(p: &[f32], w: usize, h: usize) -> Vec<f64> {
    let (cw, ch) = (w / 2, h / 2);
    let mut out = vec![0.0; cw * ch];
    for y in 0..ch {
        for x in 0..cw {
            out[y * cw + x] = (p[2 * y * w + 2 * x] as f64
                + p[2 * y * w + 2 * x + 1] as f64
                + p[(2 * y + 1) * w + 2 * x] as f64
                + p[(2 * y + 1) * w + 2 * x + 1] as f64)
                / 4.0;
        }
    }
    out
}

/// Bilinear upsampling of a half-resolution plane (pixel centres aligned).
fn up(p: &[f64], cw: usize, ch: usize, w: usize, h: usize) -> Vec<f64> {
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let fx = ((x as f64 + 0.5) / 2.0 - 0.5).clamp(0.0, (cw - 1) as f64);
            let fy = ((y as f64 + 0.5) / 2.0 - 0.5).clamp(0.0, (ch - 1) as f64);
            let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(cw - 1), (y0 + 1).min(ch - 1));
            let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
            let a = p[y0 * cw + x0] * (1.0 - tx) + p[y0 * cw + x1] * tx;
            let b = p[y1 * cw + x0] * (1.0 - tx) + p[y1 * cw + x1] * tx;
            out[y * w + x] = a * (1.0 - ty) + b * ty;
        }
    }
    out
}

fn run(
    ctx: &Arc<GpuContext>,
    m: Method,
    s: &StatsImage,
    coarse: bool,
) -> anyhow::Result<mcdenoise::Frame> {
    // Each level alone: the stage is what the probe compares.
    let mut c = Config::new(m);
    c.pyramid = mcdenoise::Pyramid::Off;
    if coarse && std::env::var("PYR_COARSE_OUTLIERS").as_deref() == Ok("off") {
        c.outliers = mcdenoise::Outliers::Off;
    }
    let d = Denoiser::new(ctx, Source::of_image(s), c)?;
    Ok(d.denoise(s, None)?)
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let m = Method::from_name(&a.method).ok_or_else(|| anyhow::anyhow!("method"))?;
    for case in &a.cases {
        let stats = io::read_stats(&a.work.join(format!("{case}.exr")))?;
        let (w, h) = (stats.width, stats.height);
        let (scene, spp) = case.rsplit_once('-').unwrap();
        let refp = a.work.join(format!("{scene}@{spp}-{w}x{h}-ref.bin"));
        let vals: Vec<f32> = bytemuck::pod_collect_to_vec(&std::fs::read(&refp)?);
        let r = RgbImage::from_planes(
            w,
            h,
            [
                vals[..w * h].to_vec(),
                vals[w * h..2 * w * h].to_vec(),
                vals[2 * w * h..].to_vec(),
            ],
        );
        let fine = run(&ctx, m, &stats, false)?;
        // The chain's stage (Config::pyramid), which implements "rblend".
        let mut sc = Config::new(m);
        sc.pyramid = mcdenoise::Pyramid::On;
        let staged = Denoiser::new(&ctx, Source::of_image(&stats), sc)?.denoise(&stats, None)?;
        let (cw, ch) = (w / 2, h / 2);
        let mut line = serde_json::Map::new();
        line.insert("case".into(), case.clone().into());
        line.insert("fine".into(), metrics::rmse(&fine.color, &r).into());
        line.insert("stage".into(), metrics::rmse(&staged.color, &r).into());
        if a.stage_only {
            let mean = |i: &RgbImage| {
                i.planes
                    .iter()
                    .flat_map(|p| p.iter())
                    .map(|&v| v as f64)
                    .sum::<f64>()
            };
            line.insert("mean_fine".into(), (mean(&fine.color) / mean(&r)).into());
            line.insert("mean_stage".into(), (mean(&staged.color) / mean(&r)).into());
            println!("{}", serde_json::Value::Object(line));
            continue;
        }
        let coarse_stats = mcdenoise::methods::pyramid::pool_cpu(&stats);
        let coarse = run(&ctx, m, &coarse_stats, true)?;
        // Per channel, at full resolution: the fine output's low band, the
        // coarse output, the fine error pooled, the coarse error, the pooled
        // input variance.
        let up_half = |p: &[f32]| {
            up(
                &p.iter().map(|&v| v as f64).collect::<Vec<_>>(),
                cw,
                ch,
                w,
                h,
            )
        };
        let coarse_var = coarse_stats.get(Layer::ColorVariance).unwrap();
        let bands: Vec<[Vec<f64>; 5]> = (0..3)
            .map(|c| {
                [
                    up(&down(&fine.color.planes[c], w, h), cw, ch, w, h),
                    up_half(&coarse.color.planes[c]),
                    up(&down(&fine.error.planes[c], w, h), cw, ch, w, h),
                    up_half(&coarse.error.planes[c]),
                    up_half(&coarse_var[c]),
                ]
            })
            .collect();
        for rule in [
            "full", "blend", "blend2", "clamp1", "clamp2", "clamp3", "vfull1", "vfull2", "vblend1",
            "vblend2", "ratio", "rblend", "rgate2", "rgate3", "rgate5",
        ] {
            let mut img = fine.color.clone();
            for c in 0..3 {
                let f = &fine.color.planes[c];
                let [lf, cu, ef, ec, vc] = &bands[c];
                for i in 0..w * h {
                    let alpha = match rule {
                        "full" => 1.0,
                        "blend2" => (ef[i] * ef[i]) / (ef[i] * ef[i] + ec[i] * ec[i]).max(1e-60),
                        r if r.starts_with("vfull") => 1.0,
                        _ => ef[i] / (ef[i] + ec[i]).max(1e-30),
                    };
                    let mut d = lf[i] - cu[i];
                    if let Some(t) = rule.strip_prefix("clamp") {
                        let t: f64 = t.parse().unwrap();
                        let lim = t * (ef[i] + ec[i]).max(0.0).sqrt();
                        d = d.clamp(-lim, lim);
                    }
                    if let Some(t) = rule.strip_prefix("vfull").or(rule.strip_prefix("vblend")) {
                        let t: f64 = t.parse().unwrap();
                        let lim = t * vc[i].max(0.0).sqrt();
                        d = d.clamp(-lim, lim);
                    }
                    img.planes[c][i] = (f[i] as f64 - alpha * d).max(0.0) as f32;
                    if rule.starts_with('r') {
                        // The low band corrected as a ratio: a bright
                        // neighbour's share does not spill into dark pixels.
                        let ratio = (cu[i].max(0.0) + 1e-3) / (lf[i].max(0.0) + 1e-3);
                        let mut a = if rule == "ratio" {
                            1.0
                        } else {
                            ef[i] / (ef[i] + ec[i]).max(1e-30)
                        };
                        // A gap between the two low bands far beyond what
                        // their estimated errors allow is bias, not noise.
                        if let Some(k) = rule.strip_prefix("rgate") {
                            let k: f64 = k.parse().unwrap();
                            let gap = (cu[i] - lf[i]).powi(2);
                            let allowed = k * k * (ef[i] + ec[i]).max(0.0);
                            if gap > allowed {
                                a *= allowed / gap;
                            }
                        }
                        img.planes[c][i] = (f[i] as f64 * (1.0 - a + a * ratio)).max(0.0) as f32;
                    }
                    if std::env::var("PYR_DEBUG").as_deref() == Ok(rule) {
                        let rv = r.planes[c][i] as f64;
                        let e = (img.planes[c][i] as f64 - rv).powi(2) / (rv * rv + 0.01);
                        if e > 100.0 {
                            eprintln!("{case} px {i} ch {c}: out {} fine {} ref {rv} lf {} cu {} vc {} ef {} ec {}", img.planes[c][i], f[i], lf[i], cu[i], vc[i], ef[i], ec[i]);
                        }
                    }
                }
            }
            line.insert(rule.into(), metrics::rmse(&img, &r).into());
        }
        println!("{}", serde_json::Value::Object(line));
    }
    Ok(())
}
