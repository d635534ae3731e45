//! The G-buffer prefilter (spec §6): `gbf_sure` and `gbf_filter` on the GPU
//! against their scalar twins (§0.3 tolerances), f32 and f64, and the
//! invariants of §6.4 on the twin routines.

mod common;
use common::*;

use mcdenoise::gpu::{Batch, GpuBuffer};
use mcdenoise::image::{Layer, StatsImage};
use mcdenoise::kernels::{gbf_filter, gbf_pack, gbf_prepare, gbf_sure, run_planes};
use mcdenoise::reference::gbf::{self as rg, Planes};
use mcdenoise::reference::{gbf_filter as rf, gbf_pack as rk, gbf_prepare as rp, gbf_sure as rs};
use mcdenoise::shared::GbfPush;

/// Position (3), position variance (3), covariance (6) and its prepared
/// inverse (6), spp, and 7 features + 7 variances (as the prefilter filters).
struct Scene {
    w: usize,
    h: usize,
    pos: Vec<Vec<f32>>,
    pos_var: Vec<Vec<f32>>,
    cov: Vec<Vec<f32>>,
    inv: Vec<Vec<f32>>,
    spp: Vec<f32>,
    feat: Vec<Vec<f32>>,
    var: Vec<Vec<f32>>,
}

impl Scene {
    fn planes(&self) -> Planes<'_> {
        Planes {
            width: self.w,
            height: self.h,
            pos: std::array::from_fn(|k| self.pos[k].as_slice()),
            pos_var: Some(std::array::from_fn(|k| self.pos_var[k].as_slice())),
            inv: std::array::from_fn(|k| self.inv[k].as_slice()),
            spp: &self.spp,
        }
    }
}

/// A tilted plane and a sphere, positions blurred along a random direction
/// per pixel (defocus-like) with matching covariance and variance; features
/// are noisy functions of the true position; ~2% invalid pixels.
fn synthetic(w: usize, h: usize, seed: u64, blur: f64) -> Scene {
    let mut rng = Rng(seed);
    let n = w * h;
    let mut s = Scene {
        w,
        h,
        pos: vec![vec![0.0; n]; 3],
        pos_var: vec![vec![0.0; n]; 3],
        cov: vec![vec![0.0; n]; 6],
        inv: vec![vec![0.0; n]; 6],
        spp: vec![16.0; n],
        feat: vec![vec![0.0; n]; 7],
        var: vec![vec![0.0; n]; 7],
    };
    for i in 0..n {
        let (x, y) = ((i % w) as f64 * 0.05, (i / w) as f64 * 0.05);
        let z = if (x - 1.0).powi(2) + (y - 1.0).powi(2) < 0.3 {
            0.5
        } else {
            2.0 + 0.2 * x
        };
        let t = [x, y, z];
        let b = blur * (0.2 + rng.uniform());
        let spread = b * b; // per-axis sample variance
        for k in 0..3 {
            s.pos[k][i] = (t[k] + (spread / 16.0).sqrt() * rng.normal()) as f32;
            s.pos_var[k][i] = (spread / 16.0) as f32;
        }
        // XX XY XZ YY YZ ZZ
        s.cov[0][i] = spread as f32;
        s.cov[1][i] = (0.3 * spread) as f32;
        s.cov[3][i] = spread as f32;
        s.cov[5][i] = (0.5 * spread) as f32;
        for j in 0..7 {
            let f = (t[0] * (j + 1) as f64).sin() + t[2];
            let v = 0.01 * blur;
            s.feat[j][i] = (f + v.sqrt() * rng.normal()) as f32;
            s.var[j][i] = v as f32;
        }
        if rng.next_u64() % 50 == 0 {
            s.spp[i] = 0.0;
        }
    }
    let inv = rp::prepare(
        w,
        h,
        std::array::from_fn(|k| s.cov[k].as_slice()),
        std::array::from_fn(|k| s.pos[k].as_slice()),
        &s.spp,
    );
    s.inv = inv;
    s
}

/// The twins of gbf_pack and gbf_filter at `hbar`: 7 features, 7 variances
/// (`second_below`: [`GbfPush::second_below`]).
fn filter_twin(s: &Scene, hbar: &[f32], second_below: f32) -> Vec<Vec<f32>> {
    let p = s.planes();
    let packed = rk::gbf_pack(
        std::array::from_fn(|j| s.feat[j].as_slice()),
        std::array::from_fn(|j| s.var[j].as_slice()),
        &s.spp,
    );
    let mut out = vec![vec![0.0f32; s.w * s.h]; 14];
    rf::gbf_filter(
        &GbfPush {
            second_below,
            ..push(s, 0)
        },
        p.pos,
        p.inv,
        &s.spp,
        hbar,
        std::array::from_fn(|k| packed[k].as_slice()),
        &mut out,
    );
    out
}

