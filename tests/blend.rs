//! The input blend (INPUT-BLEND): its kernel against its twin, what the
//! twin does at its limits, the chain's stage against the CPU path, the
//! defaults, and the configurations it refuses. The spike test and the
//! spike test (`tests/outliers.rs`) runs AOS with its defaults, the stage
//! on before the outlier stage gives the spikes' energy back.

mod common;

use common::{
    assert_close, bare_chain_config, check_validation, counts_with_invalid, gpu, precisions,
    run_chain, uniform_plane, Rng,
};
use mcdenoise::kernels::{input_blend, run_planes};
use mcdenoise::methods::blend::{push, run_cpu, BlendParams};
use mcdenoise::methods::chain::ChainConfig;
use mcdenoise::reference::input_blend::{input_blend as twin, residual_bound, trimmed_mean};
use mcdenoise::shared::BLEND_TRIM_MAX;
use mcdenoise::{
    Config, Denoiser, InputBlend, Layer, Method, Options, Pass, Prefilter, Pyramid, RgbImage,
    Source, StatsImage,
};

/// The stage's parameters: the variance's window `radius`, `k`, the
/// residual's window `s` (0: not read) and its `z`.
fn params(radius: u32, k: f32, s: u32, z: f32) -> BlendParams {
    BlendParams {
        radius,
        k,
        residual_radius: s,
        z,
    }
}

/// The kernel's colour and error planes on the planes `f, e, y, v, spp`.
fn kernel(
    ctx: &std::sync::Arc<mcdenoise::GpuContext>,
    prec: mcdenoise::Precision,
    p: &mcdenoise::shared::BlendPush,
    planes: [&[f32]; 5],
) -> Vec<Vec<f32>> {
    let n = planes[0].len();
    run_planes(
        ctx,
        &input_blend::DECL,
        prec,
        bytemuck::bytes_of(p),
        p.width as usize,
        p.height as usize,
        &planes,
        &[n, n],
        input_blend::flops_per_pixel(p.radius, p.residual_radius),
    )
    .unwrap()
    .0
}

