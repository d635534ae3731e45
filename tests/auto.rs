//! `--method auto` (AUTO-BLEND): its kernels against their twins, the
//! blend's invariants, and the whole method on the committed fixture: GPU
//! against the CPU twin, and against its members.

mod common;

use std::path::Path;

use common::{assert_close, check_validation, gpu, precisions, Rng};
use mcdenoise::kernels::{auto_blend, auto_score, run_planes};
use mcdenoise::methods::{denoise, Backend, DenoiseOutput, DenoiseRequest};
use mcdenoise::reference;
use mcdenoise::shared::{AutoPush, AUTO_MAPS, AUTO_MEMBERS};
use mcdenoise::{io, metrics, Method, Precision, StatsImage};

fn run(
    img: &StatsImage,
    method: Method,
    backend: Backend,
    prec: Precision,
    maps: bool,
) -> DenoiseOutput {
    let mut req = DenoiseRequest::new(method);
    req.backend = backend;
    req.precision = prec;
    req.error = maps;
    req.debug = maps;
    denoise(Some(&gpu()), img, &req).unwrap()
}

/// Three members' colours and errors (18 planes, colours first), random
/// around a common image, with a non-finite colour and error at two pixels.
fn members(w: usize, h: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = Rng(seed);
    let n = w * h;
    let base: Vec<f64> = (0..n)
        .map(|i| 0.2 + ((i % w) as f64 * 0.3).sin().abs())
        .collect();
    let mut planes: Vec<Vec<f32>> = Vec::new();
    for _ in 0..AUTO_MEMBERS {
        for _ in 0..3 {
            planes.push(
                (0..n)
                    .map(|i| (base[i] * (1.0 + 0.2 * rng.normal())) as f32)
                    .collect(),
            );
        }
    }
    for _ in 0..AUTO_MEMBERS {
        for _ in 0..3 {
            planes.push(
                (0..n)
                    .map(|_| (1e-4 * rng.uniform().powi(3) * 100.0) as f32)
                    .collect(),
            );
        }
    }
    planes[4][7] = f32::NAN;
    planes[12][9] = f32::INFINITY;
    planes
}

fn rgb(p: &[Vec<f32>], m: usize) -> [&[f32]; 3] {
    [&p[3 * m], &p[3 * m + 1], &p[3 * m + 2]]
}

/// The push constants of a `w × h` image and the twin's maps of `planes`.
fn twin_maps(planes: &[Vec<f32>], w: usize, h: usize) -> (AutoPush, [Vec<f32>; AUTO_MAPS]) {
    let push = AutoPush {
        width: w as u32,
        height: h as u32,
        ..Default::default()
    };
    let colors = std::array::from_fn(|m| rgb(planes, m));
    let errors = std::array::from_fn(|m| rgb(planes, AUTO_MEMBERS + m));
    let mut maps: [Vec<f32>; AUTO_MAPS] = std::array::from_fn(|_| vec![0.0; w * h]);
    reference::auto_score::auto_score(&push, colors, errors, &mut maps);
    (push, maps)
}

#[test]
fn auto_kernels_match_twins() {
    let ctx = gpu();
    let (w, h) = (37, 21);
    let n = w * h;
    let planes = members(w, h, 5);
    let (push, maps) = twin_maps(&planes, w, h);
    let colors = std::array::from_fn(|m| rgb(&planes, m));
    let errors = std::array::from_fn(|m| rgb(&planes, AUTO_MEMBERS + m));
    // Smoothed maps stand-in: the maps with some pixels zero (no score).
    let mut smoothed = maps.clone();
    smoothed[1][3] = 0.0;
    let mut out: [Vec<f32>; 6] = std::array::from_fn(|_| vec![0.0; n]);
    {
        let [r, g, b, er, eg, eb] = &mut out;
        let sm = std::array::from_fn(|k| &smoothed[k][..]);
        reference::auto_blend::auto_blend(&push, colors, errors, sm, [r, g, b], [er, eg, eb]);
    }
    for prec in precisions() {
        let inputs: Vec<&[f32]> = planes.iter().map(|p| &p[..]).collect();
        let (g, _) = run_planes(
            &ctx,
            &auto_score::DECL,
            prec,
            bytemuck::bytes_of(&push),
            w,
            h,
            &inputs,
            &[n; AUTO_MAPS],
            auto_score::FLOPS_PER_PIXEL,
        )
        .unwrap();
        for k in 0..AUTO_MAPS {
            assert_close(
                &format!("auto_score {prec:?} map {k}"),
                &g[k],
                &maps[k],
                1.0,
            );
        }
        let mut inputs = inputs.clone();
        inputs.extend(smoothed.iter().map(|p| &p[..]));
        let (g, _) = run_planes(
            &ctx,
            &auto_blend::DECL,
            prec,
            bytemuck::bytes_of(&push),
            w,
            h,
            &inputs,
            &[n; 6],
            auto_blend::FLOPS_PER_PIXEL,
        )
        .unwrap();
        for k in 0..6 {
            assert_close(
                &format!("auto_blend {prec:?} plane {k}"),
                &g[k],
                &out[k],
                1.0,
            );
        }
    }
    // The blend is a convex combination of the finite members.
    for i in 0..n {
        for c in 0..3 {
            let vals: Vec<f32> = (0..AUTO_MEMBERS)
                .map(|m| planes[3 * m + c][i])
                .filter(|_| i != 7 && i != 9)
                .collect();
            if vals.is_empty() {
                continue;
            }
            let (lo, hi) = vals
                .iter()
                .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
            let o = out[c][i];
            assert!(
                o >= lo * (1.0 - 1e-6) && o <= hi * (1.0 + 1e-6),
                "pixel {i} channel {c}: {o} outside [{lo}, {hi}]"
            );
        }
    }
    check_validation(&ctx);
}

