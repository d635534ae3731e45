//! Developer probe: GPU time of `wlr_fit` and `wlr_final` (timestamps of
//! `run_planes`) and, with `cpu`, the twins' time and the fraction of pixels
//! within the §0.3 tolerance. `wlr_final` gets `hbar` from the twin's
//! `gauss_smooth` of the GPU's `h_opt` on both sides.
//!
//! `cargo run --release --example wlr_time -- [size] [radius] [f32|f64] [cpu]`
//! Environment: `SCENE=<stats.exr>` (cropped/tiled to size), `FIXTURE=1`
//! (the committed fixture, tiled), `DETAIL=1` (worst λ1 mismatches),
//! `TSVD=1` (also time tsvd_debug), `FLOPS=<n>` (band size, per-band times).
use std::sync::Arc;
use std::time::Instant;

use mcdenoise::gpu::*;
use mcdenoise::kernels::{gauss_smooth, run_planes, wlr_final, wlr_fit};
use mcdenoise::reference;
use mcdenoise::shared::{SmoothPush, WlrPush, WLR_DEFAULT_OPTIONS};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545F4914F6CDD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let u1 = self.next().max(1e-300);
        let u2 = self.next();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// 7 features, 7 variances, 3 colours, vbar, spp.
fn scene(w: usize, h: usize) -> Vec<Vec<f32>> {
    let mut rng = Rng(77);
    let n = w * h;
    let mut p = vec![vec![0.0f32; n]; 19];
    for i in 0..n {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        let (cx, cy, rad) = (w as f64 * 0.5, h as f64 * 0.5, 0.3 * w.max(h) as f64);
        let r2 = ((x - cx).powi(2) + (y - cy).powi(2)) / rad.powi(2);
        let inside = r2 < 1.0;
        let (nx, ny, nz, d) = if inside {
            let nz = (1.0 - r2).sqrt();
            ((x - cx) / rad, (y - cy) / rad, nz, 3.0 - nz)
        } else {
            (0.0, 1.0, 0.0, 5.0 + 0.05 * y)
        };
        let alb = if (x as usize / 8 + y as usize / 8) % 2 == 0 {
            0.8
        } else {
            0.2
        };
        let base = [nx, ny, nz, d, alb, alb * 0.9, alb * 0.5];
        let noise = [0.02, 0.02, 0.02, 0.05, 0.01, 0.01, 0.01];
        for k in 0..7 {
            p[k][i] = (base[k] + noise[k] * rng.normal()) as f32;
            p[7 + k][i] = (noise[k] * noise[k]) as f32;
        }
        let shade = if inside {
            0.3 + 0.7 * nz
        } else {
            0.5 + 0.3 * (0.1 * x).sin()
        };
        let sd = 0.05;
        let mut vb = 0.0;
        for ch in 0..3 {
            let f = shade * base[4 + ch];
            p[14 + ch][i] = (f + sd * rng.normal()) as f32;
            vb += sd * sd / 3.0;
        }
        p[17][i] = vb as f32;
        p[18][i] = 16.0;
    }
    p
}

/// A statistics EXR, sanitised, cropped or tiled to w x h.
fn exr_planes(path: &str, w: usize, h: usize) -> Vec<Vec<f32>> {
    use mcdenoise::image::Layer;
    let img = mcdenoise::io::read_stats(std::path::Path::new(path)).unwrap();
    let (img, _) = mcdenoise::methods::prepare::prepare_cpu(&img);
    let get = |l: Layer| img.get(l).unwrap().to_vec();
    let mut src = Vec::new();
    for l in [
        Layer::Normal,
        Layer::Depth,
        Layer::Albedo,
        Layer::NormalVariance,
        Layer::DepthVariance,
        Layer::AlbedoVariance,
        Layer::Color,
    ] {
        src.extend(get(l));
    }
    let cv = get(Layer::ColorVariance);
    src.push(
        (0..cv[0].len())
            .map(|i| (cv[0][i] + cv[1][i] + cv[2][i]) / 3.0)
            .collect(),
    );
    src.extend(get(Layer::Spp));
    let (sw, sh) = (img.width, img.height);
    src.iter()
        .map(|p| {
            (0..w * h)
                .map(|i| p[((i / w) % sh) * sw + (i % w) % sw])
                .collect()
        })
        .collect()
}

