//! WLR kernels (spec §2) on the GPU against their scalar twins (§0.3
//! tolerances), f32 and f64, and the invariants of §2.6 on the twin routines.
//!
//! Each kernel is compared as much in isolation as it can be: `wlr_final`
//! gets the twin's `hbar` and MSE model (`λ1`, `κ0`, `κ1`) on both sides, and
//! on the GPU the rank and the centre state (local space, `b_j`) of the GPU's
//! `wlr_fit`, which it reads instead of recomputing them. Agreement numbers
//! are printed (`cargo test --test wlr -- --nocapture`).

mod common;
use common::*;

use std::sync::Arc;

use mcdenoise::gpu::{Batch, GpuBuffer, GpuContext, Precision};
use mcdenoise::image::Layer;
use mcdenoise::kernels::{
    channel_mean, gauss_smooth, run_bound, run_planes, wlr_final, wlr_fit, Bound,
};
use mcdenoise::reference::wlr::{self as rw, Planes, D, FLAG_FEW, FLAG_K0, FLAG_SOLVE_FAIL};
use mcdenoise::reference::{self, spp_of};
use mcdenoise::shared::{
    ChannelMeanPush, SmoothPush, WlrPush, WLR_DEFAULT_OPTIONS, WLR_NONNEG, WLR_OUTLIER_CLAMPED,
    WLR_REJECT,
};

/// The 19 input planes of WLR: 7 features, their 7 variances, colour R, G,
/// B, vbar, spp (the kernels get the features and variances packed, as
/// `reference::gbf_pack` packs them); with WLR-VIS two more, the visibility
/// and its variance (the `_vis` kernels' tenth feature).
#[derive(Clone)]
struct Scene {
    w: usize,
    h: usize,
    planes: Vec<Vec<f32>>,
}

impl Scene {
    fn feat(&self) -> [&[f32]; 7] {
        std::array::from_fn(|k| self.planes[k].as_slice())
    }
    fn var(&self) -> [&[f32]; 7] {
        std::array::from_fn(|k| self.planes[7 + k].as_slice())
    }
    fn color(&self) -> [&[f32]; 3] {
        std::array::from_fn(|k| self.planes[14 + k].as_slice())
    }
    fn vbar(&self) -> &[f32] {
        &self.planes[17]
    }
    fn spp(&self) -> &[f32] {
        &self.planes[18]
    }
    fn vis(&self) -> Option<[&[f32]; 2]> {
        (self.planes.len() > 19).then(|| [&self.planes[19][..], &self.planes[20][..]])
    }
    fn features(&self) -> usize {
        if self.vis().is_some() {
            10
        } else {
            9
        }
    }
    fn rw_planes(&self) -> Planes<'_> {
        Planes {
            width: self.w,
            height: self.h,
            feat: self.feat(),
            var: self.var(),
            color: self.color(),
            vbar: self.vbar(),
            spp: self.spp(),
            vis: self.vis(),
        }
    }
}

/// [`synthetic`] with a soft shadow across it: a visibility feature (noisy,
/// with its variance) that darkens the colour, which no other feature
/// explains.
fn synthetic_vis(w: usize, h: usize, seed: u64) -> Scene {
    let mut sc = synthetic(w, h, seed);
    let mut rng = Rng(seed ^ 0x5eed);
    let n = w * h;
    let (mut vis, mut vv) = (vec![0.0f32; n], vec![0.0f32; n]);
    for i in 0..n {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        let t = ((x - 0.6 * w as f64 + 0.4 * y) / 3.0).tanh();
        let v = 0.5 + 0.5 * t;
        let sd = 0.05;
        vis[i] = (v + sd * rng.normal()) as f32;
        vv[i] = (sd * sd * (0.5 + rng.uniform())) as f32;
        for ch in 14..17 {
            sc.planes[ch][i] *= (0.2 + 0.8 * v) as f32;
        }
    }
    sc.planes.push(vis);
    sc.planes.push(vv);
    sc
}

