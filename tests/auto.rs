//! `--method auto` (AUTO-BLEND): its kernels against their twins, the
//! blend's invariants, and the whole method on the committed fixture: GPU
//! against the CPU twin, and against its members.

mod common;

use std::path::Path;

use common::{assert_close, check_validation, gpu, precisions, Rng};
use mcdenoise::gpu::{Batch, BufferSlice, GpuBuffer};
use mcdenoise::kernels::{auto_blend, auto_dis, auto_score};
use mcdenoise::methods::{denoise, Backend, DenoiseOutput, DenoiseRequest};
use mcdenoise::reference;
use mcdenoise::shared::{auto_pairs, AutoPush, AUTO_SUMS};
use mcdenoise::{io, metrics, Method, Options, Precision, StatsImage};

fn run(
    img: &StatsImage,
    method: Method,
    backend: Backend,
    prec: Precision,
    maps: bool,
    options: &Options,
) -> DenoiseOutput {
    let mut req = DenoiseRequest::new(method);
    req.options = options.clone();
    req.backend = backend;
    req.precision = prec;
    req.error = maps;
    req.debug = maps;
    denoise(Some(&gpu()), img, &req).unwrap()
}

/// `n` members' colours and errors (`6n` planes, colours first), random
/// around a common image, with member 1's colour and error not finite at
/// pixels 7 and 9, member 0's colour at pixel 11 (the base then comes from
/// a later dispatch), and every member's colour at pixel 13.
fn members(w: usize, h: usize, n_members: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = Rng(seed);
    let n = w * h;
    let base: Vec<f64> = (0..n)
        .map(|i| 0.2 + ((i % w) as f64 * 0.3).sin().abs())
        .collect();
    let mut planes: Vec<Vec<f32>> = Vec::new();
    for _ in 0..n_members {
        for _ in 0..3 {
            planes.push(
                (0..n)
                    .map(|i| (base[i] * (1.0 + 0.2 * rng.normal())) as f32)
                    .collect(),
            );
        }
    }
    for _ in 0..n_members {
        for _ in 0..3 {
            planes.push(
                (0..n)
                    .map(|_| (1e-4 * rng.uniform().powi(3) * 100.0) as f32)
                    .collect(),
            );
        }
    }
    planes[4][7] = f32::NAN;
    planes[3 * n_members + 3][9] = f32::INFINITY;
    planes[0][11] = f32::NAN;
    for m in 0..n_members {
        planes[3 * m + 1][13] = f32::INFINITY;
    }
    planes
}

/// Whether member `m` of `n` has a finite colour and error at pixel `i`.
fn usable(planes: &[Vec<f32>], n: usize, m: usize, i: usize) -> bool {
    (0..3).all(|c| planes[3 * m + c][i].is_finite() && planes[3 * (n + m) + c][i].is_finite())
}

fn rgb(p: &[Vec<f32>], m: usize) -> [&[f32]; 3] {
    [&p[3 * m], &p[3 * m + 1], &p[3 * m + 2]]
}

/// The twin's maps of `planes` (`n` members): their scores, then their
/// pairs' disagreements.
fn twin_maps(planes: &[Vec<f32>], w: usize, h: usize, n: usize) -> Vec<Vec<f32>> {
    let push = AutoPush {
        width: w as u32,
        height: h as u32,
        members: n as u32,
        ..Default::default()
    };
    let colors: Vec<_> = (0..n).map(|m| rgb(planes, m)).collect();
    let mut maps = vec![vec![0.0; w * h]; n + auto_pairs(n).len()];
    for m in 0..n {
        reference::auto_score::auto_score(&push, colors[m], rgb(planes, n + m), &mut maps[m]);
    }
    reference::auto_dis::auto_dis(&push, &colors, &mut maps[n..]);
    maps
}

/// The twin's blend of `planes` (`n` members) from the (smoothed) `maps`:
/// colour then error, six planes.
fn twin_blend(
    planes: &[Vec<f32>],
    maps: &[Vec<f32>],
    w: usize,
    h: usize,
    n: usize,
) -> [Vec<f32>; 6] {
    let push = AutoPush {
        width: w as u32,
        height: h as u32,
        members: n as u32,
        ..Default::default()
    };
    let members: Vec<reference::auto_blend::Member> = (0..n)
        .map(|m| reference::auto_blend::Member {
            color: rgb(planes, m),
            error: rgb(planes, n + m),
            score: &maps[m],
        })
        .collect();
    let dis: Vec<&[f32]> = maps[n..].iter().map(|v| &v[..]).collect();
    let mut out: [Vec<f32>; 6] = std::array::from_fn(|_| vec![0.0; w * h]);
    let [r, g, b, er, eg, eb] = &mut out;
    reference::auto_blend::auto_blend(&push, &members, &dis, [r, g, b], [er, eg, eb]);
    out
}