fn push(s: &Scene, base: u32) -> GbfPush {
    GbfPush {
        width: s.w as u32,
        height: s.h as u32,
        base,
        ..Default::default()
    }
}

#[test]
fn gbf_prepare_matches_twin() {
    let ctx = gpu();
    for &(w, h) in SIZES {
        let s = synthetic(w, h, 2 + w as u64, 0.1);
        // The separable twin (row sums stored in f32) against the 2-D
        // definition of step 1, in f64.
        for (i, _) in s.spp.iter().enumerate() {
            let def = rg::prepare_pixel(
                std::array::from_fn(|k| s.cov[k].as_slice()),
                std::array::from_fn(|k| s.pos[k].as_slice()),
                &s.spp,
                w,
                h,
                i % w,
                i / w,
            );
            for k in 0..6 {
                let (a, b) = (s.inv[k][i] as f64, def[k]);
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs().max(1e-6),
                    "{w}x{h} pixel {i} entry {k}: separable {a} vs definition {b}"
                );
            }
        }
        for prec in precisions() {
            let up = |v: &[f32]| GpuBuffer::from_slice(&ctx, "test.in", v).unwrap();
            let cov: Vec<GpuBuffer> = s.cov.iter().map(|v| up(v)).collect();
            let pos: Vec<GpuBuffer> = s.pos.iter().map(|v| up(v)).collect();
            let spp = up(&s.spp);
            let zero = vec![0.0f32; w * h];
            let scratch: Vec<GpuBuffer> = (0..7).map(|_| up(&zero)).collect();
            let inv: Vec<GpuBuffer> = (0..6).map(|_| up(&zero)).collect();
            let mut batch = Batch::new(&ctx).unwrap();
            gbf_prepare::record(
                &mut batch,
                prec,
                w as u32,
                h as u32,
                std::array::from_fn(|k| cov[k].slice()),
                std::array::from_fn(|k| pos[k].slice()),
                spp.slice(),
                std::array::from_fn(|k| scratch[k].slice()),
                std::array::from_fn(|k| inv[k].slice()),
            )
            .unwrap();
            batch.finish().unwrap();
            let out: Vec<Vec<f32>> = inv.iter().map(|b| b.read_vec(w * h).unwrap()).collect();
            for k in 0..6 {
                assert_close(
                    &format!("{w}x{h} {prec:?} inv {k}"),
                    &out[k],
                    &s.inv[k],
                    0.99,
                );
            }
        }
    }
    check_validation(&ctx);
}

#[test]
fn gbf_sure_matches_twin() {
    let ctx = gpu();
    for &(w, h) in SIZES {
        let s = synthetic(w, h, 3 + w as u64, 0.1);
        let mut cpu = vec![0.0f32; w * h];
        let p = s.planes();
        rs::gbf_sure(
            &push(&s, 0),
            p.pos,
            p.pos_var.unwrap(),
            p.inv,
            &s.spp,
            &mut cpu,
        );
        let mut inputs: Vec<&[f32]> = Vec::new();
        inputs.extend(s.pos.iter().map(|v| v.as_slice()));
        inputs.extend(s.pos_var.iter().map(|v| v.as_slice()));
        inputs.extend(s.inv.iter().map(|v| v.as_slice()));
        inputs.push(&s.spp);
        for prec in precisions() {
            let (out, _) = run_planes(
                &ctx,
                &gbf_sure::DECL,
                prec,
                bytemuck::bytes_of(&push(&s, 0)),
                w,
                h,
                &inputs,
                &[w * h],
                gbf_sure::flops_per_pixel(),
            )
            .unwrap();
            let a = agreement(&out[0], &cpu);
            println!("{w}x{h} {prec:?}: h_opt agreement {a:.4}");
            assert!(a >= 0.98, "{w}x{h} {prec:?}: h_opt agrees on {a}");
        }
        if w * h > 100 {
            let nonzero = cpu.iter().filter(|&&v| v > 0.0).count();
            assert!(
                nonzero * 4 > w * h,
                "{w}x{h}: the prefilter filters ({nonzero})"
            );
        }
    }
    check_validation(&ctx);
}

