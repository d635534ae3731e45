//! Lists the worst pixels of an APR run on a statistics file against a
//! reference: the pixel, its spp, input and output colour, reference, and
//! the debug layers (order of its block, extra-centre mask). Usage:
//! `cargo run --release -p mcdenoise-tools --bin apr_worst -- stats.exr out.exr ref.exr`.
use mcdenoise::image::Layer;
const USAGE: &str = "usage: apr_worst stats.exr out.exr ref.exr";

fn main() {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return;
    }
    mcdenoise_tools::require_args(USAGE, 3);
    let a: Vec<String> = std::env::args().collect();
    let stats = mcdenoise::io::read_stats(std::path::Path::new(&a[1])).unwrap();
    let out = mcdenoise::io::read_rgb(std::path::Path::new(&a[2])).unwrap();
    let reference = mcdenoise::io::read_rgb(std::path::Path::new(&a[3])).unwrap();
    let n = stats.width * stats.height;
    let col = stats.get(Layer::Color).unwrap();
    let var = stats.get(Layer::ColorVariance).unwrap();
    let spp = &stats.get(Layer::Spp).unwrap()[0];
    let mut e: Vec<(f64, usize)> = (0..n)
        .map(|i| {
            let d = (0..3)
                .map(|c| {
                    let r = reference.planes[c][i] as f64;
                    let o = out.planes[c][i] as f64;
                    (o - r).powi(2) / (r * r + 1e-2)
                })
                .sum::<f64>();
            (d, i)
        })
        .collect();
    e.sort_by(|x, y| y.0.partial_cmp(&x.0).unwrap());
    let total: f64 = e.iter().map(|x| x.0).sum();
    println!("total {total:.3}");
    for &(d, i) in e.iter().take(15) {
        println!(
            "({:3},{:3}) err {:8.3} spp {:6} in {:9.4} var {:9.4} out {:9.4} ref {:9.4}",
            i % stats.width,
            i / stats.width,
            d,
            spp[i],
            col[0][i],
            var[0][i],
            out.planes[0][i],
            reference.planes[0][i]
        );
    }
}
