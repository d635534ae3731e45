//! The adaptive loop (WLR's maps, its schedule) run by hand through the
//! facade on host statistics, so that what the maps see can be changed:
//! `plain` hands each pass's WLR the statistics as they are; `medvar`
//! replaces each pixel's colour variance of the mean by the median over
//! its 5×5 window of the per-sample variances (`vbar·n`), over its own
//! count — the map no longer follows one pixel's rare bright sample;
//! `loovar:R` the mean over the `(2R+1)²` window without the pixel itself,
//! `loo:R` the same for the colour mean too; `checker` makes each
//! checkerboard colour's counts from a map of the image whose pixels of
//! that colour hold their four neighbours' statistics, so no pixel's
//! count reads its own samples (two reconstructions per pass).
//! The final statistics are written as they are; with a second output,
//! also with each pass's mean weighed by the pass's share of the budget
//! instead of the pixel's count in it (MAP-DEPENDENCE); `first:out.exr`
//! weighs only the uniform first pass by its share and pools the map
//! passes by count.
//!
//! `cargo run --release -p mcdenoise-tools --bin map_loop -- SCENE SIZE SPP SEED MODE out.exr [[first:]weighted.exr]`
use std::sync::Arc;

use mcdenoise::gpu::GpuBuffer;
use mcdenoise::render::{Renderer, Samples, Scene};
use mcdenoise::{
    Batch, Config, ContextOptions, Denoiser, GpuContext, InputBlend, Layer, Method, Pass,
    Precision, Pyramid, Schedule, Source, StatsImage, Validation,
};

const USAGE: &str =
    "usage: map_loop SCENE SIZE SPP SEED plain|medvar[:R]|loovar[:R]|loo[:R]|checker out.exr [[first:]weighted.exr]";

/// What each pass's map sees (the module's comment).
#[derive(Clone, Copy)]
enum Mode {
    Plain,
    Medvar(usize),
    /// The window's radius; whether the colour mean is replaced too.
    Loo(usize, bool),
    Checker,
}

fn medvar(img: &mut StatsImage, radius: usize) {
    let (w, h) = (img.width, img.height);
    let n: Vec<f32> = img.get(Layer::Spp).unwrap()[0].clone();
    let planes = img.get_mut(Layer::ColorVariance).unwrap();
    for p in planes.iter_mut() {
        let per_sample: Vec<f32> = p.iter().zip(&n).map(|(v, &c)| v * c.max(1.0)).collect();
        let mut win = Vec::with_capacity((2 * radius + 1).pow(2));
        for y in 0..h {
            for x in 0..w {
                win.clear();
                for qy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
                    for qx in x.saturating_sub(radius)..(x + radius + 1).min(w) {
                        if n[qy * w + qx] >= 1.0 {
                            win.push(per_sample[qy * w + qx]);
                        }
                    }
                }
                if win.is_empty() {
                    continue;
                }
                win.sort_by(f32::total_cmp);
                let i = y * w + x;
                p[i] = win[win.len() / 2] / n[i].max(1.0);
            }
        }
    }
}

/// Each pixel that `pick` gives neighbours (inside the image) gets, in
/// `layers`, their mean: of the colour means, of the per-sample variances
/// (`vbar·n`) over its own count. The neighbours' values are read before
/// any is replaced.
fn neighbour_means(
    img: &mut StatsImage,
    layers: &[Layer],
    pick: impl Fn(usize, usize) -> Option<Vec<(usize, usize)>>,
) {
    let (w, h) = (img.width, img.height);
    let n: Vec<f32> = img.get(Layer::Spp).unwrap()[0].clone();
    for &layer in layers {
        let per_sample = layer == Layer::ColorVariance;
        for p in img.get_mut(layer).unwrap().iter_mut() {
            let src: Vec<f64> = p
                .iter()
                .zip(&n)
                .map(|(&v, &c)| v as f64 * if per_sample { c.max(1.0) as f64 } else { 1.0 })
                .collect();
            for y in 0..h {
                for x in 0..w {
                    let Some(nb) = pick(x, y) else { continue };
                    let vals: Vec<f64> = nb
                        .into_iter()
                        .filter(|&(qx, qy)| qx < w && qy < h && n[qy * w + qx] >= 1.0)
                        .map(|(qx, qy)| src[qy * w + qx])
                        .collect();
                    if !vals.is_empty() {
                        let i = y * w + x;
                        let m = vals.iter().sum::<f64>() / vals.len() as f64;
                        let own = if per_sample {
                            n[i].max(1.0) as f64
                        } else {
                            1.0
                        };
                        p[i] = (m / own) as f32;
                    }
                }
            }
        }
    }
}