#[test]
fn gbf_filter_matches_twin() {
    filter_matches_twin(0.0);
}

/// GBF-SECOND's pass (`second_below` 8) on pixels of 4 and 16 samples: the
/// GPU equals the twin; the pixels with 16 keep their features, and every
/// pixel keeps its variances, exactly; the pixels with 4 are filtered.
#[test]
fn gbf_filter_second_pass_matches_twin() {
    filter_matches_twin(8.0);
}

fn filter_matches_twin(second_below: f32) {
    let ctx = gpu();
    for &(w, h) in SIZES {
        let mut s = synthetic(w, h, 7 + h as u64, 0.1);
        if second_below > 0.0 {
            for (i, n) in s.spp.iter_mut().enumerate() {
                if *n > 0.0 && i % 3 == 0 {
                    *n = 4.0;
                }
            }
        }
        let p = s.planes();
        let mut hopt = vec![0.0f32; w * h];
        rs::gbf_sure(
            &push(&s, 0),
            p.pos,
            p.pos_var.unwrap(),
            p.inv,
            &s.spp,
            &mut hopt,
        );
        let cpu = filter_twin(&s, &hopt, second_below);
        if second_below > 0.0 {
            let mut changed = 0;
            for i in 0..w * h {
                for j in 0..7 {
                    assert_eq!(cpu[7 + j][i], s.var[j][i], "variance {j} at {i}");
                    if s.spp[i] >= second_below {
                        assert_eq!(
                            cpu[j][i], s.feat[j][i],
                            "feature {j} at {i} ({} spp)",
                            s.spp[i]
                        );
                    } else if cpu[j][i] != s.feat[j][i] {
                        changed += 1;
                    }
                }
            }
            let low = s
                .spp
                .iter()
                .filter(|&&n| (1.0..second_below).contains(&n))
                .count();
            assert!(
                w * h < 100 || changed * 2 > low * 7,
                "{w}x{h}: {changed} of {low} x 7 filtered"
            );
        }
        for prec in precisions() {
            let up = |v: &[f32]| GpuBuffer::from_slice(&ctx, "test.in", v).unwrap();
            let bufs = |v: &[Vec<f32>]| -> Vec<GpuBuffer> { v.iter().map(|p| up(p)).collect() };
            // gbf_pack's inputs as whole vec4s (PACK-QUADS).
            let quads =
                |v: &[Vec<f32>]| -> Vec<GpuBuffer> { v.iter().map(|p| up(&padded(p))).collect() };
            let (pos, inv, feat, var) = (bufs(&s.pos), bufs(&s.inv), quads(&s.feat), quads(&s.var));
            let (spp, hbar) = (up(&padded(&s.spp)), up(&hopt));
            let packed: Vec<GpuBuffer> = (0..4).map(|_| up(&vec![0.0; 4 * w * h])).collect();
            // The variance planes hold the input's, as in the chain, where
            // the filter writes over the planes it packed (the second pass
            // leaves them).
            let out: Vec<GpuBuffer> = (0..14)
                .map(|k| {
                    up(&if k < 7 {
                        vec![0.0; w * h]
                    } else {
                        s.var[k - 7].clone()
                    })
                })
                .collect();
            let mut batch = Batch::new(&ctx).unwrap();
            let sl = |v: &[GpuBuffer], k: usize| v[k].slice();
            gbf_pack::record(
                &mut batch,
                prec,
                w as u32,
                h as u32,
                (0, h as u32),
                std::array::from_fn(|k| sl(&feat, k)),
                std::array::from_fn(|k| sl(&var, k)),
                spp.slice(),
                std::array::from_fn(|k| sl(&packed, k)),
            )
            .unwrap();
            gbf_filter::record(
                &mut batch,
                prec,
                w as u32,
                h as u32,
                (0, h as u32),
                0,
                std::array::from_fn(|k| sl(&pos, k)),
                std::array::from_fn(|k| sl(&inv, k)),
                hbar.slice(),
                std::array::from_fn(|k| sl(&packed, k)),
                std::array::from_fn(|k| sl(&out, k)),
                second_below,
            )
            .unwrap();
            batch.finish().unwrap();
            // The packing itself, exactly.
            let twin = rk::gbf_pack(
                std::array::from_fn(|j| s.feat[j].as_slice()),
                std::array::from_fn(|j| s.var[j].as_slice()),
                &s.spp,
            );
            for k in 0..4 {
                assert_eq!(
                    packed[k].read_vec::<f32>(4 * w * h).unwrap(),
                    twin[k],
                    "pack {k}"
                );
            }
            for k in 0..14 {
                assert_close(
                    &format!("{w}x{h} {prec:?} out {k}"),
                    &out[k].read_vec::<f32>(w * h).unwrap(),
                    &cpu[k],
                    0.99,
                );
            }
        }
    }
    check_validation(&ctx);
}

