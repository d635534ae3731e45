//! APR's reference (spec §4.5 invariants): hat-matrix rows sum to 1, trace
//! and idempotence without ridge, the implicit error formulas against an
//! explicit H, constant and zero-variance images reproduced exactly; and the
//! CPU method on the committed fixture.

mod common;

use common::Rng;
use mcdenoise::reference::apr::{self as r, Planes};
use mcdenoise::reference::linalg::ridge_cholesky;

struct Img {
    w: usize,
    h: usize,
    y: Vec<f64>,
    v: Vec<f64>,
    feats: Vec<Vec<f64>>,
    valid: Vec<bool>,
}

fn random(w: usize, h: usize, seed: u64) -> Img {
    let mut rng = Rng(seed);
    let n = w * h;
    let feats = (0..4)
        .map(|k| {
            (0..n)
                .map(|i| ((i % w) as f64 * 0.05 * k as f64).sin() + 0.1 * rng.uniform())
                .collect()
        })
        .collect();
    Img {
        w,
        h,
        y: (0..n)
            .map(|i| 0.5 + 0.01 * (i / w) as f64 + 0.1 * rng.normal())
            .collect(),
        // Every 11th pixel is noisier than 1, so the block kernel is
        // K_h·o_i with o_i < 1 there (APR-OUTLIER-W) in every test below.
        v: (0..n)
            .map(|i| if i % 11 == 0 { 3.0 } else { 0.01 })
            .collect(),
        feats,
        valid: (0..n).map(|_| rng.uniform() > 0.03).collect(),
    }
}

impl Img {
    fn planes(&self) -> Planes<'_> {
        Planes {
            w: self.w,
            h: self.h,
            y: &self.y,
            v: &self.v,
            feats: &self.feats,
            valid: &self.valid,
            test_scale: None,
        }
    }
}

/// `H·1 = 1` at every accepted pixel, for every order (intercept unpenalised).
#[test]
fn hat_rows_sum_to_one() {
    let img = random(40, 33, 1);
    let pl = img.planes();
    for c in [0, 14 * 40 + 14, 28 * 40 + 28] {
        if !img.valid[c] {
            continue;
        }
        let d = r::design(&pl, r::BLOCK, c);
        assert!(d.idx.len() > 20);
        let ones = vec![1.0; img.w * img.h];
        for k in 0..=r::MAX_ORDER {
            let b = r::beta(&d, k, &ones);
            for (row, _) in d.idx.iter().enumerate() {
                let p3 = d.p[r::MAX_ORDER];
                let x = &d.rows[row * p3..row * p3 + d.p[k]];
                let v = r::eval(x, &b);
                assert!((v - 1.0).abs() < 1e-9, "K={k}: (H·1) = {v}");
            }
        }
    }
}

/// Without ridge: `tr H(K) = p_K` and `H(Hz) = Hz`.
#[test]
fn trace_and_idempotence_without_ridge() {
    let img = random(35, 35, 2);
    let pl = img.planes();
    let c = 14 * 35 + 14;
    let mut d = r::design(&pl, r::BLOCK, c);
    d.lambda = 0.0;
    let n = img.w * img.h;
    for k in 0..=r::MAX_ORDER {
        let f = r::stage_error(&d, k, &img.y, &img.v);
        assert!(
            (f.trace - d.p[k] as f64).abs() < 1e-9,
            "K={k}: tr H = {}, p = {}",
            f.trace,
            d.p[k]
        );
        let p3 = d.p[r::MAX_ORDER];
        let b = r::beta(&d, k, &img.y);
        let mut hz = vec![0.0; n];
        for (row, &q) in d.idx.iter().enumerate() {
            hz[q] = r::eval(&d.rows[row * p3..row * p3 + d.p[k]], &b);
        }
        let b2 = r::beta(&d, k, &hz);
        for (row, &q) in d.idx.iter().enumerate() {
            let v = r::eval(&d.rows[row * p3..row * p3 + d.p[k]], &b2);
            assert!((v - hz[q]).abs() < 1e-8, "K={k}: H(Hz) ≠ Hz");
        }
    }
}