/// Structured features (a sphere on a tilted floor, checker albedo) with
/// noise and matching variances; colour = a smooth shading of the features
/// times albedo, plus Gaussian noise of known, spatially varying variance;
/// ~2% invalid pixels (spp 0).
fn synthetic(w: usize, h: usize, seed: u64) -> Scene {
    let mut rng = Rng(seed);
    let n = w * h;
    let mut p = vec![vec![0.0f32; n]; 19];
    let s = w.max(h) as f64;
    for i in 0..n {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        let (cx, cy, rad) = (w as f64 * 0.45, h as f64 * 0.55, 0.3 * s);
        let r2 = ((x - cx).powi(2) + (y - cy).powi(2)) / rad.powi(2);
        let inside = r2 < 1.0;
        let (nx, ny, nz, d) = if inside {
            let nz = (1.0 - r2).sqrt();
            ((x - cx) / rad, (y - cy) / rad, nz, 3.0 - nz)
        } else {
            (0.0, 0.8, 0.6, 5.0 + 0.05 * y)
        };
        let alb = if (x as usize / 8 + y as usize / 8) % 2 == 0 {
            0.8
        } else {
            0.25
        };
        let base = [nx, ny, nz, d, alb, alb * 0.9, alb * 0.6];
        let fsd = [0.02, 0.02, 0.02, 0.05, 0.01, 0.01, 0.01];
        for k in 0..7 {
            p[k][i] = (base[k] + fsd[k] * rng.normal()) as f32;
            p[7 + k][i] = (fsd[k] * fsd[k] * (0.5 + rng.uniform())) as f32;
        }
        let shade = 0.2 + 0.8 * (0.3 * nx + 0.5 * ny + 0.8 * nz).max(0.0) + 0.1 * (0.15 * x).sin();
        let sd = 0.03 + 0.05 * (y / s);
        let mut vbar = 0.0;
        for ch in 0..3 {
            let v = sd * sd * (0.8 + 0.4 * rng.uniform());
            p[14 + ch][i] = (shade * base[4 + ch] + v.sqrt() * rng.normal()) as f32;
            vbar += v / 3.0;
        }
        p[17][i] = vbar as f32;
        p[18][i] = if rng.next_u64() % 50 == 0 { 0.0 } else { 16.0 };
    }
    Scene { w, h, planes: p }
}

/// The committed fixture, sanitised on the CPU (finite values, every variance).
fn fixture() -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/dof_checker_64_spp16.exr");
    let img = mcdenoise::io::read_stats(&path).unwrap();
    let (img, _) = mcdenoise::methods::prepare::prepare_cpu(&img);
    let (w, h) = (img.width, img.height);
    let get = |l: Layer| img.get(l).unwrap().to_vec();
    let mut planes = Vec::new();
    planes.extend(get(Layer::Normal));
    planes.extend(get(Layer::Depth));
    planes.extend(get(Layer::Albedo));
    planes.extend(get(Layer::NormalVariance));
    planes.extend(get(Layer::DepthVariance));
    planes.extend(get(Layer::AlbedoVariance));
    planes.extend(get(Layer::Color));
    let cv = get(Layer::ColorVariance);
    let mut vbar = vec![0.0f32; w * h];
    let push = ChannelMeanPush {
        width: w as u32,
        height: h as u32,
        ..Default::default()
    };
    reference::channel_mean::channel_mean(&push, &cv[0], &cv[1], &cv[2], &mut vbar);
    planes.push(vbar);
    planes.extend(get(Layer::Spp));
    assert_eq!(planes.len(), 19);
    Scene { w, h, planes }
}

fn wlr_push(sc: &Scene, radius: u32, options: u32) -> WlrPush {
    WlrPush {
        width: sc.w as u32,
        height: sc.h as u32,
        radius,
        options,
        ..Default::default()
    }
}

/// Twin outputs of the chain: wlr_fit's 8 planes and hbar = G_1(h_opt).
fn twin_fit(sc: &Scene, push: &WlrPush) -> (Vec<Vec<f32>>, Vec<f32>) {
    let n = sc.w * sc.h;
    let mut fit = vec![vec![0.0f32; n]; 8];
    reference::wlr_fit::wlr_fit(
        push,
        sc.feat(),
        sc.var(),
        sc.vis(),
        sc.color(),
        sc.vbar(),
        sc.spp(),
        &mut fit,
    );
    let sp = SmoothPush {
        width: sc.w as u32,
        height: sc.h as u32,
        radius: gauss_smooth::radius(1.0),
        sigma: 1.0,
        ..Default::default()
    };
    let mut hbar = vec![0.0f32; n];
    reference::gauss_smooth::smooth(&sp, &fit[0], sc.spp(), &mut hbar);
    (fit, hbar)
}

fn twin_final(sc: &Scene, push: &WlrPush, fit: &[Vec<f32>], hbar: &[f32]) -> Vec<Vec<f32>> {
    let mut out = vec![vec![0.0f32; sc.w * sc.h]; 5];
    reference::wlr_final::wlr_final(
        push,
        sc.feat(),
        sc.var(),
        sc.vis(),
        sc.color(),
        sc.vbar(),
        sc.spp(),
        hbar,
        [&fit[1], &fit[2], &fit[3], &fit[4]],
        &mut out,
    );
    out
}

/// Words of `wlr_fit`'s centre-state ring for the whole image
/// (`ring_rows` = height).
fn state_words(sc: &Scene, p: Precision) -> usize {
    let word = if p == Precision::F64 { 2 } else { 1 };
    sc.w * sc.h * wlr_fit::state_words(sc.features()) * word
}

/// A context without 64-bit types: its f32 WLR kernels are the `_dd`
/// variants (steps 6-7 in double-float).
fn gpu_dd() -> Arc<GpuContext> {
    static CTX: std::sync::OnceLock<Arc<GpuContext>> = std::sync::OnceLock::new();
    CTX.get_or_init(common::gpu_without_64bit).clone()
}

