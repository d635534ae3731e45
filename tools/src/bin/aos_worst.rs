//! The pixels where AOS (CPU path, defaults) adds the most squared error
//! over its input, with what AOS decided there: input, output, reference,
//! `vbar`, chosen order (0: the input), rank, MSE, biases and variances;
//! and what share of a 12-spp sample map each chosen order gets.
//! Usage: `cargo run --release -p mcdenoise-tools --bin aos_worst -- stats.exr ref.exr [N [KEY=VALUE ...]]`
//! (the trailing arguments are `--opt` options).
use anyhow::Context;
use mcdenoise::image::Layer;
use mcdenoise::{Config, Denoiser, Method, Source};

const USAGE: &str = "usage: aos_worst stats.exr ref.exr [N [KEY=VALUE ...]]";

fn main() -> anyhow::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    let a: Vec<String> = std::env::args().collect();
    if a.len() < 3 {
        anyhow::bail!("{USAGE}");
    }
    let img = mcdenoise::io::read_stats(std::path::Path::new(&a[1]))?;
    let rf = mcdenoise::io::read_rgb(std::path::Path::new(&a[2]))?;
    let n: usize = match a.get(3) {
        Some(s) => s.parse().with_context(|| format!("N: {s}"))?,
        None => 20,
    };
    let mut cfg = Config::new(Method::Aos);
    cfg.debug = true;
    let opts: Vec<&str> = a.iter().skip(4).map(|s| s.as_str()).collect();
    cfg.options = mcdenoise::options::Options::parse(&opts)?;
    let f = Denoiser::new_cpu(Source::of_image(&img), cfg)?
        .denoise(&img, Some(12 * (img.width * img.height) as u32))?;
    let input = mcdenoise::colour_of(&img);
    let var = img
        .get(Layer::ColorVariance)
        .context("the statistics have no colour variance")?;
    let dbg = |name: &str| -> &Vec<f32> {
        &f.debug
            .iter()
            .find(|(k, _)| k == name)
            .unwrap_or_else(|| panic!("no {name}"))
            .1
    };
    let w = img.width;
    let se = |im: &[Vec<f32>], i: usize| -> f64 {
        (0..3)
            .map(|c| {
                let r = rf.planes[c][i] as f64;
                let d = im[c][i] as f64 - r;
                d * d / (r * r + 1e-2)
            })
            .sum::<f64>()
            / 3.0
    };
    let total_in: f64 = (0..w * img.height).map(|i| se(&input.planes, i)).sum();
    let total_out: f64 = (0..w * img.height).map(|i| se(&f.color.planes, i)).sum();
    println!("relative squared error summed: input {total_in:.3}, AOS {total_out:.3}");
    // The sample map for 12 more samples per pixel on average: what share
    // each chosen order (0: the input) gets.
    let samples = f.samples.as_ref().context("AOS returned no sample map")?;
    let total: f64 = samples.iter().map(|&s| s as f64).sum();
    for o in [0.0f32, 1.0, 3.0] {
        let px: Vec<usize> = (0..w * img.height)
            .filter(|&i| dbg("aos_order")[i] == o)
            .collect();
        let share: f64 = px.iter().map(|&i| samples[i] as f64).sum::<f64>() / total;
        println!(
            "order {o}: {:.1} % of the pixels, {:.1} % of the next pass's samples",
            100.0 * px.len() as f64 / (w * img.height) as f64,
            100.0 * share
        );
    }
    let mut idx: Vec<usize> = (0..w * img.height).collect();
    let gain = |i: usize| se(&f.color.planes, i) - se(&input.planes, i);
    idx.sort_by(|p, q| gain(*q).total_cmp(&gain(*p)));
    let top: f64 = idx.iter().take(n).map(|&i| gain(i)).sum();
    println!("the {n} worst pixels add {top:.3}");
    for &i in idx.iter().take(n) {
        let vb = (var[0][i] + var[1][i] + var[2][i]) / 3.0;
        println!(
            "({:3},{:3}) in {:8.3} out {:8.3} ref {:8.3} vbar {:9.3e} order {} rank {} mse {:9.3e} b1 {:9.2e} v1 {:9.2e} b3 {:9.2e} v3 {:9.2e} sd1 {:9.2e}",
            i % w,
            i / w,
            input.planes[0][i],
            f.color.planes[0][i],
            rf.planes[0][i],
            vb,
            dbg("aos_order")[i],
            dbg("aos_rank")[i],
            f.error.planes[0][i],
            dbg("aos_bias1")[i],
            dbg("aos_var1")[i],
            dbg("aos_bias3")[i],
            dbg("aos_var3")[i],
            dbg("aos_bias_sd1")[i],
        );
    }
    Ok(())
}