/// Runs `auto_score`, `auto_dis` and `auto_blend` on the GPU as the method
/// records them, the blend reading `smoothed` for the maps: the unsmoothed
/// maps, then the blend's six planes.
fn gpu_kernels(
    planes: &[Vec<f32>],
    smoothed: &[Vec<f32>],
    (w, h): (usize, usize),
    n: usize,
    prec: Precision,
) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let ctx = gpu();
    let up = |v: &[f32]| GpuBuffer::from_slice(&ctx, "test.auto", v).unwrap();
    let inputs: Vec<GpuBuffer> = planes.iter().map(|p| up(p)).collect();
    let zero = vec![0.0f32; w * h];
    let maps: Vec<GpuBuffer> = smoothed.iter().map(|_| up(&zero)).collect();
    let smooth: Vec<GpuBuffer> = smoothed.iter().map(|p| up(p)).collect();
    let sums: Vec<GpuBuffer> = (0..AUTO_SUMS).map(|_| up(&zero)).collect();
    let out: Vec<GpuBuffer> = (0..6).map(|_| up(&zero)).collect();
    let rgb3 =
        |k: usize| -> [BufferSlice; 3] { std::array::from_fn(|c| inputs[3 * k + c].slice()) };
    let size = (w as u32, h as u32);
    let mut batch = Batch::new(&ctx).unwrap();
    let colors: Vec<_> = (0..n).map(rgb3).collect();
    for m in 0..n {
        auto_score::record(
            &mut batch,
            prec,
            size,
            colors[m],
            rgb3(n + m),
            maps[m].slice(),
        )
        .unwrap();
    }
    let dis: Vec<BufferSlice> = maps[n..].iter().map(|b| b.slice()).collect();
    auto_dis::record(&mut batch, prec, size, &colors, &dis).unwrap();
    let members: Vec<auto_blend::Member> = (0..n)
        .map(|m| auto_blend::Member {
            color: colors[m],
            error: rgb3(n + m),
            score: smooth[m].slice(),
        })
        .collect();
    let sdis: Vec<BufferSlice> = smooth[n..].iter().map(|b| b.slice()).collect();
    auto_blend::record(
        &mut batch,
        prec,
        size,
        &members,
        &sdis,
        std::array::from_fn(|k| sums[k].slice()),
        std::array::from_fn(|c| out[c].slice()),
        std::array::from_fn(|c| out[3 + c].slice()),
    )
    .unwrap();
    batch.finish().unwrap();
    let read = |b: &GpuBuffer| mcdenoise::gpu::buffer::read_slice(&ctx, b.slice(), w * h).unwrap();
    (
        maps.iter().map(read).collect(),
        out.iter().map(read).collect(),
    )
}

#[test]
fn auto_kernels_match_twins() {
    let (w, h) = (37, 21);
    for n_members in [3, 4] {
        let planes = members(w, h, n_members, 5);
        let maps = twin_maps(&planes, w, h, n_members);
        // Smoothed maps stand-in: the maps with some pixels zero (no score).
        let mut smoothed = maps.clone();
        smoothed[1][3] = 0.0;
        let out = twin_blend(&planes, &smoothed, w, h, n_members);
        for prec in precisions() {
            let (g, o) = gpu_kernels(&planes, &smoothed, (w, h), n_members, prec);
            for k in 0..maps.len() {
                let what = format!("{n_members} members {prec:?} map {k}");
                assert_close(&what, &g[k], &maps[k], 1.0);
            }
            for k in 0..6 {
                let what = format!("{n_members} members {prec:?} auto_blend plane {k}");
                assert_close(&what, &o[k], &out[k], 1.0);
            }
        }
        // The blend is a convex combination of the usable members; 0 where
        // none is.
        for i in 0..w * h {
            for c in 0..3 {
                let vals: Vec<f32> = (0..n_members)
                    .filter(|&m| usable(&planes, n_members, m, i))
                    .map(|m| planes[3 * m + c][i])
                    .collect();
                if vals.is_empty() {
                    assert_eq!((out[c][i], out[3 + c][i]), (0.0, 0.0), "pixel {i}");
                    continue;
                }
                let (lo, hi) = vals
                    .iter()
                    .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
                let o = out[c][i];
                assert!(
                    o >= lo * (1.0 - 1e-6) && o <= hi * (1.0 + 1e-6),
                    "{n_members} members, pixel {i} channel {c}: {o} outside [{lo}, {hi}]"
                );
            }
        }
    }
    check_validation(&gpu());
}

