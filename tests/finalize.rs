//! Statistics finalize: GPU kernels against their scalar twins, and against
//! statistics computed directly from the samples.

mod common;
use common::*;

use mcdenoise::accum::{AccumLayout, Accumulator};
use mcdenoise::gpu::{Batch, GpuBuffer, Precision};
use mcdenoise::image::Layer;
use mcdenoise::methods::stats::{finalize_cpu, finalized_layers, record_finalize, GpuStats};

/// Random samples with a large position offset (to provoke cancellation),
/// varying counts including 0 and 1.
fn accumulate(w: usize, h: usize, seed: u64, offset: f64) -> (Accumulator, Vec<Vec<Vec<f64>>>) {
    let layout = AccumLayout::new(w, h, true, true);
    let mut acc = Accumulator::new(layout);
    let nch = layout.channels().len();
    let mut rng = Rng(seed);
    let mut samples = vec![Vec::new(); w * h];
    for p in 0..w * h {
        let n = match p % 7 {
            0 => 0,
            1 => 1,
            _ => 2 + (rng.next_u64() % 30) as usize,
        };
        for _ in 0..n {
            let v: Vec<f64> = (0..nch)
                .map(|c| {
                    let base = if (10..13).contains(&c) { offset } else { 0.5 };
                    base + rng.normal() * 0.3
                })
                .collect();
            acc.add(p, &v);
            samples[p].push(v);
        }
    }
    (acc, samples)
}

/// Packs the accumulation exactly as a renderer would (planes at the
/// stride) into a GPU buffer.
fn upload_accum(acc: &Accumulator) -> GpuBuffer {
    upload_planes(&acc.layout, &acc.planes())
}

/// Packs planes in layout order at the stride into a GPU buffer.
fn upload_planes(layout: &AccumLayout, planes: &[Vec<f32>]) -> GpuBuffer {
    let stride = layout.plane_stride() as usize;
    let mut bytes = vec![0u8; layout.bytes() as usize];
    for (i, p) in planes.iter().enumerate() {
        bytes[i * stride..i * stride + p.len() * 4].copy_from_slice(bytemuck::cast_slice(p));
    }
    let buf = GpuBuffer::new(&gpu(), "accum", layout.bytes()).unwrap();
    buf.upload(0, &bytes).unwrap();
    buf
}

fn run_gpu(
    w: usize,
    h: usize,
    precision: Precision,
) -> (mcdenoise::image::StatsImage, mcdenoise::image::StatsImage) {
    let ctx = gpu();
    let (acc, _) = accumulate(w, h, 7 + w as u64 * 31 + h as u64, 100.0);
    let layout = acc.layout;
    let buf = upload_accum(&acc);
    let out = GpuStats::new(&ctx, "stats", w, h, &finalized_layers(&layout)).unwrap();
    let mut batch = Batch::new(&ctx).unwrap();
    record_finalize(&mut batch, precision, &layout, buf.slice(), &out).unwrap();
    let timings = batch.finish().unwrap();
    assert!(!timings.is_empty());
    let g = out.download().unwrap();
    check_validation(&ctx);
    (g, finalize_cpu(&layout, &acc.planes()))
}

#[test]
fn gpu_matches_twin_f32_and_f64() {
    for &(w, h) in SIZES {
        for p in [Precision::F32, Precision::F64] {
            if p == Precision::F64 && !gpu().supports_f64() {
                continue;
            }
            let (g, c) = run_gpu(w, h, p);
            for (layer, cp) in c.layers() {
                let gp = g.get(layer).unwrap();
                for (k, (a, b)) in gp.iter().zip(cp).enumerate() {
                    let what = format!("{w}x{h} {p:?} {}.{}", layer.name(), layer.channels()[k]);
                    // Variances of position samples near 100 lose digits in
                    // f32 (sum(x^2) ~ 3e5 vs variance ~ 0.1): f32 is checked
                    // only on the means there; the f64 variant on everything.
                    let cancel = p == Precision::F32
                        && matches!(layer, Layer::PositionVariance | Layer::PositionCovariance);
                    if !cancel {
                        assert_close(&what, a, b, 0.99);
                    }
                }
            }
        }
    }
}