/// Members that agree give their colour back exactly, with their own error
/// (no disagreement: the hat estimate is 0 and raises nothing).
#[test]
fn agreeing_members_give_themselves_back() {
    let (w, h) = (16, 9);
    let n = w * h;
    let mut planes = members(w, h, 6);
    for m in 1..AUTO_MEMBERS {
        for c in 0..3 {
            planes[3 * m + c] = planes[c].clone();
            planes[3 * (AUTO_MEMBERS + m) + c] = planes[3 * AUTO_MEMBERS + c].clone();
        }
    }
    planes[4][7] = planes[1][7];
    planes[12][9] = planes[9][9];
    let (push, maps) = twin_maps(&planes, w, h);
    let colors = std::array::from_fn(|m| rgb(&planes, m));
    let errors = std::array::from_fn(|m| rgb(&planes, AUTO_MEMBERS + m));
    let mut out: [Vec<f32>; 6] = std::array::from_fn(|_| vec![0.0; n]);
    let [r, g, b, er, eg, eb] = &mut out;
    let sm = std::array::from_fn(|k| &maps[k][..]);
    reference::auto_blend::auto_blend(&push, colors, errors, sm, [r, g, b], [er, eg, eb]);
    for k in 0..3 {
        for i in 0..n {
            assert_eq!(out[k][i], planes[k][i], "colour {k} pixel {i}");
            let e = planes[3 * AUTO_MEMBERS + k][i];
            assert!(
                (out[3 + k][i] - e).abs() <= 1e-5 * e.abs() + 1e-12,
                "error {k} pixel {i}"
            );
        }
    }
}

/// The GPU chain equals the CPU twin on the fixture, with and without the
/// error estimate and the debug planes read back (the members compute
/// their error estimates either way), and the blend beats every member.
#[test]
fn auto_gpu_matches_cpu_on_the_fixture_and_beats_its_members() {
    let img = io::read_stats(Path::new("tests/fixtures/dof_checker_64_spp16.exr")).unwrap();
    let r = io::read_rgb(Path::new("tests/fixtures/dof_checker_64_ref.exr")).unwrap();
    let cpu = run(&img, Method::Auto, Backend::Cpu, Precision::F32, true);
    for prec in precisions() {
        for maps in [false, true] {
            let g = run(&img, Method::Auto, Backend::Gpu, prec, maps);
            for c in 0..3 {
                assert_close(
                    &format!("{prec:?} maps {maps} colour {c}"),
                    &g.color.planes[c],
                    &cpu.color.planes[c],
                    0.98,
                );
            }
            if maps {
                let (ge, ce) = (g.error.as_ref().unwrap(), cpu.error.as_ref().unwrap());
                for c in 0..3 {
                    assert_close(
                        &format!("{prec:?} error {c}"),
                        &ge.planes[c],
                        &ce.planes[c],
                        0.95,
                    );
                }
            }
        }
    }
    let auto = metrics::rmse(&cpu.color, &r);
    for m in mcdenoise::methods::auto::MEMBERS {
        let alone = metrics::rmse(&run(&img, m, Backend::Gpu, Precision::F32, false).color, &r);
        println!("{}: {alone:.5}, auto {auto:.5}", m.name());
        assert!(auto < alone, "auto {auto} against {} {alone}", m.name());
    }
    check_validation(&gpu());
}
