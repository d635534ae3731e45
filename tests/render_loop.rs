//! The adaptive loop (spec §9.3) on the built-in renderer, through the
//! facade: exact sample totals, determinism, the stop flag, and the CLI.

mod common;
use common::*;

use std::process::Command;
use std::sync::atomic::AtomicBool;

use mcdenoise::render::adaptive::{
    final_config, next_budget, render, LoopConfig, StopEstimates, StopRules, CHANGE_SCALE,
};
use mcdenoise::render::{Renderer, Scene};
use mcdenoise::{metrics, Config, Frame, Layer, Method, Pyramid, RgbImage, Temporal};

/// `method`'s defaults without a per-pass cap.
fn config(method: Method, spp: u32, adaptive: bool) -> LoopConfig {
    LoopConfig {
        pass_cap: None,
        ..LoopConfig::new(method, spp, adaptive)
    }
}

/// `config` rendering open-ended under `rules`.
fn open(method: Method, adaptive: bool, rules: StopRules) -> LoopConfig {
    LoopConfig {
        stop: Some(rules),
        ..config(method, 4, adaptive)
    }
}

/// Total samples in the renderer's count plane.
fn samples_of(r: &Renderer) -> f64 {
    let stats = r.statistics().unwrap();
    stats.get(Layer::Spp).unwrap()[0]
        .iter()
        .map(|&s| s as f64)
        .sum()
}

/// A target the reconstruction after pass 0 already meets renders nothing
/// more: 4 spp, one estimate, and the output is that reconstruction.
#[test]
fn a_target_met_after_pass_0_renders_nothing_more() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let (w, h) = (16, 12);
    for adaptive in [true, false] {
        let r = Renderer::new(&ctx, &scene, w, h, 5).unwrap();
        let rules = StopRules {
            target_error: Some(1e9),
            time_limit: None,
            max_spp: 64,
        };
        let mut estimates = Vec::new();
        let out = render(
            &ctx,
            &r,
            &open(Method::Wlr, adaptive, rules),
            &AtomicBool::new(false),
            |p| estimates.extend(p.estimate),
        )
        .unwrap();
        assert_eq!(samples_of(&r), 4.0 * (w * h) as f64);
        assert_eq!(out.samples, 4 * (w * h) as u64);
        assert_eq!(estimates.len(), 1, "{estimates:?}");
        assert!(estimates[0].is_finite() && estimates[0] > 0.0);
    }
    check_validation(&ctx);
}

/// A stop rule scales the final pass's estimate by the factor of what that
/// pass runs: `auto`'s pyramid by default (PYRAMID-ERROR-SCALE), the
/// method's own estimate where the pyramid cannot or does not run.
#[test]
fn the_stop_rule_scales_the_estimate_of_the_final_pass() {
    use mcdenoise::{Config, Pass};
    for m in [
        Method::Wlr,
        Method::Lp,
        Method::Apr,
        Method::Aos,
        Method::Auto,
    ] {
        let info = m.info();
        // The merged estimate is at most the method's (E_f − a·min(E_f, Ef)).
        assert!(info.pyramid_error_scale >= info.error_scale, "{m:?}");
        let mut c = Config::new(m);
        c.pyramid = Pyramid::On;
        assert_eq!(c.error_scale(128, 128), info.pyramid_error_scale, "{m:?}");
        c.pyramid = Pyramid::Off;
        assert_eq!(c.error_scale(128, 128), info.error_scale, "{m:?}");
        c.pyramid = Pyramid::Auto;
        let by_default = if m == Method::Auto {
            info.pyramid_error_scale
        } else {
            info.error_scale
        };
        assert_eq!(c.error_scale(128, 128), by_default, "{m:?}");
        // Too small for the pyramid, or an adaptive pass's map.
        assert_eq!(c.error_scale(8, 8), info.error_scale, "{m:?}");
        c.pass = Pass::Intermediate;
        assert_eq!(c.error_scale(128, 128), info.error_scale, "{m:?}");
        let final_config = final_config(&LoopConfig::new(m, 16, true), Temporal::Off);
        assert_eq!(final_config.error_scale(128, 128), by_default, "{m:?}");
    }
    let auto = Method::Auto.info();
    assert!(auto.pyramid_error_scale > 1.5 * auto.error_scale);
}