#[test]
fn input_blend_matches_its_twin() {
    let ctx = gpu();
    for &(w, h) in &[(32usize, 32usize), (37, 23), (1, 5), (1, 1)] {
        let n = w * h;
        let mut rng = Rng(31 + w as u64);
        let f = uniform_plane(n, &mut rng, 2.0);
        let mut e = uniform_plane(n, &mut rng, 0.05);
        let y = uniform_plane(n, &mut rng, 2.0);
        let mut v = uniform_plane(n, &mut rng, 0.05);
        let spp = counts_with_invalid(n, &mut rng);
        // An estimate that is not a number, a negative one, a negative
        // variance and a pixel with nothing to say (E = V = 0).
        for (i, x) in e.iter_mut().enumerate() {
            match i % 17 {
                5 => *x = f32::NAN,
                6 => *x = -0.5,
                _ => {}
            }
        }
        for (i, x) in v.iter_mut().enumerate() {
            if i % 19 == 4 {
                *x = -1.0;
            }
        }
        // Valid pixels whose products or sums overflow f32 (issue #14's
        // range), an estimate near f32's largest with k up to 2.5, and a
        // reconstruction that is not a number.
        let (mut f, mut y) = (f, y);
        let valid: Vec<usize> = (0..n)
            .filter(|&i| spp[i].is_finite() && spp[i] >= 1.0)
            .collect();
        // Variances and residuals whose squares f32 still holds but twice
        // whose square it does not (the residual's test, BLEND-RESIDUAL;
        // its bound is positive), alone in the 1x1 image's window and
        // filling the 1x5 image's.
        if n <= 5 {
            for &i in &valid {
                (f[i], y[i], v[i]) = (1.7e19, 0.0, 1.8e19);
            }
        } else if valid.len() > 3 {
            let (a, b, c) = (valid[valid.len() / 2], valid[1], valid[valid.len() - 1]);
            (f[a], y[a], v[a], e[a]) = (1e30, 2e30, 1e30, 3e30);
            (v[b], e[b]) = (3e38, 3e38);
            f[c] = f32::NAN;
        }
        for &(radius, k, s, z) in &[
            (0u32, 1.0f32, 0u32, 1.0f32),
            (1, 1.0, 0, 1.0),
            (3, 2.5, 0, 1.0),
            (1, 2.0, 3, 1.0),
            (3, 0.5, 1, 0.0),
            (0, 0.0, 2, 2.0),
            (5, 1.0, 0, 1.0),
        ] {
            let p = push((w, h), params(radius, k, s, z));
            let (mut fo, mut eo) = (vec![0.0f32; n], vec![0.0f32; n]);
            twin(&p, &f, &e, &y, &v, &spp, &mut fo, &mut eo);
            for prec in precisions() {
                let g = kernel(&ctx, prec, &p, [&f, &e, &y, &v, &spp]);
                let what = format!("{w}x{h} r {radius} k {k} s {s} z {z} {prec:?}");
                // A pixel that keeps its own f or E passes a NaN through:
                // both sides hold it at the same pixels.
                for (name, gpu_plane, want) in [("colour", &g[0], &fo), ("error", &g[1], &eo)] {
                    let (gs, ts): (Vec<f32>, Vec<f32>) = gpu_plane
                        .iter()
                        .zip(want.iter())
                        .filter(|(a, b)| !(a.is_nan() && b.is_nan()))
                        .map(|(a, b)| (*a, *b))
                        .unzip();
                    assert_close(&format!("{what} {name}"), &gs, &ts, 1.0);
                }
            }
            for i in 0..n {
                let valid = spp[i].is_finite() && spp[i] >= 1.0;
                if !valid || !f[i].is_finite() {
                    assert_eq!(fo[i].to_bits(), f[i].to_bits(), "pixel {i} keeps f");
                    continue;
                }
                // The blend lies between the reconstruction and the input,
                // and for k <= 2 its error below the method's, read as at
                // least the residual's bound.
                let (lo, hi) = (f[i].min(y[i]), f[i].max(y[i]));
                assert!(
                    fo[i] >= lo - 1e-6 && fo[i] <= hi + 1e-6,
                    "pixel {i}: {} outside [{lo}, {hi}]",
                    fo[i]
                );
                let bound = if s > 0 {
                    residual_bound(&p, (&f, &y, &v, &spp), (i % w, i / w))
                } else {
                    0.0
                };
                if e[i] > 0.0 && k <= 2.0 {
                    let m = (e[i] as f64).max(bound);
                    assert!(eo[i] as f64 <= m * (1.0 + 1e-5), "pixel {i}: error grew");
                }
            }
        }
    }
    check_validation(&ctx);
}