/// The variants the WLR kernels are compared in: f32 and f64 on the test
/// context, and the double-float f32 variant on a context without 64-bit
/// types.
fn variants() -> Vec<(Arc<GpuContext>, Precision, &'static str)> {
    let mut v: Vec<_> = precisions()
        .into_iter()
        .map(|p| (gpu(), p, if p == Precision::F64 { "F64" } else { "F32" }))
        .collect();
    v.push((gpu_dd(), Precision::F32, "F32-dd"));
    v
}

/// GPU `wlr_fit` over the whole image: its 8 maps and its centre state.
fn gpu_fit(
    ctx: &Arc<GpuContext>,
    sc: &Scene,
    push: &WlrPush,
    p: Precision,
) -> (Vec<Vec<f32>>, Vec<f32>) {
    let push = WlrPush {
        ring_rows: sc.h as u32,
        ..*push
    };
    let pk = reference::gbf_pack::gbf_pack(sc.feat(), sc.var(), sc.spp());
    let mut bound: Vec<Bound> = pk.iter().map(|v| Bound::In(v)).collect();
    bound.extend(sc.color().map(Bound::In));
    bound.extend([Bound::In(sc.vbar()), Bound::In(sc.spp())]);
    bound.extend([Bound::Out(sc.w * sc.h); 8]);
    bound.push(Bound::Out(state_words(sc, p)));
    // The `_vis` kernel's inputs follow the state.
    bound.extend(sc.vis().into_iter().flatten().map(Bound::In));
    let (mut o, _) = run_bound(
        ctx,
        wlr_fit::decl(sc.features()),
        p,
        bytemuck::bytes_of(&push),
        (sc.w, sc.h),
        &bound,
        wlr_fit::flops_per_pixel(push.radius, sc.features()),
    )
    .unwrap();
    let state = o.pop().unwrap();
    (o, state)
}

/// GPU `wlr_final` on `hbar`, the maps `λ1`, `κ0`, `κ1`, `kflags` and the
/// centre state of [`gpu_fit`].
fn gpu_final(
    ctx: &Arc<GpuContext>,
    sc: &Scene,
    push: &WlrPush,
    p: Precision,
    hbar: &[f32],
    fit: [&[f32]; 4],
    state: &[f32],
) -> Vec<Vec<f32>> {
    let push = WlrPush {
        ring_rows: sc.h as u32,
        ..*push
    };
    let pk = reference::gbf_pack::gbf_pack(sc.feat(), sc.var(), sc.spp());
    let mut bound: Vec<Bound> = vec![Bound::In(&pk[0]), Bound::In(&pk[1])];
    bound.extend(sc.color().map(Bound::In));
    bound.extend([sc.vbar(), sc.spp(), hbar].map(Bound::In));
    bound.extend(fit.map(Bound::In));
    bound.push(Bound::In(state));
    bound.extend([Bound::Out(sc.w * sc.h); 5]);
    // The `_vis` kernel's visibility follows the outputs.
    bound.extend(sc.vis().map(|[v, _]| Bound::In(v)));
    run_bound(
        ctx,
        wlr_final::decl(sc.features()),
        p,
        bytemuck::bytes_of(&push),
        (sc.w, sc.h),
        &bound,
        wlr_final::flops_per_pixel(push.radius, sc.features()),
    )
    .unwrap()
    .0
}

/// `k` and the flags of a kflags plane.
fn split_kflags(p: &[f32]) -> (Vec<f32>, Vec<f32>) {
    let k = p.iter().map(|&v| (v as u32 % 16) as f32).collect();
    let f = p.iter().map(|&v| (v as u32 / 16) as f32).collect();
    (k, f)
}

/// GPU `wlr_fit` and `wlr_final` against the twins on one scene; returns a
/// summary line of the agreement numbers. Continuous outputs must pass the
/// §0.3 tolerance on 99% of pixels (wlr_fit's maps in f32: `fit_frac_f32`).
fn compare_wlr(what: &str, sc: &Scene, radius: u32, options: u32) -> String {
    compare_wlr_with(what, sc, radius, options, 0.99)
}