/// An open-ended render judges its final reconstruction with the factor of
/// that reconstruction's configuration: WLR with the pyramid's low band
/// takes the pyramid's factor, without it its own.
#[test]
fn an_open_render_scales_the_estimate_its_final_pass_makes() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let wlr = Method::Wlr.info();
    for (pyramid, scale) in [
        (Pyramid::On, wlr.pyramid_error_scale),
        (Pyramid::Off, wlr.error_scale),
    ] {
        let r = Renderer::new(&ctx, &scene, 16, 16, 5).unwrap();
        let rules = StopRules {
            target_error: Some(1e9),
            time_limit: None,
            max_spp: 64,
        };
        let cfg = LoopConfig {
            pyramid,
            ..open(Method::Wlr, true, rules)
        };
        let mut estimates = Vec::new();
        let out = render(&ctx, &r, &cfg, &AtomicBool::new(false), |p| {
            estimates.extend(p.estimate)
        })
        .unwrap();
        let own = mcdenoise::metrics::estimated_rmse(&out.frame.color, &out.frame.error);
        assert_eq!(estimates.len(), 1, "{estimates:?}");
        assert!(own > 0.0);
        let want = scale * own;
        assert!(
            (estimates[0] - want).abs() <= 1e-12 * want,
            "{pyramid:?}: {} against {want}",
            estimates[0]
        );
    }
    check_validation(&ctx);
}

/// An unreachable target spends exactly up to --max-spp and never past it,
/// in whole passes, adaptive or uniform; the estimate falls as it goes, and
/// after pass 0 it is the change since an earlier pass (STOP-CHANGE).
#[test]
fn max_spp_is_never_exceeded() {
    let ctx = gpu();
    let scene = Scene::builtin("soft_shadows").unwrap();
    let (w, h) = (16, 16);
    for (method, adaptive) in [
        (Method::Wlr, true),
        (Method::Lp, true),
        (Method::None, false),
    ] {
        let r = Renderer::new(&ctx, &scene, w, h, 9).unwrap();
        let rules = StopRules {
            target_error: Some(1e-12),
            time_limit: None,
            max_spp: 13,
        };
        let mut estimates = Vec::new();
        let mut passes: Vec<(f64, RgbImage)> = Vec::new();
        let out = render(
            &ctx,
            &r,
            &open(method, adaptive, rules),
            &AtomicBool::new(false),
            |p| {
                estimates.extend(p.estimate);
                passes.push((p.spp, p.frame.unwrap().color.clone()));
            },
        )
        .unwrap();
        // STOP-CHANGE: after pass 0, the change since the latest kept pass
        // (kept: pass 0, then each one at least doubling the last kept)
        // with at most half the samples, else since pass 0.
        let mut kept = vec![0usize];
        for k in 1..passes.len() {
            let (n, f) = &passes[k];
            let base = *kept
                .iter()
                .rev()
                .find(|&&j| passes[j].0 <= n / 2.0)
                .unwrap_or(&kept[0]);
            let m = passes[base].0;
            let want = CHANGE_SCALE * m / (n - m) * metrics::rmse(&passes[base].1, f);
            assert!(
                (estimates[k] - want).abs() <= 1e-12 * want,
                "{method:?} pass {k}: {} against {want}",
                estimates[k]
            );
            if *n >= 2.0 * passes[*kept.last().unwrap()].0 {
                kept.push(k);
            }
        }
        assert_eq!(out.estimate, estimates.last().copied());
        let total = samples_of(&r);
        assert!(total <= 13.0 * (w * h) as f64, "{method:?}: {total}");
        assert_eq!(total, out.samples as f64);
        // Passes stop once less than one sample per pixel is left.
        assert!(total > 12.0 * (w * h) as f64, "{method:?}: {total}");
        assert!(estimates.len() >= 2, "{method:?}: {estimates:?}");
        assert!(
            estimates.last().unwrap() < estimates.first().unwrap(),
            "{method:?}: {estimates:?}"
        );
    }
    check_validation(&ctx);
}