/// The weights at their limits: an exact reconstruction (E = 0) is kept,
/// an exact input (its variance and its window's 0) is taken, and equal
/// errors (k = 1) average the two.
#[test]
fn the_twin_weighs_by_inverse_error() {
    let (w, h) = (5usize, 5usize);
    let n = w * h;
    let spp = vec![4.0f32; n];
    let f = vec![1.0f32; n];
    let y = vec![3.0f32; n];
    let p = push((w, h), params(1, 1.0, 0, 1.0));
    let run = |e: &[f32], v: &[f32]| {
        let (mut fo, mut eo) = (vec![0.0f32; n], vec![0.0f32; n]);
        twin(&p, &f, e, &y, v, &spp, &mut fo, &mut eo);
        (fo, eo)
    };
    let (fo, eo) = run(&vec![0.0; n], &vec![0.2; n]);
    assert!(fo.iter().all(|&x| x == 1.0) && eo.iter().all(|&x| x == 0.0));
    let (fo, eo) = run(&vec![0.2; n], &vec![0.0; n]);
    assert!(fo.iter().all(|&x| x == 3.0) && eo.iter().all(|&x| x == 0.0));
    let (fo, eo) = run(&vec![0.2; n], &vec![0.2; n]);
    assert!(fo.iter().all(|&x| (x - 2.0).abs() < 1e-6));
    assert!(eo.iter().all(|&x| (x - 0.1).abs() < 1e-7));
    // A pixel whose own variance is 0 in a noisy window is floored by the
    // window's mean without its largest value (BLEND-TRIM): the centre of
    // a 3x3 window of 0.2 but itself 0 takes V = 0.2 * 7 / 8.
    let mut v = vec![0.2f32; n];
    v[12] = 0.0;
    let (fo, _) = run(&vec![0.2; n], &v);
    let big_v = 0.2 * 7.0 / 8.0;
    let want = (big_v * 1.0 + 0.2 * 3.0) / (big_v + 0.2);
    assert!((fo[12] as f64 - want).abs() < 1e-5, "{} vs {want}", fo[12]);
    // BLEND-RESIDUAL: f = 1 where every input says 3 within their variance
    // of 0.2 is that far off whatever its estimate says. At the centre of
    // a 3x3 window B = 2² − 0.2 − z √(2 · 0.2² / 9), and the output is
    // taken towards the input by W = max(k E, B) = B.
    let (mut fo, mut eo) = (vec![0.0f32; n], vec![0.0f32; n]);
    let p1 = push((w, h), params(1, 1.0, 1, 1.0));
    twin(
        &p1,
        &f,
        &vec![0.0; n],
        &y,
        &vec![0.2; n],
        &spp,
        &mut fo,
        &mut eo,
    );
    let b = 4.0 - 0.2 - (2.0f64 * 0.04 / 9.0).sqrt();
    let wy = b / (0.2 + b);
    assert!(
        (fo[12] as f64 - (1.0 + 2.0 * wy)).abs() < 1e-5,
        "{}",
        fo[12]
    );
    let want_e = (1.0 - wy) * (1.0 - wy) * b + wy * wy * 0.2;
    assert!(
        (eo[12] as f64 - want_e).abs() < 1e-5,
        "{} vs {want_e}",
        eo[12]
    );
    // Where f agrees with the input the bound is negative: the output is
    // the residual-free one, bit for bit.
    let same = vec![3.0f32; n];
    let (mut a, mut ae) = (vec![0.0f32; n], vec![0.0f32; n]);
    let (mut b0, mut be) = (vec![0.0f32; n], vec![0.0f32; n]);
    let e = vec![0.05f32; n];
    twin(&p1, &same, &e, &y, &vec![0.2; n], &spp, &mut a, &mut ae);
    twin(&p, &same, &e, &y, &vec![0.2; n], &spp, &mut b0, &mut be);
    assert!(a == b0 && ae == be);
}

/// BLEND-RESIDUAL: a reconstruction that smoothed away a thin bright line
/// its features do not show, and whose estimate does not know it, is
/// taken back towards the input on the line, while on the flat noisy
/// ground beyond the residual's window of the line, where it is right, the
/// input's noise stays out (within the window it comes in with the line).
#[test]
fn the_residual_takes_a_lost_line_back_from_the_input() {
    let (w, h) = (48usize, 48usize);
    let n = w * h;
    let mut rng = Rng(7);
    let truth: Vec<f32> = (0..n)
        .map(|i| if i % w == 24 { 4.0 } else { 0.5 })
        .collect();
    let v = vec![0.01f32; n];
    // The input: the truth with noise of variance v.
    let noise = uniform_plane(n, &mut rng, 1.0);
    let y: Vec<f32> = (0..n)
        .map(|i| truth[i] + (noise[i] - 0.5) * (12.0f32 * 0.01).sqrt())
        .collect();
    // The reconstruction: exact off the line, the ground's level on it.
    let f = vec![0.5f32; n];
    let e = vec![1e-4f32; n];
    let spp = vec![16.0f32; n];
    let run = |s: u32| {
        let (mut fo, mut eo) = (vec![0.0f32; n], vec![0.0f32; n]);
        twin(
            &push((w, h), params(3, 1.0, s, 1.0)),
            &f,
            &e,
            &y,
            &v,
            &spp,
            &mut fo,
            &mut eo,
        );
        fo
    };
    let mse = |o: &[f32], on_line: bool| {
        let px: Vec<usize> = (0..n).filter(|&i| (i % w == 24) == on_line).collect();
        px.iter()
            .map(|&i| ((o[i] - truth[i]) as f64).powi(2))
            .sum::<f64>()
            / px.len() as f64
    };
    let (off, on) = (run(0), run(3));
    println!(
        "line MSE {} -> {}, ground MSE {} -> {}",
        mse(&off, true),
        mse(&on, true),
        mse(&off, false),
        mse(&on, false)
    );
    assert!(mse(&on, true) < 0.01 * mse(&off, true));
    assert!(mse(&on, true) < 2.0 * 0.01);
    // On the ground away from the line (its window does not reach it) the
    // input's noise adds less than 2 % of its variance.
    let far: Vec<usize> = (0..n).filter(|&i| (i % w).abs_diff(24) > 3).collect();
    let added = far
        .iter()
        .map(|&i| ((on[i] - truth[i]) as f64).powi(2))
        .sum::<f64>()
        / far.len() as f64;
    assert!(added < 0.02 * 0.01, "{added}");
}

