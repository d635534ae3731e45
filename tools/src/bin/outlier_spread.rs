//! Experiment (issue #11, `docs/outliers.md`): other windows for the
//! outlier stage's step 4. For each `STATS=REF` pair and method: steps 1–3
//! on the CPU (`remove_cpu` on the sanitised statistics), the method on the
//! GPU with the stage off on the cleaned statistics, then step 4 in f64 with
//! several windows, each scored by rMSE against REF, beside the shipped
//! stage off and on (`off`, `GPU on`):
//! - `spec`: 87×87 around each outlier, ∝ ŷ (the shipped step 4; equals
//!   `GPU on` to the digits printed);
//! - `whole`: the whole image, ∝ ŷ;
//! - `near/F×k`: a half-width of k times the Chebyshev distance to the
//!   nearest other outlier whose grey excess is at least 1/F of this one's
//!   (never below 43; the whole image if there is none), ∝ ŷ. The pairs
//!   `F:k` come from `SPREAD_VARIANTS` (default `1:1,2:1,4:1`).
//!
//! ```text
//! SPREAD_VARIANTS=1:1,1:4 cargo run --release -p mcdenoise-tools --bin outlier_spread -- \
//!     [--methods wlr,apr] a.exr=ref.exr ...
//! ```

use std::path::Path;
use std::sync::Arc;

use mcdenoise::methods::outliers::{remove_cpu, Detection, Removed};
use mcdenoise::metrics::rmse;
use mcdenoise::{
    Config, ContextOptions, Denoiser, GpuContext, Layer, Method, Outliers, RgbImage, Source,
};

const SPEC_R: usize = 43;

/// Step 4 with a square window of half-width `r[o]` per outlier, ∝ ŷ
/// over the window's valid pixels (uniform when dark), unclamped then
/// clamped at 0 as the stage does.
fn restore(
    w: usize,
    h: usize,
    spp: &[f32],
    rem: &Removed,
    r: &[usize],
    yhat: &RgbImage,
) -> RgbImage {
    let n = w * h;
    let valid: Vec<f64> = spp
        .iter()
        .map(|&s| if s >= 1.0 { 1.0 } else { 0.0 })
        .collect();
    // Summed-area tables of ŷ and validity.
    let sat = |v: &dyn Fn(usize) -> f64| {
        let mut t = vec![0.0f64; (w + 1) * (h + 1)];
        for y in 0..h {
            for x in 0..w {
                t[(y + 1) * (w + 1) + x + 1] =
                    v(y * w + x) + t[y * (w + 1) + x + 1] + t[(y + 1) * (w + 1) + x]
                        - t[y * (w + 1) + x];
            }
        }
        t
    };
    let rect = |t: &[f64], x0: usize, y0: usize, x1: usize, y1: usize| {
        t[(y1 + 1) * (w + 1) + x1 + 1] - t[y0 * (w + 1) + x1 + 1] - t[(y1 + 1) * (w + 1) + x0]
            + t[y0 * (w + 1) + x0]
    };
    let tv = sat(&|i| valid[i]);
    let mut out = yhat.clone();
    for ch in 0..3 {
        let ty = sat(&|i| valid[i] * yhat.planes[ch][i] as f64);
        // Difference arrays of rho (multiplicative) and add (uniform).
        let mut drho = vec![0.0f64; (w + 1) * (h + 1)];
        let mut dadd = vec![0.0f64; (w + 1) * (h + 1)];
        for o in (0..n).filter(|&o| rem.mask[o]) {
            let (x, y) = (o % w, o / w);
            let (x0, y0) = (x.saturating_sub(r[o]), y.saturating_sub(r[o]));
            let (x1, y1) = ((x + r[o]).min(w - 1), (y + r[o]).min(h - 1));
            let cnt = rect(&tv, x0, y0, x1, y1);
            if cnt == 0.0 {
                continue;
            }
            let s = rect(&ty, x0, y0, x1, y1);
            let e = rem.excess[ch][o];
            let (d, v) = if s <= 1e-6 * cnt {
                (&mut dadd, e / cnt)
            } else {
                (&mut drho, e / s)
            };
            d[y0 * (w + 1) + x0] += v;
            d[y0 * (w + 1) + x1 + 1] -= v;
            d[(y1 + 1) * (w + 1) + x0] -= v;
            d[(y1 + 1) * (w + 1) + x1 + 1] += v;
        }
        for t in [&mut drho, &mut dadd] {
            for y in 0..=h {
                for x in 0..=w {
                    let mut v = t[y * (w + 1) + x];
                    if x > 0 {
                        v += t[y * (w + 1) + x - 1];
                    }
                    if y > 0 {
                        v += t[(y - 1) * (w + 1) + x];
                    }
                    if x > 0 && y > 0 {
                        v -= t[(y - 1) * (w + 1) + x - 1];
                    }
                    t[y * (w + 1) + x] = v;
                }
            }
        }
        for i in 0..n {
            if valid[i] == 0.0 {
                continue;
            }
            let k = (i / w) * (w + 1) + i % w;
            let y = yhat.planes[ch][i] as f64 * (1.0 + drho[k]) + dadd[k];
            out.planes[ch][i] = y.max(0.0) as f32;
        }
    }
    out
}