/// A time limit stops the render at the last pass that fits: the whole
/// render takes at most the limit plus one pass.
#[test]
fn the_time_limit_is_honoured_within_one_pass() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let r = Renderer::new(&ctx, &scene, 32, 32, 2).unwrap();
    let limit = std::time::Duration::from_secs_f64(3.0);
    let rules = StopRules {
        target_error: None,
        time_limit: Some(limit),
        max_spp: 100_000,
    };
    let t0 = std::time::Instant::now();
    let mut passes = Vec::new();
    render(
        &ctx,
        &r,
        &open(Method::Wlr, true, rules),
        &AtomicBool::new(false),
        |_| passes.push(t0.elapsed().as_secs_f64()),
    )
    .unwrap();
    let total = t0.elapsed().as_secs_f64();
    let longest = passes
        .windows(2)
        .map(|p| p[1] - p[0])
        .fold(passes[0], f64::max);
    assert!(
        total <= limit.as_secs_f64() + longest,
        "{total:.2} s for a limit of {limit:?} (longest pass {longest:.2} s, {passes:?})"
    );
    assert!(passes.len() >= 2, "{passes:?}");
    check_validation(&ctx);
}

/// STOP-CHANGE: after pass 0 the stop estimate is the method's; after the
/// others, for running means of independent samples (an error that falls
/// as 1/N), the change since an earlier reconstruction is the true rMSE of
/// the newer one times [`CHANGE_SCALE`], whatever the passes' sizes.
#[test]
fn the_change_since_an_earlier_pass_estimates_the_error() {
    let (w, h) = (64, 64);
    let n = w * h;
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let truth: Vec<f64> = (0..3 * n).map(|_| 0.1 + 2.0 * uniform()).collect();
    let mut sums = vec![0.0f64; 3 * n];
    let image = |v: Vec<f32>| {
        let p = |c: usize| v[c * n..(c + 1) * n].to_vec();
        RgbImage::from_planes(w, h, [p(0), p(1), p(2)])
    };
    let reference = image(truth.iter().map(|&t| t as f32).collect());
    let config = Config::new(Method::Wlr);
    let mut estimates = StopEstimates::default();
    let mut spp = 0u32;
    // Doubling passes, then smaller ones, then one far larger.
    for (pass, total) in [4u32, 8, 16, 24, 30, 37, 50, 200].into_iter().enumerate() {
        for _ in spp..total {
            for (s, t) in sums.iter_mut().zip(&truth) {
                // Mean t, standard deviation t/2.
                *s += t * (1.0 + (uniform() - 0.5) * 12f64.sqrt() / 2.0);
            }
        }
        spp = total;
        let mut frame = Frame::empty();
        frame.color = image(sums.iter().map(|s| (s / spp as f64) as f32).collect());
        frame.error = image(vec![0.5f32; 3 * n]);
        let (e, change) = estimates.estimate(&config, &frame, (spp as usize * n) as f64);
        if pass == 0 {
            assert!(!change);
            assert!(e > 0.0);
            assert_eq!(
                e,
                mcdenoise::render::adaptive::stop_estimate(&config, &frame)
            );
            continue;
        }
        assert!(change, "pass {pass}");
        let truth_rmse = metrics::rmse(&frame.color, &reference);
        let ratio = e / (CHANGE_SCALE * truth_rmse);
        assert!(
            (0.85..1.15).contains(&ratio),
            "pass {pass} at {spp} spp: {e} against {truth_rmse} ({ratio})"
        );
    }
}