fn compare_wlr_with(
    what: &str,
    sc: &Scene,
    radius: u32,
    options: u32,
    fit_frac_f32: f64,
) -> String {
    let (w, h) = (sc.w, sc.h);
    let n = w * h;
    let push = wlr_push(sc, radius, options);
    let (cfit, hbar) = twin_fit(sc, &push);
    let cfin = twin_final(sc, &push, &cfit, &hbar);
    let mut summary = String::new();
    for (ctx, p, variant) in variants() {
        let tag = format!("{what} {w}x{h} R={radius} opt={options} {variant}");
        let (gfit, state) = gpu_fit(&ctx, sc, &push, p);
        let (gk, gf) = split_kflags(&gfit[4]);
        let (ck, cf) = split_kflags(&cfit[4]);
        // Both rank classes of lib/wlr.glsl's loops (k <= 3, k >= 4).
        let small = ck.iter().filter(|&&k| (1.0..=3.0).contains(&k)).count();
        let large = ck.iter().filter(|&&k| k >= 4.0).count();
        eprintln!("{tag}: {small} pixels with k <= 3, {large} with k >= 4");
        if what == "synthetic" || what == "fixture" {
            // These two scenes compare both loops of each pair with the twin.
            assert!(
                small >= n / 20 && large >= n / 20,
                "{tag}: {small} pixels with k <= 3 and {large} with k >= 4: one rank class barely tested"
            );
        }
        let ak = agreement(&gk, &ck);
        let af = agreement(&gf, &cf);
        assert!(ak >= 0.98, "{tag}: k agreement {ak}");
        assert!(af >= 0.98, "{tag}: wlr_fit flags agreement {af}");
        let mut worst = 1.0f64;
        for j in [0, 1, 2, 3, 5, 6, 7] {
            assert!(
                gfit[j].iter().all(|v| v.is_finite()),
                "{tag} {}: non-finite",
                wlr_fit::OUTPUTS[j]
            );
            let frac = if p == Precision::F32 {
                fit_frac_f32
            } else {
                0.99
            };
            let fr = assert_close(
                &format!("{tag} {}", wlr_fit::OUTPUTS[j]),
                &gfit[j],
                &cfit[j],
                frac,
            );
            worst = worst.min(fr);
        }
        let model = [&cfit[1][..], &cfit[2][..], &cfit[3][..], &gfit[4][..]];
        let gfin = gpu_final(&ctx, sc, &push, p, &hbar, model, &state);
        let afl = agreement(&gfin[4], &cfin[4]);
        assert!(afl >= 0.98, "{tag}: wlr_final flags agreement {afl}");
        let mut worst_fin = 1.0f64;
        for j in 0..4 {
            let bad: Vec<_> = (0..n)
                .filter(|&i| !(gfin[j][i].is_finite() && gfin[j][i] >= 0.0))
                .map(|i| (i, gfin[j][i], cfin[j][i], cfin[4][i]))
                .take(5)
                .collect();
            assert!(
                bad.is_empty(),
                "{tag} {}: non-finite or negative (index, gpu, cpu, flags): {bad:?}",
                wlr_final::OUTPUTS[j]
            );
            let fr = assert_close(
                &format!("{tag} {}", wlr_final::OUTPUTS[j]),
                &gfin[j],
                &cfin[j],
                0.99,
            );
            worst_fin = worst_fin.min(fr);
        }
        let line = format!(
            "{tag}: k {ak:.4} fit-flags {af:.4} fit-continuous(min) {worst:.4} | \
             final-flags {afl:.4} final-continuous(min) {worst_fin:.4}\n"
        );
        eprint!("{line}");
        summary.push_str(&line);
    }
    summary
}

#[test]
fn channel_mean_matches_twin() {
    let ctx = gpu();
    for &(w, h) in SIZES {
        let sc = synthetic(w, h, 5 + w as u64);
        let push = ChannelMeanPush {
            width: w as u32,
            height: h as u32,
            ..Default::default()
        };
        let (a, b, c) = (&sc.planes[7], &sc.planes[14], &sc.planes[3]);
        let mut cpu = vec![0.0f32; w * h];
        reference::channel_mean::channel_mean(&push, a, b, c, &mut cpu);
        for p in precisions() {
            let (out, _) = run_planes(
                &ctx,
                &channel_mean::DECL,
                p,
                bytemuck::bytes_of(&push),
                w,
                h,
                &[a, b, c],
                &[w * h],
                channel_mean::FLOPS_PER_PIXEL,
            )
            .unwrap();
            assert_close(&format!("channel_mean {w}x{h} {p:?}"), &out[0], &cpu, 0.99);
        }
    }
    check_validation(&ctx);
}

#[test]
fn gauss_smooth_matches_twin() {
    let ctx = gpu();
    for &(w, h) in SIZES {
        let sc = synthetic(w, h, 9 + h as u64);
        let mut rng = Rng(3 + w as u64);
        let map: Vec<f32> = (0..w * h).map(|_| (0.01 + rng.uniform()) as f32).collect();
        for sigma in [1.0f32, 1.5, 0.0] {
            let push = SmoothPush {
                width: w as u32,
                height: h as u32,
                radius: gauss_smooth::radius(sigma),
                sigma,
                ..Default::default()
            };
            let mut cpu = vec![0.0f32; w * h];
            reference::gauss_smooth::smooth(&push, &map, sc.spp(), &mut cpu);
            // The twin agrees with the shared routine of linalg.rs.
            if sigma > 0.0 {
                let valid: Vec<bool> = sc.spp().iter().map(|&s| spp_of(s) >= 1.0).collect();
                let lib = reference::linalg::gaussian_smooth(&map, &valid, w, h, sigma as f64);
                for (a, b) in cpu.iter().zip(&lib) {
                    assert!((*a as f64 - b).abs() <= 1e-6 * b.abs().max(1e-6));
                }
            } else {
                for i in 0..w * h {
                    let want = if spp_of(sc.spp()[i]) >= 1.0 {
                        map[i]
                    } else {
                        0.0
                    };
                    assert_eq!(cpu[i], want);
                }
            }
            for p in precisions() {
                // Both passes (gauss_rows, then the column pass).
                let up = |v: &[f32]| GpuBuffer::from_slice(&ctx, "test.in", v).unwrap();
                let (m, spp) = (up(&map), up(sc.spp()));
                let zero = vec![0.0f32; w * h];
                let (s0, s1, o) = (up(&zero), up(&zero), up(&zero));
                let mut batch = Batch::new(&ctx).unwrap();
                gauss_smooth::record(
                    &mut batch,
                    p,
                    w as u32,
                    h as u32,
                    sigma,
                    m.slice(),
                    spp.slice(),
                    [s0.slice(), s1.slice()],
                    o.slice(),
                )
                .unwrap();
                batch.finish().unwrap();
                let out = [o.read_vec::<f32>(w * h).unwrap()];
                assert_close(
                    &format!("gauss_smooth {w}x{h} sigma {sigma} {p:?}"),
                    &out[0],
                    &cpu,
                    0.99,
                );
            }
        }
    }
    check_validation(&ctx);
}

