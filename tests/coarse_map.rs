//! Coarse sample maps (MAP-COARSE): `sample_upsample` against its twin, a
//! coarse map's GPU chain against the CPU path, what the map is made of,
//! the configurations it refuses, and the adaptive loop with it.

mod common;

use common::{assert_maps_agree, check_validation, gpu, precisions, uniform_plane, Rng};
use mcdenoise::bench::synthetic;
use mcdenoise::kernels::{run_planes, sample_upsample};
use mcdenoise::methods::sampling::upsample_push;
use mcdenoise::reference::pyramid_pool::coarse_size;
use mcdenoise::reference::sample_upsample::sample_upsample as upsample_twin;
use mcdenoise::render::adaptive::{render, render_with_final, LoopConfig};
use mcdenoise::render::{Renderer, Scene};
use mcdenoise::{
    Config, Denoiser, Layer, Method, Options, Pass, Pyramid, Source, StatsImage, Temporal,
};
use std::sync::atomic::AtomicBool;

#[test]
fn sample_upsample_matches_its_twin() {
    let ctx = gpu();
    for &(w, h) in &[(32usize, 32usize), (37, 23), (1, 5), (3, 1)] {
        let (cw, ch) = coarse_size(w, h);
        let coarse = uniform_plane(cw * ch, &mut Rng(11 + w as u64), 3.0);
        let push = upsample_push((w, h));
        let mut want = vec![0.0f32; w * h];
        upsample_twin(&push, &coarse, &mut want);
        for (i, v) in want.iter().enumerate() {
            let (x, y) = (i % w, i / w);
            assert_eq!(*v, coarse[(y / 2) * cw + x / 2], "{w}x{h} pixel {i}");
        }
        for prec in precisions() {
            let (g, _) = run_planes(
                &ctx,
                &sample_upsample::DECL,
                prec,
                bytemuck::bytes_of(&push),
                w,
                h,
                &[&coarse],
                &[w * h],
                sample_upsample::FLOPS_PER_PIXEL,
            )
            .unwrap();
            assert_eq!(g[0], want, "{w}x{h} {prec:?}: a copy is exact");
        }
    }
    check_validation(&ctx);
}

/// An adaptive pass's configuration of `method` with a coarse map and
/// `options`.
fn coarse(method: Method, options: &[&str]) -> Config {
    let mut c = Config::new(method);
    c.pass = Pass::Intermediate;
    c.coarse_map = true;
    let opts: Vec<String> = options.iter().map(|s| s.to_string()).collect();
    c.options = Options::parse(&opts).unwrap();
    c
}

fn total(counts: &[u32]) -> u64 {
    counts.iter().map(|&c| c as u64).sum()
}

/// The GPU chain's coarse map spends exactly the budget, as the CPU path
/// does, and their counts agree (the reconstructions differ by f32
/// rounding, so a count may move by one); the outputs are the sanitised
/// input's, as `none`'s.
#[test]
fn the_gpu_map_matches_the_cpu_path() {
    let ctx = gpu();
    let s = synthetic(40, 34, 4, 7);
    let img = &s.stats;
    let budget = (3 * 40 * 34) as u32;
    for method in [Method::Wlr, Method::Lp] {
        let config = coarse(method, &[]);
        let src = Source::of_image(img);
        let g = Denoiser::new(&ctx, src.clone(), config.clone())
            .unwrap()
            .denoise(img, Some(budget))
            .unwrap();
        let c = Denoiser::new_cpu(src.clone(), config)
            .unwrap()
            .denoise(img, Some(budget))
            .unwrap();
        let (gs, cs) = (g.samples.unwrap(), c.samples.unwrap());
        assert_maps_agree(&gs, &cs, budget);
        let none = Denoiser::new(&ctx, src, Config::new(Method::None))
            .unwrap()
            .denoise(img, None)
            .unwrap();
        assert_eq!(g.color.planes, none.color.planes, "{method:?} colour");
    }
    check_validation(&ctx);
}

/// The map is the coarse reconstruction's: without MAP-SMOOTH the four
/// pixels of a block share one priority, so their counts differ by at most
/// two (one from the priority's share, one from SAMPLE-FLOOR's uniform
/// share, each rounded in raster order); with it (the default) they need
/// not; and the map is not the full-resolution one.
#[test]
fn each_block_shares_its_coarse_priority() {
    let ctx = gpu();
    let (w, h) = (40usize, 34usize);
    let s = synthetic(w, h, 4, 8);
    let img = &s.stats;
    let budget = (4 * w * h) as u32;
    let map = |config: Config| {
        Denoiser::new(&ctx, Source::of_image(img), config)
            .unwrap()
            .denoise(img, Some(budget))
            .unwrap()
            .samples
            .unwrap()
    };
    let spread = |counts: &[u32]| {
        let mut most = 0;
        for by in 0..h / 2 {
            for bx in 0..w / 2 {
                let block: Vec<u32> = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|(dx, dy)| counts[(2 * by + dy) * w + 2 * bx + dx])
                    .collect();
                most = most.max(block.iter().max().unwrap() - block.iter().min().unwrap());
            }
        }
        most
    };
    let flat = map(coarse(Method::Wlr, &["sampling.smooth=0"]));
    assert_eq!(total(&flat), budget as u64);
    assert!(
        spread(&flat) <= 2,
        "a block's counts differ by {}",
        spread(&flat)
    );
    let smoothed = map(coarse(Method::Wlr, &[]));
    assert!(
        spread(&smoothed) > 2,
        "MAP-SMOOTH runs at the full resolution: spread {}",
        spread(&smoothed)
    );
    let mut full = Config::new(Method::Wlr);
    full.pass = Pass::Intermediate;
    let full = map(full);
    let moved: u64 = full
        .iter()
        .zip(&smoothed)
        .map(|(&a, &b)| (a as i64 - b as i64).unsigned_abs())
        .sum();
    assert!(moved > budget as u64 / 20, "moved {moved} of {budget}");
    check_validation(&ctx);
}