/// The next budget: doubling with no target, α = 1 after one pass, the
/// measured decay after two, at least a sample per pixel, never past the cap.
#[test]
fn next_budget_follows_the_decay() {
    // No target: double, within the cap.
    assert_eq!(next_budget(&[(400.0, 1.0)], None, 100, 10_000), 400);
    assert_eq!(next_budget(&[(400.0, 1.0)], None, 100, 500), 100);
    assert_eq!(next_budget(&[(500.0, 1.0)], None, 100, 500), 0);
    // α = 1: halving the error needs twice the samples: 400 more.
    assert_eq!(next_budget(&[(400.0, 0.2)], Some(0.1), 100, 10_000), 400);
    // A target nearly met still takes a sample per pixel.
    assert_eq!(next_budget(&[(400.0, 0.1001)], Some(0.1), 100, 10_000), 100);
    // Measured α = 0.5 (4× the samples halved the error): to halve it
    // again takes 4× the samples, capped at doubling.
    let h = [(100.0, 0.4), (400.0, 0.2)];
    assert_eq!(next_budget(&h, Some(0.1), 100, 10_000), 400);
    // Measured α = 2 is clamped to 1.5: 0.2 → 0.18 needs 400·(10/9)^(2/3) − 400.
    let h = [(200.0, 0.8), (400.0, 0.2)];
    let want = (400.0f64 * (0.2f64 / 0.18).powf(1.0 / 1.5) - 400.0).max(100.0);
    assert_eq!(next_budget(&h, Some(0.18), 100, 10_000), want.ceil() as u64);
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

/// `passes` replaces the map method's pass count: two adaptive passes
/// still spend exactly the average, differ from the five of the default
/// schedule, more passes than samples is an error, and the command line
/// refuses `--passes` without `--adaptive` or with a stop rule.
#[test]
fn passes_sets_the_schedule_and_keeps_the_total() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let (w, h) = (24, 20);
    let run = |passes: Option<u32>| {
        let r = Renderer::new(&ctx, &scene, w, h, 3).unwrap();
        let cfg = LoopConfig {
            passes,
            ..config(Method::Wlr, 9, true)
        };
        let out = render(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {}).unwrap();
        let spp = r.statistics().unwrap().get(Layer::Spp).unwrap()[0].clone();
        (out.schedule.unwrap(), spp)
    };
    let (five, spp5) = run(None);
    let (two, spp2) = run(Some(2));
    assert_eq!(five.budgets.len(), 5);
    assert_eq!(two.budgets.len(), 2);
    assert_eq!(two.total(w * h), 9 * (w * h) as u64);
    let total: f64 = spp2.iter().map(|&s| s as f64).sum();
    assert_eq!(total, 9.0 * (w * h) as f64);
    assert!(spp2.iter().all(|&s| s >= 4.0), "pass 0 gives every pixel 4");
    assert_ne!(spp2, spp5, "two maps place samples unlike five");
    // More passes than samples to place is an error, not empty passes.
    let r = Renderer::new(&ctx, &scene, 4, 4, 3).unwrap();
    let cfg = LoopConfig {
        passes: Some(17),
        ..config(Method::Wlr, 5, true)
    };
    let e = render(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {}).unwrap_err();
    assert!(e.to_string().contains("17 adaptive passes"), "{e}");
    check_validation(&ctx);
    let never = std::env::temp_dir().join(format!("mcdenoise-passes-{}.exr", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_mcdenoise"))
        .args([
            "render", "--scene", "cornell", "--size", "8x8", "--spp", "8", "--passes", "2",
            "--output",
        ])
        .arg(&never)
        .output()
        .unwrap();
    assert!(!never.exists(), "nothing rendered");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--passes") && err.contains("--adaptive"),
        "{err}"
    );
    // Nor with a stop rule, which sizes its passes itself.
    let out = Command::new(env!("CARGO_BIN_EXE_mcdenoise"))
        .args([
            "render",
            "--scene",
            "cornell",
            "--size",
            "8x8",
            "--spp",
            "8",
            "--adaptive",
            "--passes",
            "2",
            "--target-error",
            "0.01",
            "--output",
        ])
        .arg(&never)
        .output()
        .unwrap();
    assert!(!never.exists(), "nothing rendered");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--target-error"),
        "{err}"
    );
}