#[test]
fn twin_matches_sample_statistics() {
    let (w, h) = (13, 11);
    // Offset 3 (positions of a unit-sized scene): f32 sums keep ~4 digits of
    // the variance; at offset 100 (the GPU test above) they keep almost none.
    let (acc, samples) = accumulate(w, h, 99, 3.0);
    let layout = acc.layout;
    let img = finalize_cpu(&layout, &acc.planes());
    let pos0 = layout.channel_index(Layer::Position, 0).unwrap();
    for p in 0..w * h {
        let s = &samples[p];
        let n = s.len() as f64;
        assert_eq!(img.get(Layer::Spp).unwrap()[0][p], n as f32);
        for (c, ch) in layout.channels().iter().enumerate() {
            let mean_ref = if n >= 1.0 {
                s.iter().map(|v| v[c]).sum::<f64>() / n
            } else {
                0.0
            };
            let var_ref = if n >= 2.0 {
                s.iter().map(|v| (v[c] - mean_ref).powi(2)).sum::<f64>() / (n - 1.0) / n
            } else {
                0.0
            };
            let mean = img.get(ch.layer).unwrap()[ch.component][p] as f64;
            let var = img.get(ch.layer.variance().unwrap()).unwrap()[ch.component][p] as f64;
            assert!(
                (mean - mean_ref).abs() <= 1e-5 * (1.0 + mean_ref.abs()),
                "mean {c} at {p}"
            );
            // Sums are stored in f32 (as a renderer hands them): positions
            // lose digits to cancellation in Σx² − n·mean².
            let tol = if ch.layer == Layer::Position {
                2e-2
            } else {
                1e-4
            };
            assert!(
                (var - var_ref).abs() <= tol * (var_ref + 1e-4),
                "var {c} at {p}: {var} vs {var_ref}"
            );
        }
        if n >= 2.0 {
            let m: Vec<f64> = (0..3)
                .map(|a| s.iter().map(|v| v[pos0 + a]).sum::<f64>() / n)
                .collect();
            let cov = |a: usize, b: usize| {
                s.iter()
                    .map(|v| (v[pos0 + a] - m[a]) * (v[pos0 + b] - m[b]))
                    .sum::<f64>()
                    / n
            };
            let got = img.get(Layer::PositionCovariance).unwrap();
            for (k, (a, b)) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
                .into_iter()
                .enumerate()
            {
                let r = cov(a, b);
                assert!(
                    (got[k][p] as f64 - r).abs() <= 5e-2 * (0.09 + r.abs()),
                    "cov {k} at {p}"
                );
            }
        }
    }
}

#[test]
fn cancellation_never_gives_negative_variance() {
    // Constant samples with a huge offset: sum(x^2) - n*mean^2 rounds either way.
    let layout = AccumLayout::new(8, 8, true, false);
    let mut acc = Accumulator::new(layout);
    let nch = layout.channels().len();
    for p in 0..64 {
        for _ in 0..(3 + p % 5) {
            acc.add(p, &vec![12345.678 + p as f64 * 0.001; nch]);
        }
    }
    let img = finalize_cpu(&layout, &acc.planes());
    for (layer, planes) in img.layers() {
        if layer.name().ends_with("variance") || layer == Layer::PositionCovariance {
            for p in planes {
                assert!(p
                    .iter()
                    .all(|v| *v >= 0.0 || layer == Layer::PositionCovariance));
            }
        }
    }
    let cov = img.get(Layer::PositionCovariance).unwrap();
    for i in 0..64 {
        for (k, (a, b)) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
            .into_iter()
            .enumerate()
        {
            let d = |j: usize| cov[[0, 3, 5][j]][i] as f64;
            assert!((cov[k][i] as f64).abs() <= (d(a) * d(b)).sqrt() + 1e-12);
        }
    }
}

