//! APR's kernel twins (`reference::apr_block`, `reference::apr_gather`:
//! fixed 18-column design, one factorisation per block, error from the
//! factor's inverse) against the definitional reference `reference::apr`
//! (compact design, explicit `M⁻¹` and per-pixel error terms).

mod common;

use common::apr::{image, stats, Img};
use common::Rng;
use mcdenoise::reference::apr::{self as r, Planes};
use mcdenoise::reference::apr_block::{self as b, Inputs};
use mcdenoise::reference::apr_gather;
use mcdenoise::reference::spp_total::{spp_total, spp_total_mean};

fn f64s(v: &[f32]) -> Vec<f64> {
    v.iter().map(|&x| x as f64).collect()
}

/// Channel `ch` of an [`Img`] in f64, for `reference::apr`.
struct RefChannel {
    w: usize,
    h: usize,
    y: Vec<f64>,
    v: Vec<f64>,
    feats: Vec<Vec<f64>>,
    valid: Vec<bool>,
    scales: Vec<f64>,
}

impl RefChannel {
    fn new(img: &Img, ch: usize) -> RefChannel {
        RefChannel {
            w: img.w,
            h: img.h,
            y: f64s(&img.y[ch]),
            v: f64s(&img.v[ch]),
            feats: img.feats.iter().map(|f| f64s(f)).collect(),
            valid: img.spp.iter().map(|&s| s >= 1.0).collect(),
            scales: r::test_scales(&img.spp, img.count_cap),
        }
    }

    fn planes(&self) -> Planes<'_> {
        Planes {
            w: self.w,
            h: self.h,
            y: &self.y,
            v: &self.v,
            feats: &self.feats,
            valid: &self.valid,
            test_scale: Some(&self.scales),
        }
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (a.abs().max(b.abs()) + 1e-12)
}

/// Block by block, stage 1: the same order, `ξ̂`, `tr H`, and outputs
/// `(H y)_i` at every accepted pixel, to 1e-9.
#[test]
fn block_twin_equals_the_reference() {
    for (vis, clamped) in [(true, true), (false, true), (true, false)] {
        let mut img = image(45, 38, 7, vis);
        img.clamped = clamped;
        let shape = r::block_shape(clamped);
        let mut checked = 0;
        for ch in 0..3 {
            let rc = RefChannel::new(&img, ch);
            let (pl, y, v, valid) = (rc.planes(), &rc.y, &rc.v, &rc.valid);
            let inp = img.inputs(ch);
            for c in (0..img.w * img.h).step_by(37) {
                if !valid[c] {
                    continue;
                }
                let d = r::design(&pl, shape, c);
                let fit = r::choose(&d, &pl, y, v);
                let tb = b::block(&inp, c, true, b::EPS);
                assert_eq!(tb.order, fit.order, "c={c} ch={ch}");
                assert_eq!(tb.degenerate, d.degenerate());
                assert!(
                    close(tb.xi, fit.xi, 1e-9),
                    "c={c}: xi {} vs {}",
                    tb.xi,
                    fit.xi
                );
                assert!(
                    close(tb.trace, fit.trace, 1e-9),
                    "c={c}: trace {} vs {}",
                    tb.trace,
                    fit.trace
                );
                let by = r::beta(&d, fit.order, y);
                let s: Vec<f64> = v.iter().map(|v| v.max(0.0).sqrt()).collect();
                let bs = r::beta(&d, fit.order, &s);
                for &q in &d.idx {
                    let x = d.row(&pl, q);
                    let p = by.len();
                    let (ry, rs) = (r::eval(&x[..p], &by), r::eval(&x[..p], &bs));
                    let (ty, ts) = (tb.eval(&inp, c, q, false), tb.eval(&inp, c, q, true));
                    assert!(
                        (ry - ty).abs() <= 1e-9 * (ry.abs() + 1.0),
                        "c={c} q={q}: {ty} vs {ry}"
                    );
                    assert!(
                        (rs - ts).abs() <= 1e-9 * (rs.abs() + 1.0),
                        "c={c} q={q}: {ts} vs {rs}"
                    );
                }
                checked += 1;
            }
        }
        assert!(checked > 100);
    }
}