/// §4.5: the implicit error formulas of §4.2 step 4 equal a direct
/// computation from the explicit H on a small window.
#[test]
fn implicit_error_equals_explicit_hat_matrix() {
    let img = random(20, 20, 3);
    let pl = img.planes();
    let c = 14 * 20 + 14;
    let d = r::design(&pl, r::BLOCK, c);
    let yprev: Vec<f64> = img.y.iter().map(|y| y * 0.9 + 0.02).collect();
    let s2: Vec<f64> = (0..400).map(|i| 0.002 + 0.0001 * (i % 7) as f64).collect();
    let (n, p3) = (d.idx.len(), d.p[r::MAX_ORDER]);
    for k in 0..=r::MAX_ORDER {
        let p = d.p[k];
        let mut m = vec![0.0; p * p];
        for row in 0..n {
            let x = &d.rows[row * p3..row * p3 + p];
            for a in 0..p {
                for b in 0..p {
                    m[a * p + b] += d.kh[row] * x[a] * x[b];
                }
            }
        }
        let ch = ridge_cholesky(&m, p, d.lambda, 1e-12);
        // H_ij = x_iᵀ M⁻¹ x_j K_j
        let t: Vec<Vec<f64>> = (0..n)
            .map(|row| ch.solve(&d.rows[row * p3..row * p3 + p]))
            .collect();
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            let xi = &d.rows[i * p3..i * p3 + p];
            let mut hy = 0.0;
            let mut var = 0.0;
            for j in 0..n {
                let hij: f64 = xi.iter().zip(&t[j]).map(|(a, b)| a * b).sum::<f64>() * d.kh[j];
                hy += hij * yprev[d.idx[j]];
                var += hij * hij * s2[d.idx[j]];
            }
            let bias = hy - yprev[d.idx[i]];
            num += d.kh[i] * (bias * bias + var);
            den += d.kh[i];
        }
        let f = r::stage_error(&d, k, &yprev, &s2);
        let direct = num / den;
        assert!(
            (f.xi - direct).abs() <= 1e-9 * direct.abs(),
            "K={k}: implicit {} explicit {direct}",
            f.xi
        );
    }
}

/// A constant image comes back exactly (order 0 and every other order); a
/// zero-variance image comes back exactly (only equal neighbours are
/// accepted; uncovered pixels become their own centres).
#[test]
fn constant_and_zero_variance_images_are_reproduced() {
    let mut img = random(45, 31, 4);
    img.y = vec![0.37; img.w * img.h];
    let res = r::channel(&img.planes(), 2, r::BLOCK, None);
    for (i, &v) in res.color.iter().enumerate() {
        if img.valid[i] {
            assert!((v - 0.37).abs() < 1e-12, "pixel {i}: {v}");
        }
    }
    let mut img = random(45, 31, 5);
    img.v = vec![0.0; img.w * img.h];
    let res = r::channel(&img.planes(), 2, r::BLOCK, None);
    for (i, &v) in res.color.iter().enumerate() {
        if img.valid[i] {
            assert!(
                (v - img.y[i]).abs() < 1e-9,
                "pixel {i}: {v} vs {}",
                img.y[i]
            );
        }
    }
    assert!(res.extra.iter().sum::<f64>() > 100.0, "no extra centres");
}

/// APR-OUTLIER-W: a pair of adjacent pixels each dominated by one bright
/// sample (value 100, variance 2500: the confidence interval accepts them
/// in every block) on a flat dark image. With the paper's kernel every block
/// within 14 pixels averages them in and the dark pixels around rise; with
/// `K_h/max(v, 1)` they stay within 1 % of the truth.
#[test]
fn one_sample_clusters_do_not_bleed_into_their_blocks() {
    let (w, h) = (57, 43);
    let n = w * h;
    let mut img = Img {
        w,
        h,
        y: vec![0.1; n],
        v: vec![1e-4; n],
        feats: vec![vec![0.5; n]; 4],
        valid: vec![true; n],
    };
    let cluster = [21 * w + 28, 21 * w + 29];
    for &i in &cluster {
        img.y[i] = 100.0;
        img.v[i] = 2500.0;
    }
    // Worst deviation from 0.1 at the pixels at least 3 from the cluster.
    let worst = |block: r::Shape| -> f64 {
        let res = r::channel(&img.planes(), 2, block, None);
        (0..n)
            .filter(|&i| (i / w).abs_diff(21) >= 3 || (i % w).abs_diff(28) >= 4)
            .map(|i| (res.color[i] - 0.1).abs())
            .fold(0.0, f64::max)
    };
    let (clamped, off) = (worst(r::BLOCK), worst(r::BLOCK_UNWEIGHTED));
    assert!(clamped <= 1e-3, "clamped: {clamped}");
    assert!(off >= 0.1, "the paper's kernel bleeds: {off}");
}

/// Every valid pixel lies within 14 of a sparse centre; `covering` lists
/// exactly the centres whose window holds the pixel.
#[test]
fn centres_cover_every_pixel() {
    let (w, h) = (43, 30);
    let valid = vec![true; w * h];
    let cs = r::centres(w, h, &valid);
    for i in 0..w * h {
        let cov = r::covering(w, h, i, &valid);
        let brute: Vec<usize> = cs
            .iter()
            .copied()
            .filter(|&c| {
                (c % w).abs_diff(i % w) <= r::RADIUS && (c / w).abs_diff(i / w) <= r::RADIUS
            })
            .collect();
        assert_eq!(cov, brute, "pixel {i}");
        assert!(!cov.is_empty());
    }
}