/// `cfg`'s render of `cornell` at 24×20, seed 3: each pixel's samples and
/// the loop's result.
fn cornell_24x20(
    ctx: &std::sync::Arc<mcdenoise::GpuContext>,
    cfg: &LoopConfig,
) -> (Vec<f32>, mcdenoise::render::adaptive::LoopResult) {
    let scene = Scene::builtin("cornell").unwrap();
    let r = Renderer::new(ctx, &scene, 24, 20, 3).unwrap();
    let out = render(ctx, &r, cfg, &AtomicBool::new(false), |_| {}).unwrap();
    let spp = r.statistics().unwrap().get(Layer::Spp).unwrap()[0].clone();
    (spp, out)
}

/// MAP-WLR, AUTO-MAPS: LP's (without MAP-CHECK) and `auto`'s adaptive
/// renders sample exactly where WLR's does, pass for pass, and reconstruct
/// their final images with their own method; `map_method` set to the
/// method itself gives its own maps.
#[test]
fn lp_and_auto_sample_where_wlr_does_unless_told_otherwise() {
    let ctx = gpu();
    let run = |cfg: &LoopConfig| {
        let (spp, out) = cornell_24x20(&ctx, cfg);
        (spp, out.frame.color)
    };
    let (wlr_spp, wlr_color) = run(&config(Method::Wlr, 9, true));
    for m in [Method::Lp, Method::Auto] {
        // LP's own estimate would move part of a pass (MAP-CHECK).
        let cfg = LoopConfig {
            map_check: false,
            ..config(m, 9, true)
        };
        assert_eq!(cfg.mapper(), Method::Wlr, "{m:?}");
        let (spp, color) = run(&cfg);
        assert_eq!(spp, wlr_spp, "{m:?}: the samples of WLR's maps");
        assert_ne!(color, wlr_color, "{m:?}: the final image is its own");
        assert_eq!(LoopConfig::new(m, 9, true).pass_cap, None, "{m:?}");
    }
    let own = LoopConfig::new(Method::Lp, 9, true).with_map_method(Some(Method::Lp));
    assert_eq!(own.pass_cap, Some(4.0), "LP-CAP with LP's own maps");
    // Uncapped, so that only the maps differ from WLR's run.
    let (own_spp, _) = run(&LoopConfig {
        pass_cap: None,
        ..own
    });
    assert_ne!(own_spp, wlr_spp, "LP's own maps differ");
    let own = config(Method::Auto, 9, true).with_map_method(Some(Method::Auto));
    assert_eq!(own.pass_cap, None);
    let (own_spp, _) = run(&own);
    assert_ne!(own_spp, wlr_spp, "auto's own maps differ");
    check_validation(&ctx);
}