fn frac_close(g: &[f32], c: &[f32]) -> f64 {
    g.iter()
        .zip(c)
        .filter(|(g, c)| ((**g - **c).abs() as f64) <= 1e-3 * ((**c as f64).abs() + 1e-3))
        .count() as f64
        / g.len() as f64
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(64);
    let radius: u32 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(5);
    let prec = match args.get(3).map(|s| s.as_str()) {
        Some("f64") => Precision::F64,
        _ => Precision::F32,
    };
    let cpu = args.get(4).is_some_and(|s| s == "cpu");
    let (w, h) = (size, size);
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default()).unwrap());
    let planes = if let Ok(path) = std::env::var("SCENE") {
        exr_planes(&path, w, h)
    } else if std::env::var("FIXTURE").is_ok() {
        exr_planes("tests/fixtures/dof_checker_64_spp16.exr", w, h)
    } else {
        scene(w, h)
    };
    let inputs: Vec<&[f32]> = planes.iter().map(|p| p.as_slice()).collect();
    let push = WlrPush {
        width: w as u32,
        height: h as u32,
        radius,
        options: WLR_DEFAULT_OPTIONS,
        ..Default::default()
    };
    let t = Instant::now();
    let (fit, tim) = run_planes(
        &ctx,
        &wlr_fit::DECL,
        prec,
        bytemuck::bytes_of(&push),
        w,
        h,
        &inputs,
        &[w * h; 8],
        std::env::var("FLOPS")
            .map(|v| v.parse().unwrap())
            .unwrap_or(wlr_fit::flops_per_pixel(radius)),
    )
    .unwrap();
    let gpu_fit: f64 = tim.iter().map(|t| t.nanoseconds).sum::<f64>() / 1e9;
    if std::env::var("FLOPS").is_ok() {
        for t in &tim {
            println!("  band {:?}: {:.3} s", t.rows, t.nanoseconds / 1e9);
        }
    }
    println!(
        "wlr_fit{} {w}x{h} R={radius}: GPU {gpu_fit:.3} s (wall {:.3} s)",
        prec.suffix(),
        t.elapsed().as_secs_f64()
    );
    let sp = SmoothPush {
        width: w as u32,
        height: h as u32,
        radius: gauss_smooth::radius(1.0),
        sigma: 1.0,
        ..Default::default()
    };
    let mut hbar = vec![0.0f32; w * h];
    reference::gauss_smooth::gauss_smooth(&sp, &fit[0], &planes[18], &mut hbar);
    let mut fin_in = inputs.clone();
    fin_in.push(&hbar);
    for j in 1..5 {
        fin_in.push(&fit[j]);
    }
    let t = Instant::now();
    let (fin, tim) = run_planes(
        &ctx,
        &wlr_final::DECL,
        prec,
        bytemuck::bytes_of(&push),
        w,
        h,
        &fin_in,
        &[w * h; 5],
        wlr_final::flops_per_pixel(radius),
    )
    .unwrap();
    let gpu_fin: f64 = tim.iter().map(|t| t.nanoseconds).sum::<f64>() / 1e9;
    println!(
        "wlr_final{} {w}x{h} R={radius}: GPU {gpu_fin:.3} s (wall {:.3} s)",
        prec.suffix(),
        t.elapsed().as_secs_f64()
    );
    if std::env::var("TSVD").is_ok() {
        let mut ti: Vec<&[f32]> = inputs[..14].to_vec();
        ti.push(inputs[18]);
        let tp = mcdenoise::shared::TsvdPush {
            width: w as u32,
            height: h as u32,
            radius,
            row0: 0,
        };
        let (_, tim) = run_planes(
            &ctx,
            &mcdenoise::kernels::tsvd_debug::DECL,
            prec,
            bytemuck::bytes_of(&tp),
            w,
            h,
            &ti,
            &[w * h; 12],
            1e5,
        )
        .unwrap();
        println!(
            "tsvd_debug: GPU {:.3} s",
            tim.iter().map(|t| t.nanoseconds).sum::<f64>() / 1e9
        );
    }
    if !cpu {
        return;
    }
    let f7: [&[f32]; 7] = std::array::from_fn(|k| inputs[k]);
    let v7: [&[f32]; 7] = std::array::from_fn(|k| inputs[7 + k]);
    let c3: [&[f32]; 3] = std::array::from_fn(|k| inputs[14 + k]);
    let mut cf = vec![vec![0.0f32; w * h]; 8];
    let t = Instant::now();
    reference::wlr_fit::wlr_fit(&push, f7, v7, c3, inputs[17], inputs[18], &mut cf);
    println!("twin wlr_fit: {:.3} s", t.elapsed().as_secs_f64());
    for (j, name) in wlr_fit::OUTPUTS.iter().enumerate() {
        println!("  {name}: close {:.4}", frac_close(&fit[j], &cf[j]));
    }
    if std::env::var("DETAIL").is_ok() {
        let mut bad: Vec<usize> = (0..w * h)
            .filter(|&i| {
                ((fit[1][i] - cf[1][i]).abs() as f64) > 1e-3 * ((cf[1][i] as f64).abs() + 1e-3)
            })
            .collect();
        bad.truncate(12);
        for i in bad {
            println!(
                "  px {i}: lambda1 gpu {:e} cpu {:e} | h {} {} | k0 {:e} {:e} | kappa1 {:e} {:e} | kflags {} {}",
                fit[1][i], cf[1][i], fit[0][i], cf[0][i], fit[2][i], cf[2][i], fit[3][i], cf[3][i], fit[4][i], cf[4][i]
            );
        }
    }
    let mut cfin = vec![vec![0.0f32; w * h]; 5];
    let t = Instant::now();
    reference::wlr_final::wlr_final(
        &push,
        f7,
        v7,
        c3,
        inputs[17],
        inputs[18],
        &hbar,
        [&fit[1], &fit[2], &fit[3], &fit[4]],
        &mut cfin,
    );
    println!("twin wlr_final: {:.3} s", t.elapsed().as_secs_f64());
    for (j, name) in wlr_final::OUTPUTS.iter().enumerate() {
        println!("  {name}: close {:.4}", frac_close(&fin[j], &cfin[j]));
    }
    let mut hist = [0usize; 16];
    for v in &cf[4] {
        hist[(*v as u32 % 16) as usize] += 1;
    }
    println!("k histogram {:?}", &hist[..10]);
    let mut fl = [0usize; 6];
    for v in &cf[4] {
        let f = *v as u32 / 16;
        for b in 0..5 {
            if f & (1 << b) != 0 {
                fl[b] += 1;
            }
        }
    }
    println!("flag counts (bits 0..4) {:?}", &fl[..5]);
}
