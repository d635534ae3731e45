//! Per-kernel timings: GPU time from timestamp queries (median of runs after a
//! warm-up) and the scalar twin's CPU time, on a synthetic frame.
//! Cases are named `kernel.inputs.WxH`; filter with a substring argument:
//! `cargo bench --bench kernels -- tsvd`.

use std::sync::Arc;
use std::time::Instant;

use mcdenoise::gpu::KernelDecl;
use mcdenoise::gpu::{ContextOptions, GpuContext, Precision};
use mcdenoise::kernels::{finalize_stats, run_planes, sanitize, tsvd_debug};
use mcdenoise::reference;
use mcdenoise::shared::{FinalizePush, LpPush, SanitizePush, TsvdPush};

const RUNS: usize = 5;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn plane(n: usize, f: impl Fn(usize) -> f32) -> Vec<f32> {
    (0..n).map(f).collect()
}

fn gpu_time(
    ctx: &Arc<GpuContext>,
    decl: &KernelDecl,
    p: Precision,
    push: &[u8],
    w: usize,
    h: usize,
    inputs: &[&[f32]],
    outs: &[usize],
    flops: f64,
) -> f64 {
    let mut t = Vec::new();
    for run in 0..=RUNS {
        let (_, timings) =
            run_planes(ctx, decl, p, push, w, h, inputs, outs, flops).expect("dispatch");
        if run > 0 {
            t.push(timings.iter().map(|k| k.nanoseconds).sum::<f64>());
        }
    }
    median(t)
}

fn cpu_time(mut f: impl FnMut()) -> f64 {
    f();
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64() * 1e9
}

fn row(
    name: &str,
    filter: &Option<String>,
    w: usize,
    h: usize,
    gpu32: f64,
    gpu64: Option<f64>,
    cpu: f64,
) {
    if filter.as_ref().is_some_and(|f| !name.contains(f.as_str())) {
        return;
    }
    let mp = (w * h) as f64 / 1e6;
    println!(
        "| {name:<32} | {:>10.2} | {:>10} | {:>10.2} | {:>12.1} |",
        gpu32 / 1e6,
        gpu64
            .map(|t| format!("{:.2}", t / 1e6))
            .unwrap_or("-".into()),
        cpu / 1e6,
        gpu32 / 1e6 / mp
    );
}