/// With three members the n-cornered hat is the three-cornered one:
/// `t_0 = (dis01 + dis02 − dis12) / 2` and so on; with four it is the
/// least-squares solution of `dis_ab = e_a + e_b`, exact when the
/// disagreements are such sums.
#[test]
fn the_hat_recovers_independent_errors() {
    let d3 = [0.3, 0.5, 0.6];
    assert!((reference::auto_blend::hat(&d3, 3, 0) - 0.5 * (0.3 + 0.5 - 0.6)).abs() < 1e-15);
    assert!((reference::auto_blend::hat(&d3, 3, 1) - 0.5 * (0.3 + 0.6 - 0.5)).abs() < 1e-15);
    assert!((reference::auto_blend::hat(&d3, 3, 2) - 0.5 * (0.5 + 0.6 - 0.3)).abs() < 1e-15);
    let e = [0.1, 0.4, 0.02, 0.7];
    let d4: Vec<f64> = auto_pairs(4).iter().map(|&(a, b)| e[a] + e[b]).collect();
    for (m, &em) in e.iter().enumerate() {
        let t = reference::auto_blend::hat(&d4, 4, m);
        assert!((t - em).abs() < 1e-12, "member {m}: {t} against {em}");
    }
}

/// Members that agree give their colour back exactly, with their own error
/// (no disagreement: the hat estimate is 0 and raises nothing).
#[test]
fn agreeing_members_give_themselves_back() {
    let (w, h) = (16, 9);
    let n = w * h;
    for n_members in [3, 4] {
        let mut planes = members(w, h, n_members, 6);
        for m in 1..n_members {
            for c in 0..3 {
                planes[3 * m + c] = planes[c].clone();
                planes[3 * (n_members + m) + c] = planes[3 * n_members + c].clone();
            }
        }
        planes[4][7] = planes[1][7];
        planes[3 * n_members + 3][9] = planes[3 * n_members][9];
        let maps = twin_maps(&planes, w, h, n_members);
        let out = twin_blend(&planes, &maps, w, h, n_members);
        for k in 0..3 {
            for i in 0..n {
                if !usable(&planes, n_members, 0, i) {
                    // Pixels 11 and 13: no member is usable.
                    assert_eq!((out[k][i], out[3 + k][i]), (0.0, 0.0), "pixel {i}");
                    continue;
                }
                assert_eq!(
                    out[k][i], planes[k][i],
                    "{n_members} members colour {k} pixel {i}"
                );
                let e = planes[3 * n_members + k][i];
                assert!(
                    (out[3 + k][i] - e).abs() <= 1e-5 * e.abs() + 1e-12,
                    "{n_members} members error {k} pixel {i}"
                );
            }
        }
    }
}