/// BLEND-TRIM: the variance window leaves out its tenth of largest
/// values, at most `BLEND_TRIM_MAX`, never all.
#[test]
fn the_variance_floor_is_a_trimmed_mean() {
    let mut ten: Vec<f64> = (1..=10).map(f64::from).collect();
    assert_eq!(trimmed_mean(&mut ten), 5.0);
    let mut nine: Vec<f64> = (1..=9).map(f64::from).collect();
    assert_eq!(trimmed_mean(&mut nine), 4.5);
    assert_eq!(trimmed_mean(&mut [7.0]), 7.0);
    assert_eq!(trimmed_mean(&mut [7.0, 1.0]), 1.0);
    let mut many = vec![1.0; 100];
    many[..20].fill(1e9);
    let drop = BLEND_TRIM_MAX as f64;
    assert_eq!(
        trimmed_mean(&mut many),
        ((20.0 - drop) * 1e9 + 80.0) / (100.0 - drop)
    );
}

/// BLEND-TRIM: a dark pixel beside a small lamp whose pixels are partly
/// covered (a huge variance each) and into which the method leaked the
/// lamp, knowing its error to be large, takes its input back: the lamp's
/// few variances do not lift its floor `V` above the method's error. On
/// the GPU in both precisions as in the twin.
#[test]
fn a_lamp_beside_a_dark_pixel_does_not_lift_its_variance_floor() {
    let ctx = gpu();
    let (w, h) = (24usize, 24usize);
    let n = w * h;
    let lamp = |i: usize| (11..13).contains(&(i % w)) && (11..13).contains(&(i / w));
    let leaked = |i: usize| {
        !lamp(i) && (i % w).abs_diff(11) <= 2 && (i / w).abs_diff(11) <= 2 && i % w <= 13
    };
    let y: Vec<f32> = (0..n).map(|i| if lamp(i) { 450.0 } else { 0.1 }).collect();
    let v: Vec<f32> = (0..n).map(|i| if lamp(i) { 6.7e4 } else { 1e-3 }).collect();
    let f: Vec<f32> = (0..n)
        .map(|i| {
            if leaked(i) {
                30.0
            } else if lamp(i) {
                300.0
            } else {
                0.1
            }
        })
        .collect();
    let e: Vec<f32> = (0..n)
        .map(|i| if leaked(i) || lamp(i) { 1e3 } else { 1e-4 })
        .collect();
    let spp = vec![4.0f32; n];
    let p = push((w, h), params(3, 0.125, 3, 1.0));
    let (mut fo, mut eo) = (vec![0.0f32; n], vec![0.0f32; n]);
    twin(&p, &f, &e, &y, &v, &spp, &mut fo, &mut eo);
    let mut outs = vec![fo];
    for prec in precisions() {
        outs.push(kernel(&ctx, prec, &p, [&f, &e, &y, &v, &spp]).swap_remove(0));
    }
    let dark: Vec<usize> = (0..n).filter(|&i| leaked(i)).collect();
    assert!(dark.len() >= 10);
    for out in &outs {
        for &i in &dark {
            // Within 2 % of the leak from the input: the untrimmed floor,
            // about 5500, kept about 98 % of it.
            assert!(
                (out[i] - y[i]).abs() < 0.02 * (f[i] - y[i]),
                "pixel ({}, {}): {} from input {}",
                i % w,
                i / w,
                out[i],
                y[i]
            );
        }
    }
    check_validation(&ctx);
}

fn fixture() -> (StatsImage, RgbImage) {
    let img = mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap();
    let r = mcdenoise::io::read_rgb(std::path::Path::new(
        "tests/fixtures/dof_checker_64_ref.exr",
    ))
    .unwrap();
    (img, r)
}