/// The whole method (two stages, extra centres, gather) from the twins
/// against `reference::apr::channel`: the twins keep the block state and
/// stage planes in f32, as the GPU does, so 1e-4 relative.
#[test]
fn twin_run_equals_the_reference_channel() {
    for clamped in [true, false] {
        let mut img = image(43, 31, 3, true);
        img.clamped = clamped;
        let shape = r::block_shape(clamped);
        let inp: [Inputs; 3] = std::array::from_fn(|ch| img.inputs(ch));
        let (out, _) = apr_gather::run(&inp, 2, b::EPS);
        let mut extras = 0;
        for ch in 0..3 {
            let rc = RefChannel::new(&img, ch);
            let valid = &rc.valid;
            let res = r::channel(&rc.planes(), 2, shape, Some(&img.spp));
            for i in 0..img.w * img.h {
                if !valid[i] {
                    continue;
                }
                let (tc, rc) = (out[ch][i] as f64, res.color[i].max(0.0));
                assert!(
                    (tc - rc).abs() <= 1e-4 * (rc.abs() + 1e-3),
                    "ch={ch} i={i}: colour {tc} vs {rc}"
                );
                let (te, re) = (out[3 + ch][i] as f64, res.error[i]);
                assert!(
                    (te - re).abs() <= 1e-4 * (re.abs() + 1e-6),
                    "ch={ch} i={i}: error {te} vs {re}"
                );
                assert_eq!(
                    out[7 + ch][i] as f64,
                    res.extra[i],
                    "ch={ch} i={i}: extra mask"
                );
                extras += res.extra[i] as usize;
            }
        }
        assert!(extras >= 4, "the spikes become extra centres ({extras})");
    }
}

/// `apr_block` (sparse and extra mode) and `apr_gather` through
/// `record_apr`, both precisions, against the twins' run: continuous
/// outputs within §0.3 on 99 % of the pixels, the extra mask and the chosen
/// orders equal on 98 %. With APR-VIS the twins read the visibility as
/// `wlr::filter_visibility` filters it, the GPU the input's raw one.
#[test]
fn gpu_kernels_match_the_twins() {
    use mcdenoise::gpu::Batch;
    use mcdenoise::methods::apr::{self, AprParams, AprPlanes};
    use mcdenoise::methods::stats::GpuStats;
    let ctx = common::gpu();
    // `bands`: a small budget per submit, so that the sparse blocks and the
    // extra blocks' queue (reset per band) run in several bands.
    for (w, h, vis, clamped, bands, count_cap, filtered) in [
        (45, 38, true, true, false, true, false),
        (29, 17, false, true, false, true, false),
        (1, 9, true, true, false, true, false),
        (45, 38, true, false, false, true, false),
        (45, 38, true, true, true, true, false),
        (45, 38, true, true, false, false, false),
        (45, 38, true, true, false, true, true),
        (29, 17, false, true, false, true, true),
    ] {
        let mut img = image(w, h, 11, vis);
        img.clamped = clamped;
        img.count_cap = count_cap;
        let gs = GpuStats::upload(&ctx, "apr.test", &stats(&img)).unwrap();
        if filtered && vis {
            let zero = vec![0.0; w * h];
            let [g, _] =
                mcdenoise::methods::wlr::filter_visibility(w, h, &img.feats[7], &zero, &img.spp);
            assert_ne!(g, img.feats[7], "the filter changes the visibility");
            img.feats[7] = g;
        }
        let inp: [Inputs; 3] = std::array::from_fn(|ch| img.inputs(ch));
        for precision in common::precisions() {
            let eps = if precision == mcdenoise::gpu::Precision::F64 {
                b::EPS
            } else {
                1e-6
            };
            let (cpu, cpu_state) = apr_gather::run(&inp, 2, eps);
            let planes = AprPlanes::new(&ctx, w, h).unwrap();
            let mut batch = Batch::new(&ctx).unwrap();
            if bands {
                batch.max_flops_per_submit = 8.0 * mcdenoise::kernels::apr_block::flops_per_block();
            }
            apr::record_apr(
                &mut batch,
                precision,
                &gs,
                &planes,
                AprParams {
                    stages: 2,
                    prefilter: false,
                    clamped,
                    pixel_test: img.pixel_test,
                    count_cap,
                    filter_visibility: filtered,
                },
                None,
                None,
            )
            .unwrap();
            batch.finish().unwrap();
            let out = planes.out.download_all().unwrap();
            let what = |k: usize| {
                format!("{w}x{h} {precision:?} clamped={clamped} bands={bands} cap={count_cap} filtered={filtered} plane {k}")
            };
            for k in [0, 1, 2, 3, 4, 5, 6] {
                common::assert_close(&what(k), &out[k], &cpu[k], 0.99);
            }
            for k in 7..10 {
                let a = common::agreement(&out[k], &cpu[k]);
                assert!(a >= 0.98, "{}: extra mask agreement {a}", what(k));
            }
            let (gw, gh) = b::grid(w, h);
            let state = planes
                .state
                .read_vec::<f32>(3 * gw * gh * b::STATE)
                .unwrap();
            let orders = |s: &[f32]| -> Vec<f32> { s.chunks(b::STATE).map(|r| r[0]).collect() };
            let cpu_orders: Vec<f32> = cpu_state.iter().flat_map(|s| orders(s)).collect();
            let a = common::agreement(&orders(&state), &cpu_orders);
            assert!(a >= 0.98, "{w}x{h} {precision:?}: order agreement {a}");
        }
    }
    common::check_validation(&ctx);
}