/// Each pixel's colour variance of the mean replaced by the mean over its
/// `(2r+1)²` window, itself left out, of the per-sample variances; with
/// `colour`, its colour mean too: the map at a pixel no longer reads the
/// pixel's own samples directly.
fn loo(img: &mut StatsImage, radius: usize, colour: bool) {
    let layers: &[Layer] = if colour {
        &[Layer::ColorVariance, Layer::Color]
    } else {
        &[Layer::ColorVariance]
    };
    neighbour_means(img, layers, |x, y| {
        let (x0, y0) = (x.saturating_sub(radius), y.saturating_sub(radius));
        Some(
            (y0..=y + radius)
                .flat_map(|qy| (x0..=x + radius).map(move |qx| (qx, qy)))
                .filter(|&q| q != (x, y))
                .collect(),
        )
    });
}

/// `img` with the pixels of one colour of a checkerboard (`(x + y) % 2 ==
/// parity`) given the mean colour and per-sample variance of their four
/// edge neighbours (of the other colour), over their own count: a map from
/// it reads none of those pixels' samples.
fn checker(img: &StatsImage, parity: usize) -> StatsImage {
    let mut out = img.clone();
    neighbour_means(&mut out, &[Layer::ColorVariance, Layer::Color], |x, y| {
        ((x + y) % 2 == parity).then(|| {
            vec![
                (x.wrapping_sub(1), y),
                (x + 1, y),
                (x, y.wrapping_sub(1)),
                (x, y + 1),
            ]
        })
    });
    out
}