/// Issue #14: world positions far from the origin (|p| ≈ 1000, a pixel
/// footprint of 0.01, the geometry a few units from the camera) keep their
/// variance and covariance when the renderer accumulates them relative to
/// `position_origin` (the built-in renderer: the lens centre) — in f32 sums
/// and the f32 kernels; accumulated raw, f32 sums cannot hold them.
#[test]
fn positions_far_from_the_origin_keep_their_variance() {
    let (w, h) = (16, 8);
    let ctx = gpu();
    let run = |origin: [f32; 3]| {
        let layout = AccumLayout::new(w, h, true, false).with_position_origin(origin);
        let mut acc = Accumulator::new(layout);
        let mut rng = Rng(5);
        let nch = layout.channels().len();
        let pos0 = layout.channel_index(Layer::Position, 0).unwrap();
        let mut truth = vec![[0.0f64; 6]; w * h];
        for (p, t) in truth.iter_mut().enumerate() {
            let n = 64;
            let mut s: Vec<[f64; 3]> = Vec::new();
            for _ in 0..n {
                let mut v: Vec<f64> = (0..nch).map(|_| 0.5 + 0.1 * rng.normal()).collect();
                let (a, b) = (rng.normal() * 0.01, rng.normal() * 0.01);
                // Geometry a few units from the camera (the origin), 1000
                // units from world zero.
                let q = [1002.0 + p as f64 * 0.01 + a, -699.0 + b, 1203.0 + 0.5 * a];
                v[pos0..pos0 + 3].copy_from_slice(&q);
                acc.add(p, &v);
                s.push(q);
            }
            let m: Vec<f64> = (0..3)
                .map(|c| s.iter().map(|q| q[c]).sum::<f64>() / 64.0)
                .collect();
            let cov = |a: usize, b: usize| {
                s.iter().map(|q| (q[a] - m[a]) * (q[b] - m[b])).sum::<f64>() / 63.0 / 64.0
            };
            // position_variance: of the mean; position_covariance: of the
            // samples, divided by n (input-format.md).
            *t = [
                cov(0, 0),
                cov(1, 1),
                cov(2, 2),
                cov(0, 1) * 63.0,
                cov(0, 2) * 63.0,
                cov(1, 2) * 63.0,
            ];
        }
        let buf = upload_accum(&acc);
        let out = GpuStats::new(&ctx, "stats", w, h, &finalized_layers(&layout)).unwrap();
        let mut batch = Batch::new(&ctx).unwrap();
        record_finalize(&mut batch, Precision::F32, &layout, buf.slice(), &out).unwrap();
        batch.finish().unwrap();
        let img = out.download().unwrap();
        let var = img.get(Layer::PositionVariance).unwrap().to_vec();
        let cov = img.get(Layer::PositionCovariance).unwrap().to_vec();
        let mean = img.get(Layer::Position).unwrap().to_vec();
        // Fraction of pixels whose variance (x) and covariance (xz) are
        // within 5 % of the truth; and the mean is exact to f32.
        let mut good = 0;
        for p in 0..w * h {
            let ok = |got: f32, want: f64| (got as f64 - want).abs() <= 0.05 * want.abs();
            // Covariance planes: xx, xy, xz, yy, yz, zz.
            if ok(var[0][p], truth[p][0]) && ok(cov[2][p], truth[p][4]) {
                good += 1;
            }
            assert!((mean[0][p] as f64 - (1002.0 + p as f64 * 0.01)).abs() < 0.01);
        }
        good as f64 / (w * h) as f64
    };
    let shifted = run([1000.0, -700.0, 1200.0]);
    assert!(shifted >= 0.99, "relative to the origin: {shifted}");
    let raw = run([0.0; 3]);
    assert!(raw < 0.5, "raw f32 sums kept the variance?! {raw}");
    check_validation(&ctx);
}