#[test]
fn wlr_synthetic_matches_twin() {
    let sc = synthetic(64, 64, 2024);
    compare_wlr("synthetic", &sc, 5, WLR_DEFAULT_OPTIONS);
    compare_wlr("synthetic", &sc, 9, WLR_DEFAULT_OPTIONS);
    check_validation(&gpu());
}

/// WLR-VIS: the `_vis` kernels (the visibility as a tenth feature) against
/// the twin with it.
#[test]
fn wlr_with_visibility_matches_twin() {
    let sc = synthetic_vis(64, 64, 2025);
    compare_wlr("synthetic", &sc, 5, WLR_DEFAULT_OPTIONS);
    compare_wlr("synthetic", &sc, 9, WLR_DEFAULT_OPTIONS);
    compare_wlr("small", &synthetic_vis(37, 23, 12), 5, WLR_DEFAULT_OPTIONS);
    // Noiseless features (every variance 0): all ten are kept by the TSVD,
    // and the rank is cut to the 9 local coordinates the kernels hold.
    let mut clean = synthetic_vis(32, 32, 7);
    for k in (7..14).chain([20]) {
        clean.planes[k].iter_mut().for_each(|v| *v = 0.0);
    }
    let push = wlr_push(&clean, 5, WLR_DEFAULT_OPTIONS);
    let (fit, _) = twin_fit(&clean, &push);
    let (k, _) = split_kflags(&fit[4]);
    let full = k.iter().filter(|&&k| k == 9.0).count();
    assert!(k.iter().all(|&k| k <= 9.0), "a rank above 9");
    assert!(
        full > 32 * 32 / 2,
        "{full} pixels of rank 9: the cap barely tested"
    );
    // Rank-9 fits everywhere: wlr_fit's f32 maps within tolerance on 98 %
    // (lambda1 0.9893 measured; f64 as everywhere).
    compare_wlr_with("noiseless", &clean, 5, WLR_DEFAULT_OPTIONS, 0.98);
    check_validation(&gpu());
}

#[test]
fn wlr_fixture_matches_twin() {
    let sc = fixture();
    compare_wlr("fixture", &sc, 5, WLR_DEFAULT_OPTIONS);
    compare_wlr("fixture", &sc, 9, WLR_DEFAULT_OPTIONS);
    check_validation(&gpu());
}

#[test]
fn wlr_small_sizes_and_options_match_twin() {
    for &(w, h) in &[(1, 1), (1, 17), (23, 1), (37, 23)] {
        let sc = synthetic(w, h, 77 + (w * h) as u64);
        compare_wlr("small", &sc, 5, WLR_DEFAULT_OPTIONS);
    }
    // The option paths: rejection off, outlier weight off, NONNEG off.
    let mut sc = synthetic(37, 23, 11);
    // Dark, noisy colour so that NONNEG has work to do.
    for ch in 14..17 {
        for v in sc.planes[ch].iter_mut() {
            *v = *v * 0.1 - 0.02;
        }
    }
    for options in [
        WLR_DEFAULT_OPTIONS,
        WLR_OUTLIER_CLAMPED | WLR_NONNEG,
        WLR_REJECT | WLR_NONNEG,
        WLR_REJECT | WLR_OUTLIER_CLAMPED,
    ] {
        compare_wlr("options", &sc, 5, options);
    }
    check_validation(&gpu());
}