fn main() -> anyhow::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 7 && a.len() != 8 {
        anyhow::bail!("{USAGE}");
    }
    let scene = Scene::by_name_or_file(&a[1])?;
    let size: usize = a[2].parse()?;
    let spp: u32 = a[3].parse()?;
    let seed: u64 = a[4].parse()?;
    let mut parts = a[5].splitn(2, ':');
    let name = parts.next().unwrap_or_default();
    let mut radius = || parts.next().map_or(Ok(2), str::parse::<usize>);
    let mode = match name {
        "plain" => Mode::Plain,
        "medvar" => Mode::Medvar(radius()?),
        "loovar" => Mode::Loo(radius()?, false),
        "loo" => Mode::Loo(radius()?, true),
        "checker" => Mode::Checker,
        m => anyhow::bail!("mode {m}"),
    };
    let ctx = Arc::new(GpuContext::new(&ContextOptions {
        device: None,
        validation: Validation::Off,
        ..Default::default()
    })?);
    let r = Renderer::new(&ctx, &scene, size, size, seed)?;
    // The schedule of WLR's loop (§9.3).
    let s = Schedule::for_method(Method::Wlr, spp, size * size)?;
    let mut b = Batch::new(&ctx)?;
    r.record_pass(&mut b, Samples::Uniform(s.initial_spp))?;
    b.finish()?;
    let l = r.layout();
    // Per pass: (Σx of R G B, count), from the accumulation's differences.
    let mut passes: Vec<([Vec<f64>; 3], Vec<f64>)> = Vec::new();
    let mut before: Option<Vec<Vec<f32>>> = None;
    let mut take_pass = |planes: Vec<Vec<f32>>| {
        let diff = |k: usize| -> Vec<f64> {
            planes[k]
                .iter()
                .enumerate()
                .map(|(i, &v)| v as f64 - before.as_ref().map_or(0.0, |b| b[k][i] as f64))
                .collect()
        };
        passes.push((
            [
                diff(l.sum_plane(0)),
                diff(l.sum_plane(1)),
                diff(l.sum_plane(2)),
            ],
            diff(l.count_plane()),
        ));
        before = Some(planes);
    };
    take_pass(r.download()?);
    let mut c = Config::new(Method::Wlr);
    c.pass = Pass::Intermediate;
    c.pyramid = Pyramid::Off;
    c.input_blend = InputBlend::Off;
    let mut bufs = Vec::new();
    for &budget in &s.budgets {
        let mut img = r.statistics_at(Precision::F32)?;
        let map_of = |im: &StatsImage| -> anyhow::Result<Vec<u32>> {
            let d = Denoiser::new(&ctx, Source::of_image(im), c.clone())?;
            Ok(d.denoise(im, Some(budget))?.samples.expect("a sample map"))
        };
        let counts = match mode {
            Mode::Checker => {
                // Each colour's counts from the map of the image whose
                // pixels of that colour hold their neighbours' statistics.
                let parts = [map_of(&checker(&img, 0))?, map_of(&checker(&img, 1))?];
                (0..size * size)
                    .map(|i| parts[((i % size) + (i / size)) % 2][i])
                    .collect()
            }
            Mode::Medvar(rad) => {
                medvar(&mut img, rad);
                map_of(&img)?
            }
            Mode::Loo(rad, colour) => {
                loo(&mut img, rad, colour);
                map_of(&img)?
            }
            Mode::Plain => map_of(&img)?,
        };
        let budget: u32 = counts.iter().sum();
        bufs.push(GpuBuffer::from_slice(&ctx, "loop.map", &counts)?);
        let mut b = Batch::new(&ctx)?;
        r.record_pass(
            &mut b,
            Samples::Map {
                map: bufs.last().unwrap().slice(),
                total: budget,
            },
        )?;
        b.finish()?;
        take_pass(r.download()?);
    }
    let stats = r.statistics_at(Precision::F32)?;
    mcdenoise::io::write_stats(std::path::Path::new(&a[6]), &stats)?;
    if let Some(out) = a.get(7) {
        // Each group of passes' mean weighed by the group's share of the
        // budget, not by the pixel's count in it (which depends on the
        // earlier passes' samples); groups without a sample at a pixel give
        // their share to the others. A group is one pass, or with `first:`
        // the uniform first pass and the map passes together. The variance
        // of the mean scales accordingly.
        let (first_only, out) = match out.strip_prefix("first:") {
            Some(o) => (true, o),
            None => (false, out.as_str()),
        };
        let group = |p: usize| if first_only { p.min(1) } else { p };
        let groups = group(passes.len() - 1) + 1;
        let mut budgets = vec![0.0f64; groups];
        budgets[0] = (s.initial_spp as usize * size * size) as f64;
        for (p, &b) in s.budgets.iter().enumerate() {
            budgets[group(p + 1)] += b as f64;
        }
        let mut img = stats.clone();
        let n_all = img.get(Layer::Spp).unwrap()[0].clone();
        for c in 0..3 {
            let var = img.get(Layer::ColorVariance).unwrap()[c].clone();
            let mut col = img.get(Layer::Color).unwrap()[c].clone();
            let mut v_out = var.clone();
            for i in 0..size * size {
                let mut sum = vec![0.0f64; groups];
                let mut cnt = vec![0.0f64; groups];
                for (p, (sums, counts)) in passes.iter().enumerate() {
                    sum[group(p)] += sums[c][i];
                    cnt[group(p)] += counts[i].round();
                }
                let (mut wsum, mut m, mut w2n) = (0.0, 0.0, 0.0);
                for g in 0..groups {
                    if cnt[g] >= 1.0 {
                        wsum += budgets[g];
                        m += budgets[g] * sum[g] / cnt[g];
                        w2n += budgets[g] * budgets[g] / cnt[g];
                    }
                }
                if wsum > 0.0 {
                    col[i] = (m / wsum) as f32;
                    // var = s²/n_all; the estimator's is s² Σ w_g²/n_g.
                    v_out[i] = (var[i] as f64 * n_all[i] as f64 * w2n / (wsum * wsum)) as f32;
                }
            }
            img.get_mut(Layer::Color).unwrap()[c] = col;
            img.get_mut(Layer::ColorVariance).unwrap()[c] = v_out;
        }
        mcdenoise::io::write_stats(std::path::Path::new(out), &img)?;
    }
    Ok(())
}
