//! Which APR blocks accept a pixel, and what each predicts there for the
//! orders 0..3 (CPU reference, raw features, default kernel, stage-1 order
//! from (y, v)); with a reference image, first the 25 brightest input pixels
//! within 20 of it with their variance and reference value. Usage:
//! `cargo run --release -p mcdenoise-tools --bin apr_probe -- stats.exr X Y [channel [ref.exr]]`.
use mcdenoise::image::Layer;
use mcdenoise::reference::apr as r;
const USAGE: &str = "usage: apr_probe stats.exr X Y [channel [ref.exr]]";

fn main() {
    if mcdenoise_tools::asked_for_help(USAGE) {
        return;
    }
    mcdenoise_tools::require_args(USAGE, 3);
    let a: Vec<String> = std::env::args().collect();
    let stats = mcdenoise::io::read_stats(std::path::Path::new(&a[1])).unwrap();
    let (x, yy): (usize, usize) = (a[2].parse().unwrap(), a[3].parse().unwrap());
    let ch: usize = a.get(4).map(|s| s.parse().unwrap()).unwrap_or(0);
    let (w, h) = (stats.width, stats.height);
    let i = yy * w + x;
    let y: Vec<f64> = stats.get(Layer::Color).unwrap()[ch]
        .iter()
        .map(|&v| v as f64)
        .collect();
    let v: Vec<f64> = stats.get(Layer::ColorVariance).unwrap()[ch]
        .iter()
        .map(|&v| v as f64)
        .collect();
    let valid = vec![true; w * h];
    let (feats, _) = mcdenoise::methods::apr::features(&stats).unwrap();
    let scales = r::test_scales(&stats.get(Layer::Spp).unwrap()[0], true);
    let pl = r::Planes {
        w,
        h,
        y: &y,
        v: &v,
        feats: &feats,
        valid: &valid,
        test_scale: Some(&scales),
    };
    if a.get(5).is_some() {
        let rf = mcdenoise::io::read_rgb(std::path::Path::new(&a[5])).unwrap();
        for qy in (yy.saturating_sub(16)..(yy + 17).min(h)).step_by(2) {
            let row: Vec<String> = (x.saturating_sub(16)..(x + 17).min(w))
                .step_by(2)
                .map(|qx| format!("{:5.1}/{:4.1}", y[qy * w + qx], rf.planes[ch][qy * w + qx]))
                .collect();
            println!("{qy:3} {}", row.join(" "));
        }
    }
    if let Some(rp) = a.get(5) {
        let rf = mcdenoise::io::read_rgb(std::path::Path::new(rp)).unwrap();
        let mut top: Vec<usize> = (yy.saturating_sub(20)..(yy + 21).min(h))
            .flat_map(|qy| (x.saturating_sub(20)..(x + 21).min(w)).map(move |qx| qy * w + qx))
            .collect();
        top.sort_by(|p, q| y[*q].partial_cmp(&y[*p]).unwrap());
        for &q in top.iter().take(25) {
            println!(
                "({:3},{:3}) y {:9.3} v {:10.3} ref {:8.3}",
                q % w,
                q / w,
                y[q],
                v[q],
                rf.planes[ch][q]
            );
        }
    }
    println!("pixel ({x},{yy}) y {:.4} v {:.5}", y[i], v[i]);
    for c in r::covering(w, h, i, &valid) {
        let d = r::design(&pl, r::BLOCK, c);
        let acc = d.idx.binary_search(&i).is_ok();
        let fit = r::choose(&d, &pl, &y, &v);
        let row = d.row(&pl, i);
        let preds: Vec<f64> = (0..4)
            .map(|k| {
                let b = r::beta(&d, k, &y);
                r::eval(&row[..d.p[k].min(b.len())], &b)
            })
            .collect();
        println!("centre ({:3},{:3}) y_c {:8.4} v_c {:9.4} |A| {:4} acc {} K {} xi {:9.4} w {:.3} pred {:?}",
            c % w, c / w, y[c], v[c], d.idx.len(), acc, fit.order, fit.xi, d.weight(w, i),
            preds.iter().map(|p| format!("{p:.3}")).collect::<Vec<_>>());
    }
}