/// `v` followed by NaNs up to a multiple of 4 values: a plane bound as
/// whole vec4s, whose values past the plane must not be packed.
fn padded(v: &[f32]) -> Vec<f32> {
    let mut p = v.to_vec();
    p.resize(v.len().div_ceil(4) * 4, f32::NAN);
    p
}

/// PACK-QUADS: gbf_pack reads four pixels per invocation, across row ends
/// when the width is not a multiple of 4, and in chunks of rows: the packed
/// planes are the twin's exactly, nothing is written past a chunk, and a
/// plane not bound as whole vec4s is an error, not a read past its range.
#[test]
fn gbf_pack_matches_twin_in_chunks_and_partial_quads() {
    let ctx = gpu();
    for &(w, h) in &[(37usize, 41usize), (5, 35), (64, 33), (1, 17), (3, 1)] {
        let s = synthetic(w, h, 11 + w as u64, 0.1);
        let n = w * h;
        let up = |v: &[f32]| GpuBuffer::from_slice(&ctx, "test.in", v).unwrap();
        let quads =
            |v: &[Vec<f32>]| -> Vec<GpuBuffer> { v.iter().map(|p| up(&padded(p))).collect() };
        let (feat, var, spp) = (quads(&s.feat), quads(&s.var), up(&padded(&s.spp)));
        let twin = rk::gbf_pack(
            std::array::from_fn(|j| s.feat[j].as_slice()),
            std::array::from_fn(|j| s.var[j].as_slice()),
            &s.spp,
        );
        for chunk in [16u32, 32, h as u32] {
            // Each chunk into its own ranges, which start at its first row;
            // a sentinel after them must stay.
            let mut batch = Batch::new(&ctx).unwrap();
            let mut outs = vec![];
            for r0 in (0..h as u32).step_by(chunk as usize) {
                let r1 = (r0 + chunk).min(h as u32);
                let len = 4 * (r1 - r0) as usize * w;
                let packed: Vec<GpuBuffer> = (0..4).map(|_| up(&vec![-7.0; len + 4])).collect();
                let sl = |v: &[GpuBuffer], k: usize| v[k].slice();
                gbf_pack::record(
                    &mut batch,
                    mcdenoise::gpu::Precision::F32,
                    w as u32,
                    h as u32,
                    (r0, r1),
                    std::array::from_fn(|k| sl(&feat, k)),
                    std::array::from_fn(|k| sl(&var, k)),
                    spp.slice(),
                    std::array::from_fn(|k| packed[k].slice().sub(0, 4 * len as u64).unwrap()),
                )
                .unwrap();
                outs.push((r0 as usize, len, packed));
            }
            batch.finish().unwrap();
            for (r0, len, packed) in outs {
                for (k, p) in packed.iter().enumerate() {
                    let got = p.read_vec::<f32>(len + 4).unwrap();
                    let want = &twin[k][4 * r0 * w..4 * r0 * w + len];
                    let same = got[..len]
                        .iter()
                        .zip(want)
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    assert!(same, "{w}x{h}, chunks of {chunk}, rows from {r0}: pack {k}");
                    assert_eq!(&got[len..], &[-7.0; 4], "{w}x{h}: written past the chunk");
                }
            }
        }
        // Planes bound at their exact size, when that is not whole vec4s.
        if n % 4 != 0 {
            let exact: Vec<GpuBuffer> = s.feat.iter().map(|p| up(p)).collect();
            let packed: Vec<GpuBuffer> = (0..4).map(|_| up(&vec![0.0; 4 * n])).collect();
            let mut batch = Batch::new(&ctx).unwrap();
            let err = gbf_pack::record(
                &mut batch,
                mcdenoise::gpu::Precision::F32,
                w as u32,
                h as u32,
                (0, h as u32),
                std::array::from_fn(|k| exact[k].slice()),
                std::array::from_fn(|k| var[k].slice()),
                spp.slice(),
                std::array::from_fn(|k| packed[k].slice()),
            );
            assert!(err.is_err(), "{w}x{h}: unpadded planes accepted");
        }
    }
    check_validation(&ctx);
}