fn main() {
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default()).expect("Vulkan device"));
    let (w, h) = (256usize, 256usize);
    let n = w * h;
    println!("device: {}", ctx.info().name);
    println!("| case | GPU f32 ms | GPU f64 ms | twin CPU ms | GPU f32 ms/MP |");
    println!("|---|---:|---:|---:|---:|");
    let f64ok = ctx.supports_f64();
    let both = |decl: &KernelDecl, push: &[u8], inputs: &[&[f32]], outs: &[usize], flops: f64| {
        let a = gpu_time(&ctx, decl, Precision::F32, push, w, h, inputs, outs, flops);
        let b =
            f64ok.then(|| gpu_time(&ctx, decl, Precision::F64, push, w, h, inputs, outs, flops));
        (a, b)
    };

    // finalize_stats
    let sum = plane(n, |i| (i % 97) as f32 * 0.3);
    let sumsq = plane(n, |i| ((i % 97) as f32 * 0.3).powi(2) / 16.0 * 1.1);
    let count = vec![16.0f32; n];
    let push = FinalizePush {
        width: w as u32,
        height: h as u32,
        ..Default::default()
    };
    let (g, g64) = both(
        &finalize_stats::DECL,
        bytemuck::bytes_of(&push),
        &[&sum, &sumsq, &count],
        &[n, n],
        finalize_stats::FLOPS_PER_PIXEL,
    );
    let (mut m, mut v) = (vec![0.0; n], vec![0.0; n]);
    let c = cpu_time(|| {
        reference::finalize_stats::finalize_stats(&push, &sum, &sumsq, &count, &mut m, &mut v)
    });
    row(
        &format!("finalize_stats.synthetic.{w}x{h}"),
        &filter,
        w,
        h,
        g,
        g64,
        c,
    );

    // sanitize, each stage
    let value = plane(n, |i| {
        if i % 101 == 0 {
            f32::NAN
        } else {
            (i % 13) as f32 * 0.1
        }
    });
    let var = plane(n, |i| if i % 89 == 0 { -1.0 } else { 0.01 });
    let spp = plane(n, |i| if i % 53 == 0 { 1.0 } else { 16.0 });
    for stage in 0..3u32 {
        let push = SanitizePush {
            width: w as u32,
            height: h as u32,
            stage,
            has_var: (stage != 2) as u32,
            ..Default::default()
        };
        let (g, g64) = both(
            sanitize::decl(stage),
            bytemuck::bytes_of(&push),
            &[&value, &var, &spp],
            &[n, n, 4],
            sanitize::flops_per_pixel(stage),
        );
        let (mut a, mut b, mut cnt) = (vec![0.0; n], vec![0.0; n], [0u32; 4]);
        let c = cpu_time(|| {
            reference::sanitize::sanitize(&push, &value, &var, &spp, &mut a, &mut b, &mut cnt)
        });
        row(
            &format!("{}.{w}x{h}", sanitize::decl(stage).name),
            &filter,
            w,
            h,
            g,
            g64,
            c,
        );
    }

    // tsvd_debug at R = 5 and 9
    let feats: Vec<Vec<f32>> = (0..7)
        .map(|k| {
            plane(n, |i| {
                (((i % w) as f32 * 0.05 + k as f32).sin() + ((i / w) as f32 * 0.03).cos()) * 0.5
            })
        })
        .collect();
    let vars: Vec<Vec<f32>> = (0..7).map(|_| vec![1e-4f32; n]).collect();
    let spp = vec![8.0f32; n];
    for radius in [5u32, 9] {
        let push = TsvdPush {
            width: w as u32,
            height: h as u32,
            radius,
            ..Default::default()
        };
        let mut inputs: Vec<&[f32]> = feats.iter().map(|p| p.as_slice()).collect();
        inputs.extend(vars.iter().map(|p| p.as_slice()));
        inputs.push(&spp);
        let (g, g64) = both(
            &tsvd_debug::DECL,
            bytemuck::bytes_of(&push),
            &inputs,
            &[n; 13],
            tsvd_debug::flops_per_pixel(radius),
        );
        let fr: [&[f32]; 7] = std::array::from_fn(|k| feats[k].as_slice());
        let vr: [&[f32]; 7] = std::array::from_fn(|k| vars[k].as_slice());
        let mut out = vec![vec![0.0f32; n]; 13];
        let t = Instant::now();
        reference::tsvd_debug::tsvd_debug(&push, fr, vr, &spp, &mut out);
        let c = t.elapsed().as_secs_f64() * 1e9;
        row(
            &format!("tsvd_debug.r{radius}.{w}x{h}"),
            &filter,
            w,
            h,
            g,
            g64,
            c,
        );
    }

    // LP (spec §3) on the same features with a noisy shaded colour: the
    // whole method on the GPU (per-kernel sums over its dispatches) and each
    // twin on the CPU, summed over the five passes.
    let mut rng = 12345u64;
    let mut noise = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f32 / (1u64 << 53) as f32 - 0.5
    };
    let color: Vec<Vec<f32>> = (0..3)
        .map(|c| plane(n, |i| 0.5 + 0.3 * feats[c][i] + 0.2 * feats[4 + c][i]))
        .map(|p| {
            p.into_iter()
                .map(|v| (v + 0.2 * noise()).max(0.0))
                .collect()
        })
        .collect();
    let cvar: Vec<Vec<f32>> = (0..3).map(|_| vec![0.04f32 / 12.0; n]).collect();
    let mut img = mcdenoise::image::StatsImage::new(w, h);
    {
        use mcdenoise::image::Layer;
        img.set(Layer::Color, color.clone());
        img.set(Layer::ColorVariance, cvar.clone());
        img.set(Layer::Normal, feats[0..3].to_vec());
        img.set(Layer::NormalVariance, vars[0..3].to_vec());
        img.set(Layer::Depth, feats[3..4].to_vec());
        img.set(Layer::DepthVariance, vars[3..4].to_vec());
        img.set(Layer::Albedo, feats[4..7].to_vec());
        img.set(Layer::AlbedoVariance, vars[4..7].to_vec());
        img.set(Layer::Spp, vec![spp.clone()]);
    }
    let gpu_lp = |p: Precision| -> Vec<(String, f64)> {
        let mut req = mcdenoise::methods::DenoiseRequest::new(mcdenoise::methods::Method::Lp);
        req.precision = p;
        let mut runs: Vec<Vec<(String, f64, usize)>> = Vec::new();
        for run in 0..=RUNS {
            let out = mcdenoise::methods::denoise(Some(&ctx), &img, &req).expect("lp");
            if run > 0 {
                runs.push(mcdenoise::gpu::timings_per_kernel(&out.timings));
            }
        }
        runs[0]
            .iter()
            .map(|(k, _, _)| {
                let k = k.trim_end_matches("_f64").to_string();
                let t = median(
                    runs.iter()
                        .map(|r| {
                            r.iter()
                                .filter(|(n, _, _)| n.trim_end_matches("_f64") == k)
                                .map(|x| x.1)
                                .sum()
                        })
                        .collect(),
                );
                (k, t)
            })
            .collect()
    };
    let g32 = gpu_lp(Precision::F32);
    let g64 = f64ok.then(|| gpu_lp(Precision::F64));
    // The twins, pass by pass, on the same sanitised input.
    let (clean, _) = mcdenoise::methods::prepare::prepare_cpu(&img);
    let get = |l: mcdenoise::image::Layer| clean.get(l).unwrap();
    use mcdenoise::image::Layer as L;
    let (nrm, nv, dep, dv, alb, av) = (
        get(L::Normal),
        get(L::NormalVariance),
        get(L::Depth),
        get(L::DepthVariance),
        get(L::Albedo),
        get(L::AlbedoVariance),
    );
    let (col, cv, sp) = (get(L::Color), get(L::ColorVariance), &get(L::Spp)[0]);
    let planes = reference::lp::Planes {
        width: w,
        height: h,
        feat: [
            &nrm[0], &nrm[1], &nrm[2], &dep[0], &alb[0], &alb[1], &alb[2],
        ],
        var: [&nv[0], &nv[1], &nv[2], &dv[0], &av[0], &av[1], &av[2]],
        color: [&col[0], &col[1], &col[2]],
        cvar: [&cv[0], &cv[1], &cv[2]],
        spp: sp,
    };
    let mut state = vec![vec![0.0f32; 4 * n]; reference::lp::StateLayout::PLANES];
    let mut reach = vec![-1.0f32; n];
    let (mut t_reach, mut t_centres) = (0.0, 0.0);
    for pass in 0..reference::lp::GRANULARITIES.len() {
        let push = LpPush {
            width: w as u32,
            height: h as u32,
            granularity: reference::lp::GRANULARITIES[pass],
            pass: pass as u32,
            options: mcdenoise::shared::LP_VARSUB,
            ..Default::default()
        };
        let t = Instant::now();
        reference::lp_reach::lp_reach(&push, &state[0], &mut reach);
        t_reach += t.elapsed().as_secs_f64() * 1e9;
        let t = Instant::now();
        reference::lp_centres::lp_centres(&push, &planes, &reach, &mut state);
        t_centres += t.elapsed().as_secs_f64() * 1e9;
    }
    // The reach over every pass's centres, for the gather.
    let push = LpPush {
        width: w as u32,
        height: h as u32,
        pass: reference::lp::GRANULARITIES.len() as u32,
        ..Default::default()
    };
    let t = Instant::now();
    reference::lp_reach::lp_reach(&push, &state[0], &mut reach);
    t_reach += t.elapsed().as_secs_f64() * 1e9;
    let mut out = vec![vec![0.0f32; n]; reference::lp_gather::OUTPUTS];
    let t = Instant::now();
    reference::lp_gather::lp_gather(&push, &planes, &reach, &state, &mut out);
    let t_gather = t.elapsed().as_secs_f64() * 1e9;
    for (k, twin) in [
        ("lp_reach", t_reach),
        ("lp_centres", t_centres),
        ("lp_gather", t_gather),
    ] {
        let find = |v: &[(String, f64)]| v.iter().find(|(n, _)| n == k).map_or(0.0, |x| x.1);
        row(
            &format!("{k}.synthetic.{w}x{h}"),
            &filter,
            w,
            h,
            find(&g32),
            g64.as_ref().map(|v| find(v)),
            twin,
        );
    }
}