/// Non-finite and overflowing position sums (a NaN sample, positions of
/// 1e30 whose squares leave f32 range) finalise to a finite covariance
/// without panicking: what f32 cannot hold is 0, a zeroed variance zeroes
/// its covariances (`reference::finalize_covariance::kept`); the kernel in
/// both precisions agrees with the twin.
#[test]
fn non_finite_position_sums_give_a_finite_covariance() {
    let (w, h) = (12, 2);
    let layout = AccumLayout::new(w, h, true, false);
    let mut acc = Accumulator::new(layout);
    let nch = layout.channels().len();
    let mut rng = Rng(3);
    for p in 0..w * h {
        for _ in 0..4 {
            let v: Vec<f64> = (0..nch).map(|_| 0.5 + 0.3 * rng.normal()).collect();
            acc.add(p, &v);
        }
    }
    let mut planes = acc.planes();
    let p0 = layout.channel_index(Layer::Position, 0).unwrap();
    let (sx, sy) = (layout.sum_plane(p0), layout.sum_plane(p0 + 1));
    let (qx, qy) = (layout.sumsq_plane(p0), layout.sumsq_plane(p0 + 1));
    let xy = layout.cross_plane(0).unwrap();
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    // (pixel, plane, value); pixels 10 and 11 keep their samples.
    let edits = [
        (0, sx, nan),
        (1, qx, nan),
        (2, qx, inf),
        (3, sx, inf),
        (4, xy, nan),
        (5, xy, -inf),
        (6, qx, -inf),
        // A camera at 1e30: sums of 4e30, their squares overflow f32.
        (7, sx, 4e30),
        (7, sy, 4e30),
        (7, qx, inf),
        (7, qy, inf),
        (7, xy, inf),
        (8, qy, inf),
        (8, qx, 0.0),
        (8, sx, 0.0),
        (9, layout.count_plane(), nan),
    ];
    for &(p, plane, v) in &edits {
        planes[plane][p] = v;
    }
    let twin = finalize_cpu(&layout, &planes);
    let cov = twin.get(Layer::PositionCovariance).unwrap();
    for (k, c) in cov.iter().enumerate() {
        assert!(c.iter().all(|v| v.is_finite()), "plane {k}: {c:?}");
    }
    // Planes XX XY XZ YY YZ ZZ: a non-finite x variance zeroes XX, XY, XZ.
    for p in [0, 1, 2, 3, 6, 7] {
        for k in [0, 1, 2] {
            assert_eq!(cov[k][p], 0.0, "pixel {p} plane {k}");
        }
    }
    // A NaN or infinite cross sum zeroes that covariance only.
    for p in [4, 5] {
        assert_eq!(cov[1][p], 0.0, "pixel {p}");
        assert!(cov[0][p] > 0.0 && cov[3][p] > 0.0, "pixel {p}");
    }
    // y overflows, x is constant: zero variances, covariance zero.
    assert_eq!((cov[3][8], cov[1][8]), (0.0, 0.0));
    assert!(cov.iter().all(|c| c[9] == 0.0));
    assert!(cov[0][10] > 0.0 && cov[0][11] > 0.0);

    let ctx = gpu();
    let buf = upload_planes(&layout, &planes);
    for p in [Precision::F32, Precision::F64] {
        if p == Precision::F64 && !ctx.supports_f64() {
            continue;
        }
        let out = GpuStats::new(&ctx, "stats", w, h, &finalized_layers(&layout)).unwrap();
        let mut batch = Batch::new(&ctx).unwrap();
        record_finalize(&mut batch, p, &layout, buf.slice(), &out).unwrap();
        batch.finish().unwrap();
        let g = out.download().unwrap();
        let gcov = g.get(Layer::PositionCovariance).unwrap();
        for k in 0..6 {
            assert_close(&format!("{p:?} covariance {k}"), &gcov[k], &cov[k], 1.0);
        }
    }
    check_validation(&ctx);
}