/// An image whose packed planes do not fit one binding is packed, then
/// filtered, in chunks of rows: the output is bit-identical to one chunk.
#[test]
fn row_chunks_are_bit_identical() {
    use mcdenoise::gpu::Precision;
    use mcdenoise::methods::gbf::{record_gbf_chunked, GbfPlanes};
    use mcdenoise::methods::stats::GpuStats;
    let ctx = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let img = mcdenoise::io::read_stats(&dir.join("dof_checker_64_spp16.exr")).unwrap();
    let run = |max_binding: u64| {
        let stats = GpuStats::upload(&ctx, "test.stats", &img).unwrap();
        // GBF-SECOND's pass (the fixture has 16 spp) and GBF-NLM too.
        let settings = mcdenoise::methods::gbf::GbfSettings {
            second_below: 32.0,
            albedo_nlm: true,
        };
        let planes = GbfPlanes::new(&ctx, img.width, img.height, None, settings).unwrap();
        let mut batch = Batch::new(&ctx).unwrap();
        record_gbf_chunked(&mut batch, Precision::F32, &stats, &planes, max_binding).unwrap();
        let timings = batch.finish().unwrap();
        let filters = timings.iter().filter(|t| t.kernel == "gbf_filter").count();
        (stats.download().unwrap(), filters)
    };
    let (one, n1) = run(u64::MAX);
    // 32 rows of 16-byte pixels: chunks of 16 rows (the smallest).
    let (many, n16) = run(32 * 16 * img.width as u64);
    // Two passes (GBF-SECOND) of each.
    assert_eq!(n1, 2, "one chunk");
    assert_eq!(n16, 2 * img.height.div_ceil(16), "chunks of 16 rows");
    for layer in [
        Layer::Normal,
        Layer::NormalVariance,
        Layer::Albedo,
        Layer::AlbedoVariance,
        Layer::Depth,
        Layer::DepthVariance,
    ] {
        let (a, b) = (one.get(layer).unwrap(), many.get(layer).unwrap());
        for (c, (pa, pb)) in a.iter().zip(b).enumerate() {
            let bits = |p: &[f32]| p.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(pa), bits(pb), "{layer:?} channel {c}");
        }
        // And the prefilter did change the features.
        assert_ne!(a, img.get(layer).unwrap(), "{layer:?} unfiltered");
    }
    check_validation(&ctx);
}

#[test]
fn sure_invariants() {
    let s = synthetic(20, 20, 5, 0.1);
    let p = s.planes();
    for (cx, cy) in [(10, 10), (0, 0), (19, 7)] {
        let c = cy * s.w + cx;
        if !p.valid(c) {
            continue;
        }
        let vbar = (0..3).map(|k| s.pos_var[k][c] as f64).sum::<f64>() / 3.0;
        let sure = rg::sure(&p, cx, cy);
        assert_eq!(sure[0], vbar, "SURE(0) = vbar");
        let nb = rg::neighbours(&p, cx, cy);
        // div -> 3 as h -> 0 (only the centre keeps weight).
        let (_, div) = rg::filter_position(&p, &nb, 1e-4);
        assert!((div - 3.0).abs() < 1e-9, "div at h -> 0: {div}");
        // The analytic divergence equals a central difference of p^ in p_c
        // with S~ held fixed.
        for &h in &[0.4, 1.2, 2.0] {
            let (_, div) = rg::filter_position(&p, &nb, h);
            let mut fd = 0.0;
            for k in 0..3 {
                let eps = 1e-6;
                let shift = |e: f64| {
                    let mut nb2 = nb.clone();
                    let inv_c = p.inv_cov(c);
                    for n in nb2.iter_mut() {
                        if n.q == c {
                            continue;
                        }
                        n.delta[k] -= e;
                        let inv_q = p.inv_cov(n.q);
                        let m: [f64; 6] = std::array::from_fn(|j| inv_c[j] + inv_q[j]);
                        n.m_delta = rg::mul(m, n.delta);
                        n.d = n.delta.iter().zip(n.m_delta).map(|(a, b)| a * b).sum();
                    }
                    // p^ relative to the moved centre: the centre's own
                    // position enters with weight 1.
                    let mut w_sum = 0.0;
                    let mut acc = 0.0;
                    for n in &nb2 {
                        let w = rg::weight(n, h);
                        let pk = if n.q == c {
                            p.position(c)[k] + e
                        } else {
                            p.position(n.q)[k]
                        };
                        w_sum += w;
                        acc += w * pk;
                    }
                    acc / w_sum
                };
                fd += (shift(eps) - shift(-eps)) / (2.0 * eps);
            }
            assert!(
                (div - fd).abs() <= 1e-5 * fd.abs().max(1.0),
                "h {h}: div {div} vs fd {fd}"
            );
        }
    }
}