/// The GPU chain equals the CPU twin on the fixture, with and without the
/// error estimate and the debug planes read back (the members compute
/// their error estimates either way), and the blend beats every member;
/// with three members and with AOS as a fourth (`auto.aos=on`).
#[test]
fn auto_gpu_matches_cpu_on_the_fixture_and_beats_its_members() {
    let img = io::read_stats(Path::new("tests/fixtures/dof_checker_64_spp16.exr")).unwrap();
    let r = io::read_rgb(Path::new("tests/fixtures/dof_checker_64_ref.exr")).unwrap();
    for aos in ["off", "on"] {
        let opts = Options::parse(&[format!("auto.aos={aos}")]).unwrap();
        let cpu = run(
            &img,
            Method::Auto,
            Backend::Cpu,
            Precision::F32,
            true,
            &opts,
        );
        for prec in precisions() {
            // Without the maps read back only for three members (the
            // fourth adds nothing to that path).
            let maps_runs: &[bool] = if aos == "off" {
                &[false, true]
            } else {
                &[true]
            };
            for &maps in maps_runs {
                let g = run(&img, Method::Auto, Backend::Gpu, prec, maps, &opts);
                let what = format!("aos {aos} {prec:?} maps {maps}");
                if aos == "on" {
                    // AOS's GPU and CPU fits agree to an rMSE of 1e-4, not
                    // pixel by pixel (tests/aos.rs); so does the blend.
                    let diff = metrics::rmse(&g.color, &cpu.color);
                    assert!(diff < 1e-4, "{what}: colour rMSE {diff}");
                    let (ge, ce) = (g.error.as_ref().unwrap(), cpu.error.as_ref().unwrap());
                    let diff = metrics::rmse(ge, ce);
                    assert!(diff < 1e-3, "{what}: error rMSE {diff}");
                    continue;
                }
                for c in 0..3 {
                    assert_close(
                        &format!("{what} colour {c}"),
                        &g.color.planes[c],
                        &cpu.color.planes[c],
                        0.98,
                    );
                }
                if maps {
                    let (ge, ce) = (g.error.as_ref().unwrap(), cpu.error.as_ref().unwrap());
                    for c in 0..3 {
                        assert_close(
                            &format!("{what} error {c}"),
                            &ge.planes[c],
                            &ce.planes[c],
                            0.95,
                        );
                    }
                }
            }
        }
        let auto = metrics::rmse(&cpu.color, &r);
        let members = mcdenoise::methods::auto::members(&opts, mcdenoise::Pass::Final);
        assert_eq!(members.len(), if aos == "on" { 4 } else { 3 });
        let alone: Vec<f64> = members
            .iter()
            .map(|&m| {
                let none = Options::default();
                let o = run(&img, m, Backend::Gpu, Precision::F32, false, &none);
                let e = metrics::rmse(&o.color, &r);
                println!("aos {aos}: {}: {e:.5}, auto {auto:.5}", m.name());
                e
            })
            .collect();
        let best = alone.iter().cloned().fold(f64::MAX, f64::min);
        assert!(
            auto < best,
            "aos {aos}: auto {auto} against its best member {best}"
        );
    }
    check_validation(&gpu());
}

/// AUTO-AOS: the AOS member reads the features from before the G-buffer
/// prefilter, as AOS alone does by default: its debug planes inside `auto`
/// equal AOS's alone, on the GPU and on the CPU, though the prefilter runs
/// for the other members (and changes AOS's planes when AOS is made to
/// read its output).
#[test]
fn the_aos_member_reads_unprefiltered_features() {
    let img = io::read_stats(Path::new("tests/fixtures/dof_checker_64_spp16.exr")).unwrap();
    let opts = Options::parse(&["auto.aos=on"]).unwrap();
    for backend in [Backend::Gpu, Backend::Cpu] {
        let auto = run(&img, Method::Auto, backend, Precision::F32, true, &opts);
        let alone = run(&img, Method::Aos, backend, Precision::F32, true, &opts);
        let mut prefiltered = DenoiseRequest::new(Method::Aos);
        prefiltered.backend = backend;
        prefiltered.debug = true;
        prefiltered.prefilter = mcdenoise::Prefilter::On;
        let prefiltered = denoise(Some(&gpu()), &img, &prefiltered).unwrap();
        let mut compared = 0;
        let mut moved = 0;
        // The stage's own planes (the chain's, such as the outlier mask,
        // are not the member's).
        for (name, plane) in &alone.debug {
            let inside = auto.debug.iter().find(|(k, _)| *k == format!("aos.{name}"));
            let Some((_, inside)) = inside else {
                continue;
            };
            assert_eq!(inside, plane, "{backend:?}: aos.{name}");
            compared += 1;
            let (_, p) = prefiltered.debug.iter().find(|(k, _)| k == name).unwrap();
            moved += (p != plane) as usize;
        }
        assert!(
            compared > 0 && moved > 0,
            "{backend:?}: {compared} planes, {moved} moved"
        );
    }
    check_validation(&gpu());
}

/// AUTO-AOS joins final reconstructions only: an adaptive pass's `auto`
/// with `auto.aos=on` is the three members' blend, bit for bit.
#[test]
fn an_intermediate_pass_blends_three_members() {
    let img = io::read_stats(Path::new("tests/fixtures/dof_checker_64_spp16.exr")).unwrap();
    let out = |aos: &str| {
        let mut req = DenoiseRequest::new(Method::Auto);
        req.options = Options::parse(&[format!("auto.aos={aos}")]).unwrap();
        req.pass = mcdenoise::Pass::Intermediate;
        denoise(Some(&gpu()), &img, &req).unwrap().color
    };
    assert_eq!(out("on").planes, out("off").planes);
    let final_on = run(&img, Method::Auto, Backend::Gpu, Precision::F32, false, &{
        Options::parse(&["auto.aos=on"]).unwrap()
    });
    let final_off = run(
        &img,
        Method::Auto,
        Backend::Gpu,
        Precision::F32,
        false,
        &Options::default(),
    );
    assert_ne!(final_on.color.planes, final_off.color.planes);
    check_validation(&gpu());
}