/// Degenerate inputs: fireflies, huge and zero variances, constant features,
/// negative colours. Both sides stay finite and agree; outputs, flags and
/// the f64 kernels at the usual tolerances. In f32 the bias model of a
/// firefly centre (colour 1e4) is a residual of ~1e-7 of its colour, below
/// f32 resolution, so wlr_fit's maps only need 90% there.
#[test]
fn extreme_inputs_match_twin() {
    let mut sc = synthetic(37, 23, 123);
    let n = sc.w * sc.h;
    let mut rng = Rng(9);
    for i in 0..n {
        match rng.next_u64() % 12 {
            0 => {
                for ch in 14..17 {
                    sc.planes[ch][i] = 1e4;
                }
                sc.planes[17][i] = 1e6;
            }
            1 => sc.planes[17][i] = 0.0,
            2 => sc.planes[17][i] = 1e12,
            3 => {
                for ch in 14..17 {
                    sc.planes[ch][i] = -0.5;
                }
            }
            _ => {}
        }
    }
    // constant albedo and depth over the left half
    for i in 0..n {
        if i % sc.w < sc.w / 2 {
            for k in 3..7 {
                sc.planes[k][i] = 0.5;
                sc.planes[7 + k][i] = 0.0;
            }
        }
    }
    compare_wlr_with("extreme", &sc, 5, WLR_DEFAULT_OPTIONS, 0.9);
    // All features constant (only pixel coordinates vary) and noise-free.
    let mut flat = synthetic(23, 19, 5);
    for k in 0..14 {
        flat.planes[k]
            .iter_mut()
            .for_each(|v| *v = if k < 7 { 0.25 } else { 0.0 });
    }
    compare_wlr("flat", &flat, 5, WLR_DEFAULT_OPTIONS);
    check_validation(&gpu());
}