#[test]
fn zero_position_variance_is_passed_through() {
    let mut s = synthetic(24, 18, 9, 0.0);
    for k in 0..3 {
        s.pos_var[k].iter_mut().for_each(|v| *v = 0.0);
    }
    let p = s.planes();
    let mut hopt = vec![1.0f32; s.w * s.h];
    rs::gbf_sure(
        &push(&s, 0),
        p.pos,
        p.pos_var.unwrap(),
        p.inv,
        &s.spp,
        &mut hopt,
    );
    assert!(hopt.iter().all(|&v| v == 0.0), "every h_opt = 0");
    let out = filter_twin(&s, &hopt, 0.0);
    for j in 0..7 {
        assert_eq!(out[j], s.feat[j]);
        assert_eq!(out[7 + j], s.var[j]);
    }
}

#[test]
fn outputs_are_convex_combinations() {
    let s = synthetic(30, 30, 13, 0.2);
    let p = s.planes();
    let hbar = vec![1.5f32; s.w * s.h];
    let out = filter_twin(&s, &hbar, 0.0);
    for y in 0..s.h {
        for x in 0..s.w {
            let q = y * s.w + x;
            if !p.valid(q) {
                continue;
            }
            for j in 0..7 {
                let (mut lo, mut hi) = (f32::MAX, f32::MIN);
                for qy in y.saturating_sub(3)..(y + 4).min(s.h) {
                    for qx in x.saturating_sub(3)..(x + 4).min(s.w) {
                        if p.valid(qy * s.w + qx) {
                            lo = lo.min(s.feat[j][qy * s.w + qx]);
                            hi = hi.max(s.feat[j][qy * s.w + qx]);
                        }
                    }
                }
                let v = out[j][q];
                assert!(
                    v >= lo - 1e-6 && v <= hi + 1e-6,
                    "({x},{y}) {j}: {v} not in [{lo}, {hi}]"
                );
                // Filtering never raises the variance above the largest input one.
                assert!(out[7 + j][q] <= s.var[j][q] * 1.0001 + 1e-12);
            }
        }
    }
}

/// The whole prefilter + WLR on the fixture (it has position layers): GPU
/// and twins agree, and the prefilter lowers the error against the reference.
#[test]
fn prefilter_chain_on_the_fixture() {
    use mcdenoise::methods::{denoise, Backend, DenoiseRequest, Method, Prefilter};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let img = mcdenoise::io::read_stats(&dir.join("dof_checker_64_spp16.exr")).unwrap();
    assert!(img.has(Layer::PositionCovariance));
    let reference = mcdenoise::io::read_rgb(&dir.join("dof_checker_64_ref.exr")).unwrap();
    let run = |backend: Backend, prefilter: Prefilter, second: &str| {
        let mut req = DenoiseRequest::new(Method::Wlr);
        req.backend = backend;
        req.prefilter = prefilter;
        req.options = mcdenoise::Options::parse(&[format!("gbf.second_below={second}")]).unwrap();
        denoise(Some(&gpu()), &img, &req).unwrap().color
    };
    let g = run(Backend::Gpu, Prefilter::Auto, "8");
    let c = run(Backend::Cpu, Prefilter::Auto, "8");
    for k in 0..3 {
        assert_close(&format!("colour {k}"), &g.planes[k], &c.planes[k], 0.99);
    }
    // The CPU path reads `gbf.second_below` (16 spp < 32: every pixel is
    // filtered twice).
    assert_ne!(run(Backend::Cpu, Prefilter::Auto, "32").planes, c.planes);
    let off = run(Backend::Cpu, Prefilter::Off, "8");
    let e =
        |x: &mcdenoise::image::RgbImage| mcdenoise::metrics::compare(x, &reference).unwrap().rmse;
    println!(
        "fixture WLR rMSE: prefilter {:.5}, off {:.5}",
        e(&c),
        e(&off)
    );
    assert!(e(&c) < e(&off), "prefilter {} vs off {}", e(&c), e(&off));
    check_validation(&gpu());
}

