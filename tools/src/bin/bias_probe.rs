//! Signed error by sample count: for a statistics file, its reference and
//! any outputs, the energy ratio `Σo / Σr` and the relative squared error,
//! over the image and per class of the pixel's count over the image's mean.
//! Usage: `cargo run --release -p mcdenoise-tools --bin bias_probe -- stats.exr ref.exr[,ref2.exr ...] [out.exr ...]`
use anyhow::Context;
use mcdenoise::image::Layer;

const USAGE: &str = "usage: bias_probe stats.exr ref.exr[,ref2.exr ...] [out.exr ...]";
const EDGES: [f64; 7] = [0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0];

fn main() -> anyhow::Result<()> {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return Ok(());
    }
    mcdenoise_tools::require_args(USAGE, 2);
    let a: Vec<String> = std::env::args().collect();
    let img = mcdenoise::io::read_stats(std::path::Path::new(&a[1]))?;
    // The reference: the mean of comma-separated renders.
    let refs: Vec<_> = a[2]
        .split(',')
        .map(|p| mcdenoise::io::read_rgb(std::path::Path::new(p)))
        .collect::<Result<_, _>>()?;
    let mut rf = refs[0].clone();
    for c in 0..3 {
        for i in 0..rf.planes[c].len() {
            rf.planes[c][i] =
                refs.iter().map(|r| r.planes[c][i] as f64).sum::<f64>() as f32 / refs.len() as f32;
        }
    }
    let spp = &img.get(Layer::Spp).context("no spp layer")?[0];
    let mean_n = spp.iter().map(|&v| v as f64).sum::<f64>() / spp.len() as f64;
    let class = |i: usize| -> usize {
        let q = spp[i] as f64 / mean_n;
        EDGES.iter().rposition(|&e| q >= e).unwrap_or(0)
    };
    let mut rows: Vec<(String, [Vec<f32>; 3])> =
        vec![("input".into(), mcdenoise::colour_of(&img).planes)];
    for p in &a[3..] {
        rows.push((
            p.clone(),
            mcdenoise::io::read_rgb(std::path::Path::new(p))?.planes,
        ));
    }
    let npx = spp.len();
    println!("mean count {mean_n:.2}");
    for (name, o) in &rows {
        let mut so = [0.0f64; EDGES.len()];
        let mut sr = [0.0f64; EDGES.len()];
        let mut se = [0.0f64; EDGES.len()];
        let mut cnt = [0usize; EDGES.len()];
        for i in 0..npx {
            let k = class(i);
            cnt[k] += 1;
            for c in 0..3 {
                let (ov, rv) = (o[c][i] as f64, rf.planes[c][i] as f64);
                so[k] += ov;
                sr[k] += rv;
                se[k] += (ov - rv).powi(2) / (rv * rv + 0.01);
            }
        }
        let tot_e: f64 = se.iter().sum();
        // The same output scaled to the reference's energy: what a global
        // bias costs.
        let g = sr.iter().sum::<f64>() / so.iter().sum::<f64>();
        let mut sg = 0.0f64;
        for i in 0..npx {
            for c in 0..3 {
                let (ov, rv) = (o[c][i] as f64 * g, rf.planes[c][i] as f64);
                sg += (ov - rv).powi(2) / (rv * rv + 0.01);
            }
        }
        println!(
            "  scaled by {g:.4}: rel. sq. error {:.6}",
            sg / (3 * npx) as f64
        );
        println!(
            "{name}: energy {:.4}, rel. sq. error {:.6}",
            so.iter().sum::<f64>() / sr.iter().sum::<f64>(),
            tot_e / (3 * npx) as f64
        );
        for k in 0..EDGES.len() {
            if cnt[k] == 0 {
                continue;
            }
            println!(
                "  count/mean >= {:.2}: {:6} px, energy {:.4}, error per px {:.6}, share {:.3}",
                EDGES[k],
                cnt[k],
                so[k] / sr[k],
                se[k] / (3 * cnt[k]) as f64,
                se[k] / tot_e
            );
        }
    }
    Ok(())
}
