//! The adaptive loop (spec §9.3) on the built-in renderer, through the
//! facade: exact sample totals, determinism, the stop flag, and the CLI.

mod common;
use common::*;

use std::process::Command;
use std::sync::atomic::AtomicBool;

use mcdenoise::render::adaptive::{render, LoopConfig};
use mcdenoise::render::{Renderer, Scene};
use mcdenoise::{Layer, Method, Options, Precision, Prefilter};

fn config(method: Method, spp: u32, adaptive: bool) -> LoopConfig {
    LoopConfig {
        spp,
        adaptive,
        method,
        prefilter: Prefilter::Auto,
        outliers: mcdenoise::Outliers::Auto,
        pass_cap: None,
        precision: Precision::F32,
        options: Options::default(),
    }
}

/// An adaptive run ends with exactly the requested average: the count plane
/// sums to spp × pixels, and the map has moved samples (counts differ).
#[test]
fn adaptive_run_spends_exactly_the_average() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let (w, h) = (24, 20);
    for method in [Method::Wlr, Method::Lp, Method::None] {
        let r = Renderer::new(&ctx, &scene, w, h, 3).unwrap();
        let out = render(
            &ctx,
            &r,
            &config(method, 9, true),
            &AtomicBool::new(false),
            |_| {},
        )
        .unwrap();
        let stats = r.statistics().unwrap();
        let spp = &stats.get(Layer::Spp).unwrap()[0];
        let total: f64 = spp.iter().map(|&s| s as f64).sum();
        assert_eq!(total, 9.0 * (w * h) as f64, "{method:?}");
        assert!(spp.iter().all(|&s| s >= 4.0), "pass 0 gives every pixel 4");
        let (lo, hi) = spp
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &s| (a.min(s), b.max(s)));
        assert!(
            hi > lo,
            "{method:?}: the map sent samples somewhere ({lo}..{hi})"
        );
        let sched = out.schedule.unwrap();
        assert_eq!(sched.budgets.len(), 5);
        assert!(out.split.render_ms >= 0.0 && out.frame.color.width == w);
        assert!(out.frame.color.planes[0]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0));
    }
    check_validation(&ctx);
}

/// Uniform rendering gives every pixel exactly spp samples; the same seed
/// renders the same image twice.
#[test]
fn uniform_run_is_uniform_and_deterministic() {
    let ctx = gpu();
    let scene = Scene::builtin("soft_shadows").unwrap();
    let run = || {
        let r = Renderer::new(&ctx, &scene, 16, 16, 7).unwrap();
        let out = render(
            &ctx,
            &r,
            &config(Method::Wlr, 6, false),
            &AtomicBool::new(false),
            |_| {},
        )
        .unwrap();
        let stats = r.statistics().unwrap();
        assert!(stats.get(Layer::Spp).unwrap()[0].iter().all(|&s| s == 6.0));
        out.frame.color
    };
    assert_eq!(run(), run());
    check_validation(&ctx);
}

/// A stop request is honoured before the next pass: the loop returns
/// Interrupted.
#[test]
fn stop_flag_interrupts() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let r = Renderer::new(&ctx, &scene, 8, 8, 1).unwrap();
    let err = render(
        &ctx,
        &r,
        &config(Method::Wlr, 8, true),
        &AtomicBool::new(true),
        |_| {},
    )
    .unwrap_err();
    assert!(matches!(err, mcdenoise::Error::Interrupted), "{err}");
}

#[test]
fn cli_render_lists_scenes_and_renders_with_a_reference() {
    let bin = env!("CARGO_BIN_EXE_mcdenoise");
    let out = Command::new(bin)
        .args(["render", "--list-scenes"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    for name in ["cornell", "dof", "motion", "soft_shadows", "mix"] {
        assert!(text.contains(name), "{text}");
    }
    let dir = std::env::temp_dir().join(format!("mcdenoise-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exr = dir.join("out.exr");
    let stats = dir.join("stats.exr");
    let out = Command::new(bin)
        .args([
            "render",
            "--scene",
            "dof",
            "--size",
            "24x16",
            "--spp",
            "8",
            "--adaptive",
        ])
        .args(["--method", "lp", "--reference", "32", "-o"])
        .arg(&exr)
        .arg("--save-stats")
        .arg(&stats)
        .env("MCDENOISE_CACHE", &dir)
        .output()
        .unwrap();
    let (o, e) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{o}\n{e}");
    assert!(o.contains("rMSE"), "{o}");
    // The saved statistics are a valid denoiser input with 8 spp on average.
    let img = mcdenoise::io::read_stats(&stats).unwrap();
    let spp = &img.get(Layer::Spp).unwrap()[0];
    assert_eq!(
        spp.iter().map(|&s| s as f64).sum::<f64>(),
        8.0 * 24.0 * 16.0
    );
    assert!(img.has(Layer::PositionCovariance) && img.has(Layer::Visibility));
    // The reference is cached: a second run finds it.
    let again = Command::new(bin)
        .args([
            "render",
            "--scene",
            "dof",
            "--size",
            "24x16",
            "--spp",
            "4",
            "--reference",
            "32",
        ])
        .arg("-o")
        .arg(dir.join("again.exr"))
        .env("MCDENOISE_CACHE", &dir)
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&again.stderr).contains("(cached)"));
    // Bad input: an unknown scene is a clear error, no output.
    let bad = Command::new(bin)
        .args(["render", "--scene", "no_such_scene", "-o"])
        .arg(dir.join("bad.exr"))
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(!dir.join("bad.exr").exists());
    std::fs::remove_dir_all(&dir).ok();
}