/// The statistics a GPU chain with no method prefilters from the 16-spp
/// fixture, with `gbf.second_below` and `gbf.albedo_nlm` as given.
fn chain_stats(second: f32, nlm: &str, pass: mcdenoise::Pass) -> StatsImage {
    use mcdenoise::{Config, Denoiser, Method, Prefilter, Source};
    let img = mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap();
    let mut cfg = Config::new(Method::None);
    cfg.prefilter = Prefilter::On;
    cfg.pass = pass;
    cfg.options = mcdenoise::Options::parse(&[
        format!("gbf.second_below={second}"),
        format!("gbf.albedo_nlm={nlm}"),
    ])
    .unwrap();
    let d = Denoiser::new(&gpu(), Source::of_image(&img), cfg).unwrap();
    d.denoise_with_statistics(&img, None).unwrap().1
}

/// The fixture prefiltered by the twins (`gbf::run_cpu`) with `settings`.
fn twin_stats(settings: mcdenoise::methods::gbf::GbfSettings) -> StatsImage {
    let img = mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap();
    let (mut twin, _) = mcdenoise::methods::prepare::prepare_cpu(&img);
    mcdenoise::methods::gbf::run_cpu(&mut twin, settings).unwrap();
    twin
}

const FEATURE_LAYERS: [Layer; 6] = [
    Layer::Normal,
    Layer::Albedo,
    Layer::Depth,
    Layer::NormalVariance,
    Layer::AlbedoVariance,
    Layer::DepthVariance,
];

/// Every plane of layer `l` of `gpu` within §0.3 of the twins'.
fn assert_layer_close(gpu: &StatsImage, twin: &StatsImage, l: Layer) {
    for (c, (g, t)) in gpu
        .get(l)
        .unwrap()
        .iter()
        .zip(twin.get(l).unwrap())
        .enumerate()
    {
        assert_close(&format!("{} {c}", l.name()), g, t, 0.99);
    }
}

/// A final reconstruction's prefiltered statistics (`chain_stats`), after
/// checking every feature layer against the twins run with the same
/// settings.
fn final_chain_matching_twin(second_below: f32, albedo_nlm: bool) -> StatsImage {
    use mcdenoise::methods::gbf::GbfSettings;
    let nlm = if albedo_nlm { "on" } else { "off" };
    let chain = chain_stats(second_below, nlm, mcdenoise::Pass::Final);
    let twin = twin_stats(GbfSettings {
        second_below,
        albedo_nlm,
    });
    for l in FEATURE_LAYERS {
        assert_layer_close(&chain, &twin, l);
    }
    chain
}

/// GBF-SECOND through the chain: the statistics a GPU chain prefilters with
/// `gbf.second_below=32` (every pixel of the 16-spp fixture filtered twice)
/// equal the twins' (`gbf::run_cpu`), and differ from one pass's; an
/// adaptive pass's (intermediate) reconstruction runs one pass (and no
/// GBF-NLM).
#[test]
fn second_pass_in_the_chain_matches_twins() {
    use mcdenoise::Pass;
    let one = chain_stats(0.0, "off", Pass::Final);
    let two = final_chain_matching_twin(32.0, false);
    let intermediate = chain_stats(32.0, "on", Pass::Intermediate);
    for l in FEATURE_LAYERS {
        let variance = l.variance().is_none();
        let same = two.get(l).unwrap() == one.get(l).unwrap();
        // The features change; their variances stay the first pass's.
        assert_eq!(same, variance, "{}", l.name());
        assert_eq!(intermediate.get(l), one.get(l), "{} intermediate", l.name());
    }
    check_validation(&gpu());
}

/// GBF-NLM through the chain: the albedo's NL-means after the prefilter
/// equals the twins', changes the albedo and its variance and nothing
/// else, and moves no albedo value further than 2 of its standard errors
/// (the clamp) from the prefilter's.
#[test]
fn albedo_nlm_in_the_chain_matches_twins() {
    let off = chain_stats(0.0, "off", mcdenoise::Pass::Final);
    let on = final_chain_matching_twin(0.0, true);
    for l in FEATURE_LAYERS {
        let albedo = matches!(l, Layer::Albedo | Layer::AlbedoVariance);
        assert_eq!(
            on.get(l).unwrap() == off.get(l).unwrap(),
            !albedo,
            "{}",
            l.name()
        );
    }
    let (a_on, a_off) = (
        on.get(Layer::Albedo).unwrap(),
        off.get(Layer::Albedo).unwrap(),
    );
    let v_off = off.get(Layer::AlbedoVariance).unwrap();
    let (mut moved, mut clamped) = (0, 0);
    for c in 0..3 {
        for i in 0..a_on[c].len() {
            let d = (a_on[c][i] - a_off[c][i]).abs();
            let se = 2.0 * v_off[c][i].max(0.0).sqrt();
            assert!(
                d <= se * (1.0 + 1e-5) + 1e-7,
                "channel {c} pixel {i}: moved {d}, bound {se}"
            );
            moved += usize::from(d > 0.0);
            clamped += usize::from(d > 0.0 && d >= se * (1.0 - 1e-5));
        }
    }
    eprintln!("albedo values moved {moved}, at the clamp {clamped}");
    assert!(moved > 0 && clamped > 0, "moved {moved}, clamped {clamped}");
    check_validation(&gpu());
}