#[test]
fn the_configurations_it_cannot_run_are_refused() {
    let ctx = gpu();
    let s = synthetic(32, 32, 4, 2);
    let src = Source::of_image(&s.stats);
    let msg = |c: Config, src: &Source| match Denoiser::new(&ctx, src.clone(), c) {
        Ok(_) => panic!("not refused"),
        Err(e) => e.to_string(),
    };
    let mut final_pass = coarse(Method::Wlr, &[]);
    final_pass.pass = Pass::Final;
    assert!(msg(final_pass, &src).contains("MAP-COARSE"));
    assert!(msg(coarse(Method::None, &[]), &src).contains("none"));
    let mut pyramid = coarse(Method::Wlr, &[]);
    pyramid.pyramid = Pyramid::On;
    assert!(msg(pyramid, &src).contains("MAP-COARSE"));
    let mut temporal = coarse(Method::Wlr, &[]);
    temporal.temporal = Temporal::Lp;
    assert!(msg(temporal, &src).contains("MAP-COARSE"));
    let mut tiled = coarse(Method::Wlr, &[]);
    tiled.tile = Some(16);
    assert!(msg(tiled, &src).contains("tiles"));
    let small: StatsImage = synthetic(12, 20, 4, 2).stats;
    assert!(msg(coarse(Method::Wlr, &[]), &Source::of_image(&small)).contains("16x16"));
    // The CPU path refuses what the GPU chain does, when it is made.
    let cpu_msg = |c: Config, src: Source| match Denoiser::new_cpu(src, c) {
        Ok(_) => panic!("not refused"),
        Err(e) => e.to_string(),
    };
    let mut cpu_final = coarse(Method::Wlr, &[]);
    cpu_final.pass = Pass::Final;
    let err = cpu_msg(cpu_final, src);
    assert!(err.contains("adaptive pass"), "{err}");
    let err = cpu_msg(coarse(Method::Wlr, &[]), Source::of_image(&small));
    assert!(err.contains("MAP-COARSE") && err.contains("16x16"), "{err}");
    check_validation(&ctx);
}

/// The adaptive loop with coarse maps renders exactly its samples, places
/// them elsewhere than with full-resolution maps, and reconstructs its final
/// image with the method.
#[test]
fn the_loop_renders_with_coarse_maps() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let (w, h, spp) = (40usize, 32usize, 9u32);
    let run = |coarse_maps: bool| {
        let r = Renderer::new(&ctx, &scene, w, h, 3).unwrap();
        let cfg = LoopConfig {
            coarse_maps,
            ..LoopConfig::new(Method::Wlr, spp, true)
        };
        let out = render(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {}).unwrap();
        assert_eq!(out.samples, spp as u64 * (w * h) as u64);
        let counts = r.statistics().unwrap().get(Layer::Spp).unwrap()[0].clone();
        let sum: f64 = counts.iter().map(|&c| c as f64).sum();
        assert_eq!(
            sum,
            (spp as usize * w * h) as f64,
            "coarse maps {coarse_maps}"
        );
        (counts, out.frame.color)
    };
    let (full, _) = run(false);
    let (with, color) = run(true);
    assert_ne!(full, with, "coarse maps place the samples elsewhere");
    assert!(color.planes.iter().flatten().all(|v| v.is_finite()));
    check_validation(&ctx);
}

/// The command line refuses `--coarse-maps` without `--adaptive`, and on an
/// image too small for it before anything renders.
#[test]
fn the_command_line_refuses_what_it_cannot_run() {
    let dir = tempfile::TempDir::new().unwrap();
    let never = dir.path().join("never.exr");
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_mcdenoise"))
            .args([
                "render",
                "--scene",
                "cornell",
                "--spp",
                "8",
                "--coarse-maps",
            ])
            .args(extra)
            .arg("--output")
            .arg(&never)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{extra:?} ran");
        assert!(!never.exists(), "{extra:?}: nothing rendered");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = run(&["--size", "32x32"]);
    assert!(err.contains("--adaptive"), "{err}");
    let err = run(&["--size", "12x12", "--adaptive"]);
    assert!(err.contains("16x16"), "{err}");
}

/// A library caller's render with coarse maps whose final denoiser keeps
/// temporal state (which a coarse map does not read) is refused before
/// anything renders, as the CLI refuses it.
#[test]
fn the_loop_refuses_temporal_maps_before_it_renders() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let (w, h) = (32usize, 32usize);
    let r = Renderer::new(&ctx, &scene, w, h, 3).unwrap();
    let mut last = Config::new(Method::Wlr);
    last.temporal = Temporal::Lp;
    let last = Denoiser::new(&ctx, Source::Accum(r.layout()), last).unwrap();
    let cfg = LoopConfig {
        coarse_maps: true,
        ..LoopConfig::new(Method::Wlr, 8, true)
    };
    let err = render_with_final(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {}, Some(&last))
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(err.contains("MAP-COARSE"), "{err}");
    let counts = r.statistics().unwrap().get(Layer::Spp).unwrap()[0].clone();
    assert!(counts.iter().all(|&c| c == 0.0), "rendered before refusing");
    // Without the temporal maps the same render runs.
    let cfg = LoopConfig {
        temporal_maps: false,
        ..cfg
    };
    render_with_final(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {}, Some(&last)).unwrap();
    check_validation(&ctx);
}