/// `apr_pack` (APR-PACKED) equals its twin bit for bit, with and without
/// visibility (without it the fourth lane of the second plane is 0).
#[test]
fn apr_pack_matches_its_twin() {
    let ctx = common::gpu();
    let (w, h) = (13usize, 7usize);
    let n = w * h;
    let feats: Vec<Vec<f32>> = (0..8)
        .map(|j| (0..n).map(|i| (j * 100 + i) as f32 * 0.25 - 3.0).collect())
        .collect();
    let refs: [&[f32]; 8] = std::array::from_fn(|j| feats[j].as_slice());
    for vis in [false, true] {
        let push = mcdenoise::shared::AprPush {
            width: w as u32,
            height: h as u32,
            flags: if vis { mcdenoise::shared::APR_VIS } else { 0 },
            ..Default::default()
        };
        let (out, _) = mcdenoise::kernels::run_planes(
            &ctx,
            &mcdenoise::kernels::apr_pack::DECL,
            mcdenoise::gpu::Precision::F32,
            bytemuck::bytes_of(&push),
            w,
            h,
            &refs,
            &[4 * n, 4 * n],
            1.0,
        )
        .unwrap();
        let twin = mcdenoise::reference::apr_pack::apr_pack(refs, vis);
        assert_eq!(out[0], twin[0], "plane a, vis {vis}");
        assert_eq!(out[1], twin[1], "plane b, vis {vis}");
        assert!(vis || out[1].chunks(4).all(|p| p[3] == 0.0));
    }
}

/// `spp_total` against its twin, exactly: counts with invalid pixels (0,
/// below 1, NaN) and fractions, and counts whose total passes 2³² (the
/// carry into the high word).
#[test]
fn spp_total_matches_its_twin() {
    use mcdenoise::kernels::{run_planes, spp_total as k};
    use mcdenoise::shared::SppTotalPush;
    let ctx = common::gpu();
    let mut rng = Rng(5);
    for (w, h, big) in [(37usize, 23usize, false), (64, 64, true), (1, 1, false)] {
        let spp: Vec<f32> = (0..w * h)
            .map(|_| match rng.uniform() {
                _ if big => 100_000.0 + (rng.uniform() * 1000.0).floor() as f32,
                u if u < 0.05 => 0.0,
                u if u < 0.08 => 0.5,
                u if u < 0.1 => f32::NAN,
                u if u < 0.2 => 4.0 + rng.uniform() as f32,
                _ => (1.0 + 64.0 * rng.uniform()).floor() as f32,
            })
            .collect();
        let push = SppTotalPush {
            width: w as u32,
            height: h as u32,
            ..Default::default()
        };
        let (out, _) = run_planes(
            &ctx,
            &k::DECL,
            mcdenoise::gpu::Precision::F32,
            bytemuck::bytes_of(&push),
            w,
            h,
            &[&spp],
            &[k::WORDS],
            k::FLOPS_PER_PIXEL,
        )
        .unwrap();
        let gpu: [u32; 3] = std::array::from_fn(|i| out[0][i].to_bits());
        let twin = spp_total(&spp);
        assert_eq!(gpu, twin, "{w}x{h}");
        assert_eq!(twin[1] > 0, big, "{w}x{h}: the high word");
        let valid = spp.iter().filter(|s| s.is_finite() && **s >= 1.0).count();
        assert_eq!(twin[2] as usize, valid);
        let mean = spp
            .iter()
            .filter(|s| s.is_finite() && **s >= 1.0)
            .map(|&s| s as f64)
            .sum::<f64>()
            / valid as f64;
        let m = spp_total_mean(twin) as f64;
        assert!(
            (m - mean).abs() <= 1e-3 * mean,
            "{w}x{h}: mean {m} against {mean}"
        );
    }
    common::check_validation(&ctx);
}