/// MAP-CHECK: APR's render with the check spends exactly the average,
/// gives every pixel pass 0's samples, records one share per adaptive pass
/// in `[0, 1]`, renders the same samples twice, and samples unlike the
/// unchecked render when a share is below 1; a render whose maps are its
/// own method's (WLR) is not checked.
#[test]
fn the_final_method_checks_the_maps_of_another() {
    let ctx = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let (w, h) = (24, 20);
    let run = |cfg: &LoopConfig| {
        let (spp, out) = cornell_24x20(&ctx, cfg);
        (spp, out.map_weights)
    };
    let checked = |m| LoopConfig {
        map_check: true,
        ..config(m, 9, true)
    };
    let unchecked = |m| LoopConfig {
        map_check: false,
        ..config(m, 9, true)
    };
    assert!(config(Method::Apr, 9, true).map_check, "APR's default");
    let (spp, weights) = run(&checked(Method::Apr));
    let total: f64 = spp.iter().map(|&s| s as f64).sum();
    assert_eq!(total, 9.0 * (w * h) as f64);
    assert!(spp.iter().all(|&s| s >= 4.0), "pass 0 gives every pixel 4");
    assert_eq!(weights.len(), 5, "{weights:?}");
    assert!(
        weights.iter().all(|w| (0.0..=1.0).contains(w)),
        "{weights:?}"
    );
    let (again, weights_again) = run(&checked(Method::Apr));
    assert_eq!((&again, &weights_again), (&spp, &weights), "deterministic");
    let (plain, none) = run(&unchecked(Method::Apr));
    assert!(none.is_empty());
    if weights.iter().any(|&w| w < 1.0) {
        assert_ne!(plain, spp, "a share below 1 moves samples");
    }
    let (wlr, weights) = run(&checked(Method::Wlr));
    assert!(weights.is_empty(), "WLR's own maps are not checked");
    assert_eq!(wlr, run(&unchecked(Method::Wlr)).0);
    // Open-ended: the reconstruction that judges the stop checks each map.
    let rules = StopRules {
        target_error: Some(1e-12),
        time_limit: None,
        max_spp: 16,
    };
    let mut passes = 0;
    let r = Renderer::new(&ctx, &scene, w, h, 3).unwrap();
    let out = render(
        &ctx,
        &r,
        &open(Method::Apr, true, rules),
        &AtomicBool::new(false),
        |_| passes += 1,
    )
    .unwrap();
    assert_eq!(out.samples, 16 * (w * h) as u64);
    assert_eq!(out.map_weights.len(), passes - 1, "{:?}", out.map_weights);
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
    // --map-method shapes adaptive passes: without --adaptive it is an
    // error, not an option that does nothing.
    let lone = Command::new(bin)
        .args(["render", "--scene", "dof", "--map-method", "wlr", "-o"])
        .arg(dir.join("lone.exr"))
        .output()
        .unwrap();
    assert_eq!(lone.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&lone.stderr).contains("--adaptive"));
    assert!(!dir.join("lone.exr").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// `render --target-error` stops when met and `--figure` writes the panels
/// side by side: input, samples per pixel, reconstruction, error estimate
/// and, with --reference, the reference (4 px apart).
#[test]
fn cli_render_to_a_target_with_a_figure() {
    let bin = env!("CARGO_BIN_EXE_mcdenoise");
    let dir = std::env::temp_dir().join(format!("mcdenoise-target-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fig = dir.join("fig.png");
    let out = Command::new(bin)
        .args([
            "render",
            "--scene",
            "cornell",
            "--size",
            "20x12",
            "--adaptive",
        ])
        .args(["--target-error", "1e9", "--reference", "16", "--figure"])
        .arg(&fig)
        .arg("-o")
        .arg(dir.join("out.exr"))
        .env("MCDENOISE_CACHE", &dir)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{e}");
    assert!(e.contains("pass 1: 4.00 spp, estimated rMSE"), "{e}");
    assert!(e.contains(", true "), "{e}");
    assert!(
        !e.contains("pass 2"),
        "the target was met after pass 0: {e}"
    );
    let decoder = png::Decoder::new(std::fs::File::open(&fig).unwrap());
    let info = decoder.read_info().unwrap().info().clone();
    assert_eq!((info.width, info.height), (5 * 20 + 4 * 4, 12));
    // --spp and --target-error exclude each other.
    let both = Command::new(bin)
        .args([
            "render",
            "--scene",
            "cornell",
            "--spp",
            "8",
            "--target-error",
            "0.1",
            "-o",
        ])
        .arg(dir.join("x.exr"))
        .output()
        .unwrap();
    assert_eq!(both.status.code(), Some(2));
    std::fs::remove_dir_all(&dir).ok();
}