/// The GPU chain with the stage equals the CPU path (the twins, in f64),
/// with and without the outlier stage around it.
#[test]
fn the_gpu_stage_matches_the_cpu_path_on_the_fixture() {
    let ctx = gpu();
    let (img, _) = fixture();
    for (method, outliers) in [
        (Method::Wlr, mcdenoise::Outliers::Off),
        (Method::Wlr, mcdenoise::Outliers::On),
    ] {
        let config = |blend: InputBlend| {
            let mut c = Config::new(method);
            c.input_blend = blend;
            c.outliers = outliers;
            c
        };
        let src = Source::of_image(&img);
        let cpu = Denoiser::new_cpu(src.clone(), config(InputBlend::On))
            .unwrap()
            .denoise(&img, None)
            .unwrap();
        let on = Denoiser::new(&ctx, src.clone(), config(InputBlend::On))
            .unwrap()
            .denoise(&img, None)
            .unwrap();
        let off = Denoiser::new(&ctx, src, config(InputBlend::Off))
            .unwrap()
            .denoise(&img, None)
            .unwrap();
        let (cpu_e, on_e) = (cpu.error, on.error);
        let mut moved = 0.0;
        for c in 0..3 {
            let what = format!("{method:?} {outliers:?} channel {c}");
            assert_close(
                &format!("{what} colour"),
                &on.color.planes[c],
                &cpu.color.planes[c],
                0.98,
            );
            assert_close(
                &format!("{what} error"),
                &on_e.planes[c],
                &cpu_e.planes[c],
                0.95,
            );
            moved += on.color.planes[c]
                .iter()
                .zip(&off.color.planes[c])
                .map(|(a, b)| (a - b).abs() as f64)
                .sum::<f64>();
        }
        assert!(moved > 0.0, "{method:?}: the stage changed nothing");
    }
    check_validation(&ctx);
}

fn chain_config(method: Method, input_blend: bool) -> ChainConfig {
    ChainConfig {
        input_blend,
        prefilter: Prefilter::Auto,
        ..bare_chain_config(method)
    }
}

/// The chain's stage is its parts: every method's own GPU output and error
/// estimate, blended by the twin with the statistics the method read.
#[test]
fn the_stage_is_the_method_output_blended() {
    let ctx = gpu();
    let (img, _) = fixture();
    for method in [
        Method::Wlr,
        Method::Lp,
        Method::Apr,
        Method::Aos,
        Method::Auto,
    ] {
        let (off, clean) = run_chain(&ctx, &img, chain_config(method, false));
        let (on, _) = run_chain(&ctx, &img, chain_config(method, true));
        let params = mcdenoise::methods::blend::params(method, &Options::default()).unwrap();
        let (want, want_e) = run_cpu(&clean, &off.color, &off.error, params).unwrap();
        for c in 0..3 {
            let what = format!("{method:?} channel {c}");
            assert_close(
                &format!("{what} colour"),
                &on.color.planes[c],
                &want.planes[c],
                1.0,
            );
            assert_close(
                &format!("{what} error"),
                &on.error.planes[c],
                &want_e.planes[c],
                1.0,
            );
        }
    }
    check_validation(&ctx);
}