/// GBF-PD: covariances whose pairwise entries pass Cauchy–Schwarz but whose
/// 3×3 matrix is indefinite (xx = yy = zz = 1, xy = xz = 1, yz = −1: det −4)
/// must not turn the filtered features into NaN, on the GPU or the CPU (a
/// 16-spp render of the built-in motion scene had 44 such pixels).
#[test]
fn indefinite_covariance_gives_finite_features() {
    use mcdenoise::{Config, Denoiser, Method, Prefilter, Source};
    let mut img = mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap();
    let n = img.pixel_count();
    let mut cov = img.get(Layer::PositionCovariance).unwrap().to_vec();
    for i in (0..n).filter(|i| (i / 64) % 8 < 4) {
        for (k, v) in [1.0, 1.0, 1.0, 1.0, -1.0, 1.0].into_iter().enumerate() {
            cov[k][i] = v;
        }
    }
    img.set(Layer::PositionCovariance, cov);
    let ctx = gpu();
    let mut cfg = Config::new(Method::Wlr);
    cfg.prefilter = Prefilter::On;
    let d = Denoiser::new(&ctx, Source::of_image(&img), cfg.clone()).unwrap();
    let f = d.denoise(&img, None).unwrap();
    let stats = d.statistics().unwrap();
    let cpu = Denoiser::new_cpu(Source::of_image(&img), cfg)
        .unwrap()
        .denoise(&img, None)
        .unwrap();
    for l in [Layer::Normal, Layer::Albedo, Layer::Depth] {
        for p in stats.get(l).unwrap() {
            assert!(p.iter().all(|v| v.is_finite()), "{} not finite", l.name());
        }
    }
    for c in 0..3 {
        assert!(f.color.planes[c].iter().all(|v| v.is_finite()));
        assert!(cpu.color.planes[c].iter().all(|v| v.is_finite()));
    }
    check_validation(&ctx);
}

/// AOS-NO-GBF (`Prefilter::resolve`): with `auto`, AOS skips the G-buffer
/// prefilter on an input that has the position layers (its own NL-means
/// filters every feature), the other methods run it, and `on` still runs
/// it for AOS. The CPU path resolves `auto` the same way (its AOS output
/// equals the one with the prefilter off).
#[test]
fn aos_skips_the_prefilter_by_default() {
    use mcdenoise::methods::{denoise, Backend, DenoiseRequest, Method, Prefilter};
    use mcdenoise::{Config, Denoiser, Source};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let img = mcdenoise::io::read_stats(&dir.join("dof_checker_64_spp16.exr")).unwrap();
    assert!(img.has(Layer::PositionCovariance));
    let ctx = gpu();
    for (method, prefilter, runs) in [
        (Method::Aos, Prefilter::Auto, false),
        (Method::Aos, Prefilter::On, true),
        (Method::Wlr, Prefilter::Auto, true),
        (Method::Lp, Prefilter::Auto, true),
        (Method::Apr, Prefilter::Auto, true),
        (Method::None, Prefilter::Auto, false),
    ] {
        let mut config = Config::new(method);
        config.prefilter = prefilter;
        let d = Denoiser::new(&ctx, Source::of_image(&img), config).unwrap();
        assert_eq!(d.prefiltered(), runs, "{method:?} with {prefilter:?}");
    }
    let cpu = |prefilter: Prefilter| {
        let mut req = DenoiseRequest::new(Method::Aos);
        req.backend = Backend::Cpu;
        req.prefilter = prefilter;
        denoise(Some(&ctx), &img, &req).unwrap().color
    };
    let (auto, off, on) = (
        cpu(Prefilter::Auto),
        cpu(Prefilter::Off),
        cpu(Prefilter::On),
    );
    assert_eq!(auto.planes, off.planes, "CPU AOS: auto is off");
    assert_ne!(auto.planes, on.planes, "CPU AOS: on prefilters");
    check_validation(&ctx);
}