#[test]
fn invalid_and_pass_through_pixels() {
    // A 1x1 image: k = 0 pass-through; an isolated valid pixel likewise.
    let sc = synthetic(1, 1, 1);
    let push = wlr_push(&sc, 5, WLR_DEFAULT_OPTIONS);
    let (fit, hbar) = twin_fit(&sc, &push);
    let fin = twin_final(&sc, &push, &fit, &hbar);
    if spp_of(sc.spp()[0]) >= 1.0 {
        assert_eq!(fit[4][0], (16 * FLAG_K0) as f32);
        assert_eq!(fit[0][0], 0.2);
        assert!((fin[3][0] - sc.vbar()[0]).abs() <= 1e-7);
        for ch in 0..3 {
            assert_eq!(fin[ch][0], sc.planes[14 + ch][0].max(0.0));
        }
    }
    // Invalid pixels: mean colour of the valid 3x3 neighbours, mse 0, bit 5.
    let mut sc = synthetic(9, 7, 4);
    sc.planes[18].iter_mut().for_each(|s| *s = 16.0);
    sc.planes[18][3 * 9 + 4] = 0.0;
    sc.planes[18][0] = f32::NAN;
    sc.planes[18][1] = 0.0;
    sc.planes[18][9] = 0.0;
    sc.planes[18][10] = 0.0;
    let push = wlr_push(&sc, 5, WLR_DEFAULT_OPTIONS);
    let (fit, hbar) = twin_fit(&sc, &push);
    let fin = twin_final(&sc, &push, &fit, &hbar);
    let i = 3 * 9 + 4;
    for ch in 0..3 {
        let mut s = 0.0f64;
        for (dx, dy) in [
            (-1i32, -1i32),
            (0, -1),
            (1, -1),
            (-1, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ] {
            let q = ((3 + dy) * 9 + 4 + dx) as usize;
            s += sc.planes[14 + ch][q] as f64;
        }
        assert!((fin[ch][i] as f64 - s / 8.0).abs() < 1e-6);
    }
    assert_eq!((fin[3][i], fin[4][i]), (0.0, 32.0));
    assert!(fit.iter().all(|p| p[i] == 0.0));
    // pixel 0 has no valid neighbour in its 3x3: output 0
    assert_eq!(
        (fin[0][0], fin[1][0], fin[2][0], fin[4][0]),
        (0.0, 0.0, 0.0, 32.0)
    );
    // The GPU agrees on these corner cases too.
    compare_wlr("invalid", &sc, 5, WLR_DEFAULT_OPTIONS);
}

/// §2.6: every fit's weights sum to 1, so a constant image comes back exactly
/// (twin and GPU), whatever path a pixel takes.
#[test]
fn constant_image_is_returned_exactly() {
    let mut sc = synthetic(40, 32, 8);
    let c = [0.37f32, 1.25, 0.0625];
    for ch in 0..3 {
        sc.planes[14 + ch].iter_mut().for_each(|v| *v = c[ch]);
    }
    let push = wlr_push(&sc, 5, WLR_DEFAULT_OPTIONS);
    let (fit, hbar) = twin_fit(&sc, &push);
    let fin = twin_final(&sc, &push, &fit, &hbar);
    let n = sc.w * sc.h;
    let mut fitted = 0;
    for i in 0..n {
        if spp_of(sc.spp()[i]) < 1.0 {
            continue;
        }
        for ch in 0..3 {
            let d = (fin[ch][i] - c[ch]).abs();
            assert!(
                d <= 1e-6 * c[ch],
                "twin pixel {i} ch {ch}: {} vs {}",
                fin[ch][i],
                c[ch]
            );
        }
        let flags = fin[4][i] as u32;
        if flags & (FLAG_FEW | FLAG_K0 | FLAG_SOLVE_FAIL) == 0 {
            fitted += 1;
        }
    }
    assert!(
        fitted as f64 > 0.9 * n as f64,
        "only {fitted} pixels fitted"
    );
    for (ctx, p, _) in variants() {
        let (gfit, state) = gpu_fit(&ctx, &sc, &push, p);
        let model = [&fit[1][..], &fit[2][..], &fit[3][..], &gfit[4][..]];
        let g = gpu_final(&ctx, &sc, &push, p, &hbar, model, &state);
        let tol = if p == Precision::F32 { 1e-5 } else { 1e-6 };
        for i in 0..n {
            if spp_of(sc.spp()[i]) >= 1.0 {
                for ch in 0..3 {
                    assert!(
                        (g[ch][i] - c[ch]).abs() <= tol * c[ch],
                        "{p:?} pixel {i} ch {ch}: {}",
                        g[ch][i]
                    );
                }
            }
        }
    }
}

/// Features in general position without noise (k = D) and a colour that is
/// affine in them: with λ = 0 every well-posed fit reproduces `y_c` exactly.
#[test]
fn affine_image_is_reproduced_with_zero_ridge() {
    let (w, h) = (15, 15);
    let mut rng = Rng(99);
    let mut p = vec![vec![0.0f32; w * h]; 19];
    // Dyadic features (multiples of 1/64) and coefficients: the affine colour
    // is exact in f32.
    let coef = [0.25, -0.125, 0.5, 0.0625, 0.75, -0.375, 0.25, 0.125, -0.25];
    for i in 0..w * h {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        let mut raw = [x, y, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        for k in 0..7 {
            let v = (0.3 * (k + 1) as f64 * x + 0.2 * y * k as f64).sin() + 0.3 * rng.uniform();
            p[k][i] = ((v * 64.0).round() / 64.0) as f32;
            raw[2 + k] = p[k][i] as f64;
        }
        let yv: f64 = 4.0 + raw.iter().zip(&coef).map(|(a, b)| a * b).sum::<f64>();
        for ch in 0..3 {
            p[14 + ch][i] = (yv + ch as f64) as f32;
            assert_eq!(p[14 + ch][i] as f64, yv + ch as f64, "not exact in f32");
        }
        p[18][i] = 4.0;
    }
    let sc = Scene { w, h, planes: p };
    let planes = sc.rw_planes();
    let options = WLR_OUTLIER_CLAMPED | WLR_NONNEG;
    let mut checked = 0;
    for (cx, cy) in [(7, 7), (3, 4), (11, 9), (0, 0), (14, 6)] {
        let ls = rw::local_space(&planes, cx, cy, 5);
        assert_eq!(ls.k, D, "k at ({cx},{cy})");
        let pr = rw::projection(&ls);
        let c = rw::centre(&planes, cx, cy);
        let curv = rw::curvature(&planes, &pr, &c, 5, options);
        assert!(!curv.failed);
        let fits = rw::fits(
            &planes,
            &pr,
            &c,
            &curv.b,
            &[1.0, 2.0, 4.0, 8.0],
            5,
            options,
            0.0,
        );
        for fit in &fits {
            if fit.flags != 0 || fit.npos < 2 * D {
                continue;
            }
            checked += 1;
            for ch in 0..3 {
                assert!(
                    (fit.f[ch] - c.y[ch]).abs() <= 1e-8 * c.y[ch].abs(),
                    "({cx},{cy}) npos {}: {} vs {}",
                    fit.npos,
                    fit.f[ch],
                    c.y[ch]
                );
            }
            assert!(fit.bias.abs() < 1e-8);
        }
    }
    assert!(checked >= 5, "only {checked} well-posed fits");
}

#[test]
fn parametric_fits_recover_the_model() {
    let mut rng = Rng(5);
    for k in 1..=9 {
        for _ in 0..10 {
            let (l0, l1) = (rng.normal() * 0.1, rng.normal() * 0.5);
            let (k0, k1) = (rng.uniform() * 0.01, rng.uniform() * 1e-3);
            let n = 1.0 + 64.0 * rng.uniform();
            let mut bias = [0.0; 5];
            let mut var = [0.0; 5];
            for s in 0..5 {
                let h = rw::TRIAL_H[s];
                bias[s] = l0 + l1 * h * h;
                var[s] = (k0 + k1 * h.powi(-(k as i32))) / n;
            }
            let par = rw::parametric(&bias, &var, k, n);
            let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-9 * scale;
            assert!(
                close(par.lambda0, l0, 1.0),
                "k {k}: λ0 {} vs {l0}",
                par.lambda0
            );
            assert!(
                close(par.lambda1, l1, 1.0),
                "k {k}: λ1 {} vs {l1}",
                par.lambda1
            );
            assert!(close(par.kappa0, k0, (k1 * 5f64.powi(k as i32)).max(k0)));
            assert!(
                close(par.kappa1, k1, k1),
                "k {k}: κ1 {} vs {k1}",
                par.kappa1
            );
        }
    }
}

#[test]
fn h_opt_zeroes_the_mse_derivative() {
    let mut rng = Rng(17);
    let mut tested = 0;
    for _ in 0..400 {
        let k = 1 + (rng.next_u64() % 9) as usize;
        let n = 1.0 + 100.0 * rng.uniform();
        let par = rw::Parametric {
            lambda0: rng.normal(),
            lambda1: rng.normal() * 10f64.powf(-2.0 * rng.uniform()),
            kappa0: rng.uniform() * 1e-2,
            kappa1: rng.uniform() * 10f64.powf(-6.0 * rng.uniform()),
        };
        let c = rw::choose_h(&par, k, n, 0.0, 0.0);
        if c.flags != 0 || c.h_opt >= rw::H_MAX {
            continue; // clamped or a special case: no stationary point
        }
        tested += 1;
        let mse = |h: f64| rw::mse_model(c.lambda1, c.kappa0, c.kappa1, k, n, h);
        let h = c.h_opt;
        let dh = 1e-5 * h;
        let deriv = (mse(h + dh) - mse(h - dh)) / (2.0 * dh);
        // scale: either term of the derivative alone
        let scale = 4.0 * c.lambda1 * c.lambda1 * h.powi(3);
        assert!(
            deriv.abs() <= 1e-6 * scale,
            "k {k}: dMSE/dh = {deriv} at h = {h} (scale {scale})"
        );
        // and it is a minimum
        assert!(mse(h) <= mse(h * 1.01) && mse(h) <= mse(h * 0.99));
    }
    assert!(tested > 100, "only {tested} unclamped cases");
}

#[test]
fn rank_and_bandwidth_bounds() {
    let sc = synthetic(48, 40, 31);
    let planes = sc.rw_planes();
    let mut ranks = [0usize; 10];
    for cy in 0..sc.h {
        for cx in 0..sc.w {
            if !planes.valid(cy * sc.w + cx) {
                continue;
            }
            let ls = rw::local_space(&planes, cx, cy, 5);
            assert!(
                ls.k >= 2usize.min(ls.k_nz) && ls.k <= D,
                "k {} k_nz {}",
                ls.k,
                ls.k_nz
            );
            ranks[ls.k] += 1;
            let pr = rw::projection(&ls);
            let c = rw::centre(&planes, cx, cy);
            let curv = rw::curvature(&planes, &pr, &c, 5, WLR_DEFAULT_OPTIONS);
            assert!(!curv.failed);
            for j in 0..D {
                if j < ls.k {
                    assert!(
                        curv.b[j] > 0.0 && curv.b[j] <= 1.25,
                        "b_{j} = {}",
                        curv.b[j]
                    );
                } else {
                    assert_eq!(curv.b[j], 0.0);
                }
            }
        }
    }
    // The scene exercises several ranks.
    assert!(ranks.iter().filter(|&&c| c > 0).count() >= 2, "{ranks:?}");
}

/// WLR-VIS through the chain: `wlr.extra_features=visibility` on the GPU
/// equals the CPU path (the NL-means of the visibility and the twins),
/// changes the output, and on an input without the layer is an error that
/// names it.
#[test]
fn the_visibility_option_runs_end_to_end() {
    let ctx = gpu();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/night_lights_40_spp64.exr");
    let img = mcdenoise::io::read_stats(&path).unwrap();
    let mut config = bare_chain_config(mcdenoise::Method::Wlr);
    config.options = mcdenoise::Options::parse(&["wlr.extra_features=visibility"]).unwrap();
    let (vis, clean) = run_chain(&ctx, &img, config.clone());
    let (nine, _) = run_chain(&ctx, &img, bare_chain_config(mcdenoise::Method::Wlr));
    let params =
        mcdenoise::methods::wlr::WlrParams::new(mcdenoise::Pass::Final, &config.options).unwrap();
    assert_eq!(params.features, 10);
    let cpu = mcdenoise::methods::wlr::run_cpu(&clean, params).unwrap();
    for c in 0..3 {
        assert_close(
            &format!("wlr.extra_features=visibility, channel {c}"),
            &vis.color.planes[c],
            &cpu.color.planes[c],
            0.99,
        );
    }
    let moved = mcdenoise::metrics::rmse(&vis.color, &nine.color);
    eprintln!("wlr.extra_features=visibility: rMSE against nine features {moved:.3e}");
    assert!(
        moved > 1e-4,
        "the visibility feature changed little ({moved})"
    );

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/dof_checker_64_spp16.exr");
    let img = mcdenoise::io::read_stats(&path).unwrap();
    let run = || -> mcdenoise::Result<()> {
        use mcdenoise::methods::chain::{ChainInput, GpuChain};
        let chain = GpuChain::new(&ctx, ChainInput::of_image(&img), config.clone())?;
        chain.upload(&img)?;
        let mut batch = mcdenoise::gpu::Batch::new(&ctx)?;
        chain.record(&mut batch, None, None)?;
        batch.finish()?;
        Ok(())
    };
    let err = run().expect_err("no visibility layer").to_string();
    assert!(err.contains("visibility layer"), "{err}");
    check_validation(&ctx);
}