/// APR on the CPU lowers the fixture's rMSE.
#[test]
fn apr_denoises_the_fixture() {
    use mcdenoise::{Config, Denoiser, Method, Source};
    let dir = std::path::Path::new("tests/fixtures");
    let img = mcdenoise::io::read_stats(&dir.join("dof_checker_64_spp16.exr")).unwrap();
    let reference = mcdenoise::io::read_rgb(&dir.join("dof_checker_64_ref.exr")).unwrap();
    let input = mcdenoise::metrics::rmse(&mcdenoise::colour_of(&img), &reference);
    let d = Denoiser::new_cpu(Source::of_image(&img), Config::new(Method::Apr)).unwrap();
    let f = d.denoise(&img, Some(4096)).unwrap();
    let out = mcdenoise::metrics::rmse(&f.color, &reference);
    assert!(out < 0.6 * input, "APR {out} vs input {input}");
    let s: u64 = f.samples.unwrap().iter().map(|&s| s as u64).sum();
    assert_eq!(s, 4096);
}

/// APR-VIS: on a flat surface whose colour shares the noise of its
/// visibility (the same shadow rays), a block's fit on the raw visibility
/// hands that noise to the output; on the filtered visibility (the
/// default) it does not. Both backends; `apr.visibility=raw` is the spec.
#[test]
fn the_visibility_noise_does_not_pass_into_the_output() {
    use mcdenoise::image::{Layer, StatsImage};
    use mcdenoise::options::Options;
    use mcdenoise::{Config, Denoiser, Method, Source};
    let (w, h) = (48usize, 48usize);
    let n = w * h;
    let mut rng = Rng(5);
    // Visibility 0.5 ± 0.15 per pixel; colour 0.2 + 0.4 (vis − 0.5), the
    // truth 0.2 everywhere.
    let vis: Vec<f32> = (0..n).map(|_| (0.5 + 0.15 * rng.normal()) as f32).collect();
    let col: Vec<f32> = vis.iter().map(|&v| 0.2 + 0.4 * (v - 0.5)).collect();
    let mut s = StatsImage::new(w, h);
    s.set(Layer::Color, vec![col.clone(); 3]);
    s.set(
        Layer::ColorVariance,
        vec![vec![(0.4f32 * 0.15).powi(2); n]; 3],
    );
    s.set(
        Layer::Normal,
        vec![vec![0.0; n], vec![0.0; n], vec![1.0; n]],
    );
    s.set(Layer::NormalVariance, vec![vec![0.0; n]; 3]);
    s.set(Layer::Albedo, vec![vec![0.5; n]; 3]);
    s.set(Layer::AlbedoVariance, vec![vec![0.0; n]; 3]);
    s.set(Layer::Depth, vec![vec![2.0; n]]);
    s.set(Layer::DepthVariance, vec![vec![0.0; n]]);
    s.set(Layer::Visibility, vec![vis]);
    s.set(Layer::VisibilityVariance, vec![vec![0.15f32 * 0.15; n]]);
    s.set(Layer::Spp, vec![vec![16.0; n]]);
    let ctx = common::gpu();
    let mse = |visibility: &str, gpu: bool| {
        let mut config = Config::new(Method::Apr);
        config.options = Options::parse(&[format!("apr.visibility={visibility}")]).unwrap();
        let d = if gpu {
            Denoiser::new(&ctx, Source::of_image(&s), config)
        } else {
            Denoiser::new_cpu(Source::of_image(&s), config)
        }
        .unwrap();
        let out = d.denoise(&s, None).unwrap().color;
        let e: f64 = out.planes[1]
            .iter()
            .map(|&o| (o as f64 - 0.2).powi(2))
            .sum::<f64>()
            / n as f64;
        e
    };
    let input: f64 = col.iter().map(|&c| (c as f64 - 0.2).powi(2)).sum::<f64>() / n as f64;
    for gpu in [false, true] {
        let (raw, filtered) = (mse("raw", gpu), mse("filtered", gpu));
        assert!(
            raw > 0.5 * input,
            "gpu={gpu}: raw {raw}, input {input}: the fit follows the visibility"
        );
        assert!(
            filtered < 0.1 * raw,
            "gpu={gpu}: filtered {filtered} against raw {raw}"
        );
    }
    common::check_validation(&ctx);
}
