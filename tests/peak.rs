//! The device-limit micro-kernels of `mcdenoise bench` (issue #13) against
//! their twins, and the measured limits.

mod common;

use mcdenoise::kernels::{peak_copy, peak_fma, run_planes};
use mcdenoise::reference;
use mcdenoise::shared::PeakPush;

#[test]
fn peak_fma_matches_its_twin() {
    let ctx = common::gpu();
    for (w, h, iterations) in [(64, 3, 16), (100, 1, 1), (1, 1, 300)] {
        let push = PeakPush {
            width: w,
            height: h,
            iterations,
            ..Default::default()
        };
        let mut cpu = vec![0.0f32; (w * h) as usize];
        reference::peak_fma::peak_fma(&push, &mut cpu);
        for p in common::precisions() {
            let (out, timings) = run_planes(
                &ctx,
                &peak_fma::DECL,
                p,
                bytemuck::bytes_of(&push),
                w as usize,
                h as usize,
                &[],
                &[(w * h) as usize],
                peak_fma::flops_per_invocation(iterations),
            )
            .unwrap();
            common::assert_close(&format!("peak_fma {w}x{h} {p:?}"), &out[0], &cpu, 1.0);
            let flops: f64 = timings.iter().map(|t| t.flops).sum();
            let want = peak_fma::flops_per_invocation(iterations) * (w * h) as f64;
            assert_eq!(flops, want, "the timings carry the counted flops");
        }
    }
    common::check_validation(&ctx);
}

#[test]
fn peak_copy_matches_its_twin() {
    let ctx = common::gpu();
    for (w, h) in [(256, 3), (4, 1), (1024, 2)] {
        let push = PeakPush {
            width: w,
            height: h,
            ..Default::default()
        };
        let n = (w * h) as usize;
        let src: Vec<f32> = (0..n).map(|i| i as f32 * 0.5 - 7.0).collect();
        let mut cpu = vec![0.0f32; n];
        reference::peak_copy::peak_copy(&push, &src, &mut cpu);
        assert_eq!(cpu, src);
        let (out, _) = run_planes(
            &ctx,
            &peak_copy::DECL,
            mcdenoise::gpu::Precision::F32,
            bytemuck::bytes_of(&push),
            w as usize / 4,
            h as usize,
            &[&src],
            &[n],
            4.0,
        )
        .unwrap();
        assert_eq!(out[0], cpu, "peak_copy {w}x{h}");
    }
    common::check_validation(&ctx);
}

/// The measured limits are finite and positive, min ≤ median ≤ max.
#[test]
fn the_device_limits_are_measured() {
    let ctx = common::gpu();
    let p = mcdenoise::bench::measure_peak(&ctx, 2).unwrap();
    let mut all = vec![p.fma_f32, p.copy];
    all.extend(p.fma_f64);
    for s in all {
        assert!(s.min > 0.0 && s.min.is_finite());
        assert!(s.min <= s.median && s.median <= s.max);
    }
    assert_eq!(p.flops_for("wlr_fit"), Some(p.fma_f32.median));
    assert_eq!(p.flops_for("wlr_fit_f64"), p.fma_f64.map(|s| s.median));
    assert!(mcdenoise::bench::measure_peak(&ctx, 0).is_err());
    common::check_validation(&ctx);
}