/// Half-widths: k times the distance to the nearest other outlier with
/// grey excess >= 1/f of this one's, at least SPEC_R, the image if none.
fn near(w: usize, h: usize, rem: &Removed, f: f64, k: usize) -> Vec<usize> {
    let os: Vec<usize> = (0..w * h).filter(|&o| rem.mask[o]).collect();
    let g = |o: usize| (rem.excess[0][o] + rem.excess[1][o] + rem.excess[2][o]) / 3.0;
    let mut r = vec![SPEC_R; w * h];
    for &o in &os {
        let (x, y) = ((o % w) as i64, (o / w) as i64);
        let mut best = i64::MAX;
        for &q in &os {
            if q != o && g(q) * f >= g(o) {
                let d = ((q % w) as i64 - x).abs().max(((q / w) as i64 - y).abs());
                best = best.min(d);
            }
        }
        r[o] = if best == i64::MAX {
            w.max(h)
        } else {
            (k * best as usize).max(SPEC_R)
        };
    }
    r
}

const USAGE: &str =
    "usage: [SPREAD_VARIANTS=F:k,...] outlier_spread [--methods wlr,apr] STATS.exr=REF.exr ...";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut methods = vec![Method::Wlr, Method::Lp, Method::Apr, Method::Aos];
    if args.first().is_some_and(|a| a == "--methods") {
        let list = args[1].clone();
        methods = list
            .split(',')
            .map(|m| {
                methods
                    .iter()
                    .copied()
                    .find(|a| a.name() == m)
                    .expect("method")
            })
            .collect();
        args.drain(..2);
    }
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let fs: Vec<(f64, usize)> = std::env::var("SPREAD_VARIANTS")
        .unwrap_or("1:1,2:1,4:1".into())
        .split(',')
        .map(|v| {
            let (f, k) = v.split_once(':').unwrap();
            (f.parse().unwrap(), k.parse().unwrap())
        })
        .collect();
    println!(
        "| case | method | off | GPU on | spec | whole | {} |",
        fs.iter()
            .map(|(f, k)| format!("near/{f}×{k}"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|---|---|---|---|---|---|{}", "---|".repeat(fs.len()));
    for arg in args {
        let (s, rpath) = arg.split_once('=').ok_or("arguments are STATS=REF")?;
        let img = mcdenoise::io::read_stats(Path::new(s))?;
        let reference = mcdenoise::io::read_rgb(Path::new(rpath))?;
        let (mut clean, _) = mcdenoise::methods::prepare::prepare_cpu(&img);
        let rem = remove_cpu(&mut clean, Detection::of(&mcdenoise::Options::default())?);
        let (w, h) = (img.width, img.height);
        let spp = clean.get(Layer::Spp).unwrap()[0].clone();
        let p = Path::new(s);
        let case = format!(
            "{}/{}",
            p.parent()
                .and_then(|d| d.file_name())
                .unwrap_or_default()
                .to_string_lossy(),
            p.file_stem().unwrap().to_string_lossy()
        );
        for &m in &methods {
            let run = |im: &mcdenoise::StatsImage,
                       o: Outliers|
             -> Result<RgbImage, Box<dyn std::error::Error>> {
                let mut cfg = Config::new(m);
                cfg.outliers = o;
                Ok(Denoiser::new(&ctx, Source::of_image(im), cfg)?
                    .denoise(im, None)?
                    .color)
            };
            let off = run(&img, Outliers::Off)?;
            let on = run(&img, Outliers::On)?;
            let yhat = run(&clean, Outliers::Off)?;
            let spec = restore(w, h, &spp, &rem, &vec![SPEC_R; w * h], &yhat);
            let whole = restore(w, h, &spp, &rem, &vec![w.max(h); w * h], &yhat);
            let mut row = format!(
                "| {case} | {} | {:.5} | {:.5} | {:.5} | {:.5} |",
                m.name(),
                rmse(&off, &reference),
                rmse(&on, &reference),
                rmse(&spec, &reference),
                rmse(&whole, &reference)
            );
            for &(f, k) in &fs {
                let r = near(w, h, &rem, f, k);
                row += &format!(
                    " {:.5} |",
                    rmse(&restore(w, h, &spp, &rem, &r, &yhat), &reference)
                );
            }
            println!("{row}");
        }
    }
    Ok(())
}