/// The stage's parameters come from the options: k = 0 without the
/// residual keeps the method's output, the larger k the nearer the output
/// to the input, and the residual's bound only moves it nearer.
#[test]
fn the_options_set_its_parameters() {
    let ctx = gpu();
    let (img, _) = fixture();
    let run = |opts: &[&str], blend: InputBlend| {
        let mut c = Config::new(Method::Wlr);
        c.input_blend = blend;
        c.outliers = mcdenoise::Outliers::Off;
        c.options = Options::parse(opts).unwrap();
        let d = Denoiser::new(&ctx, Source::of_image(&img), c).unwrap();
        d.denoise(&img, None).unwrap().color
    };
    let off = run(&[], InputBlend::Off);
    let k0 = run(&["blend.k=0", "blend.residual_radius=0"], InputBlend::On);
    for c in 0..3 {
        assert_close(
            "k = 0 without the residual keeps the method's output",
            &k0.planes[c],
            &off.planes[c],
            1.0,
        );
    }
    // The larger k, the nearer the input.
    let input = mcdenoise::colour_of(&img);
    let spp = &img.get(Layer::Spp).unwrap()[0];
    let distance = |x: &RgbImage| -> f64 {
        (0..3)
            .map(|c| {
                (0..spp.len())
                    .filter(|&i| spp[i] >= 1.0)
                    .map(|i| (x.planes[c][i] - input.planes[c][i]).abs() as f64)
                    .sum::<f64>()
            })
            .sum()
    };
    let d: Vec<f64> = ["0.5", "1", "4", "100"]
        .iter()
        .map(|k| {
            distance(&run(
                &[
                    "blend.radius=0",
                    "blend.residual_radius=0",
                    &format!("blend.k={k}"),
                ],
                InputBlend::On,
            ))
        })
        .collect();
    let d_off = distance(&off);
    println!("distance to the input: off {d_off}, k = 0.5, 1, 4, 100: {d:?}");
    assert!(
        d_off > d[0] && d.windows(2).all(|w| w[0] > w[1]),
        "{d_off} {d:?}"
    );
    // The residual (BLEND-RESIDUAL, on by default) can only raise the
    // input's weight; the larger z, the less it does.
    let with = |z: &str| {
        distance(&run(
            &["blend.k=1", &format!("blend.z={z}")],
            InputBlend::On,
        ))
    };
    let without = distance(&run(
        &["blend.k=1", "blend.residual_radius=0"],
        InputBlend::On,
    ));
    let (z0, z1, z4) = (with("0"), with("1"), with("4"));
    println!("residual: off {without}, z = 0, 1, 4: {z0} {z1} {z4}");
    assert!(
        z0 < z1 && z1 < z4 && z4 <= without,
        "{z0} {z1} {z4} {without}"
    );
    check_validation(&ctx);
}

/// INPUT-BLEND's defaults: on after WLR, LP, APR and AOS in a final
/// reconstruction (the output is `InputBlend::On`'s bit for bit), off
/// after `auto` and in an adaptive pass.
#[test]
fn the_default_runs_the_stage_after_every_method_but_auto() {
    let ctx = gpu();
    let (img, _) = fixture();
    let run = |method: Method, pass: Pass, blend: Option<InputBlend>| {
        let mut c = Config::new(method);
        c.pass = pass;
        c.pyramid = Pyramid::Off;
        if let Some(b) = blend {
            c.input_blend = b;
        }
        let d = Denoiser::new(&ctx, Source::of_image(&img), c).unwrap();
        d.denoise(&img, None).unwrap().color.planes
    };
    for method in [Method::Wlr, Method::Lp, Method::Apr, Method::Aos] {
        let auto = run(method, Pass::Final, None);
        assert!(
            auto == run(method, Pass::Final, Some(InputBlend::On)),
            "{method:?}"
        );
        assert!(
            auto != run(method, Pass::Final, Some(InputBlend::Off)),
            "{method:?}"
        );
        let pass = run(method, Pass::Intermediate, None);
        assert!(
            pass == run(method, Pass::Intermediate, Some(InputBlend::Off)),
            "{method:?}"
        );
    }
    let auto = run(Method::Auto, Pass::Final, None);
    assert!(auto == run(Method::Auto, Pass::Final, Some(InputBlend::Off)));
    check_validation(&ctx);
}

#[test]
fn method_none_is_refused() {
    let ctx = gpu();
    let (img, _) = fixture();
    let mut c = Config::new(Method::None);
    c.input_blend = InputBlend::On;
    assert!(c.check_size(64, 64).is_err());
    let err = Denoiser::new(&ctx, Source::of_image(&img), c.clone()).unwrap_err();
    assert!(format!("{err}").contains("input blend"), "{err}");
    assert!(Denoiser::new_cpu(Source::of_image(&img), c)
        .and_then(|d| d.denoise(&img, None))
        .is_err());
    let mut auto = Config::new(Method::None);
    auto.input_blend = InputBlend::Auto;
    assert!(Denoiser::new(&ctx, Source::of_image(&img), auto).is_ok());
    check_validation(&ctx);
}