/// AUTO-VIS: in a final reconstruction `auto`'s WLR member reads the
/// visibility as a tenth feature (WLR-VIS) when the statistics have the
/// layer: the default is `wlr.extra_features=visibility` bit for bit, on
/// the GPU as on the CPU (which agree), and differs from `none`; the WLR
/// and APR members filter the visibility once between them. Without
/// the layer the default is `none`, bit for bit, and asking for the
/// visibility names the missing layer; adaptive passes keep nine features.
#[test]
fn the_wlr_member_reads_the_visibility_when_there_is_one() {
    let fixture = |name: &str| {
        io::read_stats(
            &Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/fixtures")
                .join(name),
        )
        .unwrap()
    };
    let opts = |o: &[&str]| Options::parse(o).unwrap();
    let colour = |img: &StatsImage, backend: Backend, o: &Options, pass: mcdenoise::Pass| {
        let mut req = DenoiseRequest::new(Method::Auto);
        req.options = o.clone();
        req.backend = backend;
        req.pass = pass;
        denoise(Some(&gpu()), img, &req).map(|out| out.color)
    };
    let fin = mcdenoise::Pass::Final;
    let vis = fixture("night_lights_40_spp64.exr");
    assert!(vis.get(mcdenoise::Layer::Visibility).is_some());
    let default = colour(&vis, Backend::Gpu, &Options::default(), fin).unwrap();
    let with = colour(
        &vis,
        Backend::Gpu,
        &opts(&["wlr.extra_features=visibility"]),
        fin,
    )
    .unwrap();
    let without = colour(&vis, Backend::Gpu, &opts(&["wlr.extra_features=none"]), fin).unwrap();
    assert_eq!(default.planes, with.planes);
    // The WLR and APR members share one filter of the visibility, and
    // each alone filters it once.
    let filters = |m: Method, o: &Options| {
        let mut req = DenoiseRequest::new(m);
        req.options = o.clone();
        req.pass = fin;
        let out = denoise(Some(&gpu()), &vis, &req).unwrap();
        let n = out
            .timings
            .iter()
            .filter(|t| t.kernel == "aos_nlm_vis")
            .count();
        (n, out.color)
    };
    let none = Options::default();
    assert_eq!(filters(Method::Auto, &none), (1, default.clone()));
    assert_eq!(filters(Method::Apr, &none).0, 1);
    let wlr_vis = opts(&["wlr.extra_features=visibility"]);
    assert_eq!(filters(Method::Wlr, &wlr_vis).0, 1);
    let moved = metrics::rmse(&default, &without);
    assert!(
        moved > 1e-5,
        "the visibility moved auto's output by {moved}"
    );
    let cpu = colour(&vis, Backend::Cpu, &Options::default(), fin).unwrap();
    for c in 0..3 {
        assert_close(
            &format!("auto with the visibility, channel {c}"),
            &default.planes[c],
            &cpu.planes[c],
            0.98,
        );
    }
    let mid = mcdenoise::Pass::Intermediate;
    assert_eq!(
        colour(&vis, Backend::Gpu, &Options::default(), mid)
            .unwrap()
            .planes,
        colour(&vis, Backend::Gpu, &opts(&["wlr.extra_features=none"]), mid)
            .unwrap()
            .planes,
    );

    let plain = fixture("dof_checker_64_spp16.exr");
    assert!(plain.get(mcdenoise::Layer::Visibility).is_none());
    for backend in [Backend::Gpu, Backend::Cpu] {
        assert_eq!(
            colour(&plain, backend, &Options::default(), fin)
                .unwrap()
                .planes,
            colour(&plain, backend, &opts(&["wlr.extra_features=none"]), fin)
                .unwrap()
                .planes,
            "{backend:?}"
        );
        let err = colour(
            &plain,
            backend,
            &opts(&["wlr.extra_features=visibility"]),
            fin,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("visibility"), "{backend:?}: {err}");
    }
    check_validation(&gpu());
}