/// The CPU helper of the stage refuses statistics without the layers it
/// reads, by name.
#[test]
fn the_cpu_stage_names_a_missing_layer() {
    let img = StatsImage::new(4, 4);
    let c = RgbImage::new(4, 4);
    let err = run_cpu(&img, &c, &c, params(1, 1.0, 3, 1.0)).unwrap_err();
    assert!(
        format!("{err}").contains("colour") || format!("{err}").contains("color"),
        "{err}"
    );
}

/// BLEND-RESIDUAL on the GPU: where the reconstruction is within a small
/// part of the input's noise of it, the residual's bound is negative (the
/// twin says so at every pixel), and the kernel's output, which differs
/// from the reconstruction, is the one without the residual bit for bit,
/// in both precisions.
#[test]
fn a_negative_residual_bound_leaves_the_kernel_output_unchanged() {
    let ctx = gpu();
    let (w, h) = (29usize, 17usize);
    let n = w * h;
    let mut rng = Rng(5);
    let f = uniform_plane(n, &mut rng, 2.0);
    let e = uniform_plane(n, &mut rng, 0.05);
    let v: Vec<f32> = uniform_plane(n, &mut rng, 0.05)
        .iter()
        .map(|x| x + 0.01)
        .collect();
    // |y − f| ≤ 0.05: (y − f)² ≤ 0.0025 < v ≥ 0.01 everywhere.
    let y: Vec<f32> = f
        .iter()
        .map(|&x| x + 0.1 * (rng.uniform() as f32 - 0.5))
        .collect();
    let spp = counts_with_invalid(n, &mut rng);
    let p3 = push((w, h), params(3, 0.5, 3, 1.0));
    for i in (0..n).filter(|&i| spp[i].is_finite() && spp[i] >= 1.0) {
        let b = residual_bound(&p3, (&f, &y, &v, &spp), (i % w, i / w));
        assert!(b < 0.0, "pixel {i}: bound {b}");
    }
    for prec in precisions() {
        let run = |s: u32| {
            let p = push((w, h), params(3, 0.5, s, 1.0));
            kernel(&ctx, prec, &p, [&f, &e, &y, &v, &spp])
        };
        let (with, without) = (run(3), run(0));
        assert!(with[0] != f, "{prec:?}: the blend moved nothing");
        assert!(with == without, "{prec:?}");
    }
    check_validation(&ctx);
}

/// The kernel's window limit mirrors the crate's constant.
#[test]
fn the_kernel_mirrors_the_trim_limit() {
    let source = include_str!("../spirv/input_blend.comp");
    let value: usize = common::shader_define(source, "BLEND_TRIM_MAX");
    assert_eq!(value, BLEND_TRIM_MAX);
}

/// AOS's residual test has its own defaults (BLEND-AOS: `s` = 4, `z` =
/// 0.7), the other methods BLEND-RESIDUAL's (`s` = 3, `z` = 1): AOS's
/// default output is that of the options spelled out, and not that of
/// BLEND-RESIDUAL's.
#[test]
fn aos_has_its_own_residual_defaults() {
    use mcdenoise::shared::{BLEND_RESIDUAL_RADIUS, BLEND_Z};
    let params = |m: Method| mcdenoise::methods::blend::params(m, &Options::default()).unwrap();
    for m in [Method::Wlr, Method::Lp, Method::Apr] {
        assert_eq!(
            (params(m).residual_radius, params(m).z),
            (BLEND_RESIDUAL_RADIUS, BLEND_Z),
            "{m:?}"
        );
    }
    assert_eq!(
        (params(Method::Aos).residual_radius, params(Method::Aos).z),
        (4, 0.7)
    );
    let ctx = gpu();
    let (img, _) = fixture();
    let run = |opts: &[&str]| {
        let mut c = Config::new(Method::Aos);
        c.options = Options::parse(opts).unwrap();
        let d = Denoiser::new(&ctx, Source::of_image(&img), c).unwrap();
        d.denoise(&img, None).unwrap().color
    };
    let default = run(&[]);
    assert_eq!(default, run(&["blend.residual_radius=4", "blend.z=0.7"]));
    assert_ne!(default, run(&["blend.residual_radius=3", "blend.z=1"]));
    check_validation(&ctx);
}
