//! Spec §10.1, the LP temporal filter: its invariants on the f64 twin, the
//! kernel against the twin, and the filter in the facade on rendered
//! sequences (a static camera converges, a cut forgets, a disoccluded
//! pixel is reset).

mod common;

use common::{agreement, assert_close, check_validation, gpu, precisions, Rng};
use mcdenoise::gpu::Precision;
use mcdenoise::kernels::{lp_temporal, lp_temporal_gain, run_planes, temporal_motion};
use mcdenoise::reference::lp_temporal::{self as twin, PixelState, TemporalInputs};
use mcdenoise::reference::lp_temporal_gain as gain_twin;
use mcdenoise::reference::temporal_motion as motion_twin;
use mcdenoise::shared::{
    MotionPush, TemporalPush, TEMPORAL_LAMBDA, TEMPORAL_MOTION, TEMPORAL_NO_SEARCH, TEMPORAL_P00,
    TEMPORAL_RESET, TEMPORAL_RESET_P00, TEMPORAL_RESET_P11, TEMPORAL_SOURCE_NONE,
    TEMPORAL_SOURCE_RESET, TEMPORAL_STATE,
};

/// §10.1's prior `δ` (`[LP §7]`): its reset is `P = I/δ`.
const DELTA: f64 = 0.001;
/// §10.1's reset prior, `(P00, P11)`.
const SPEC_PRIOR: (f64, f64) = (1.0 / DELTA, 1.0 / DELTA);

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

/// §10.1's invariant: with `λ = 1` and no reprojection the state after `T`
/// frames is the batch ridge fit of `(1, τ) → y` over frames `1..T` with
/// the prior `diag(P00, P11)⁻¹` around the first frame's `(y_0, 0)`
/// (§10.1's `δI`, and TEMPORAL-PRIOR's with a finite slope variance),
/// moved to the last frame's origin (`β ← S^{T−1} β`,
/// `P ← S^{T−1} P S^{T−1 ᵀ}`).
#[test]
fn lambda_one_without_reprojection_is_the_batch_ridge_fit() {
    let mut rng = Rng(11);
    for ((p00, p11), frames) in [SPEC_PRIOR, (TEMPORAL_RESET_P00 as f64, 0.01)]
        .into_iter()
        .flat_map(|prior| [2usize, 3, 7, 24, 100].map(|f| (prior, f)))
    {
        let ys: Vec<[f64; 3]> = (0..frames)
            .map(|t| std::array::from_fn(|c| 0.3 * c as f64 + 0.01 * t as f64 + 0.1 * rng.normal()))
            .collect();
        let mut s = PixelState::reset(ys[0], [0.0; 3], (p00, p11));
        for y in &ys[1..] {
            s = s.shifted();
            s.update(*y, 1.0);
        }
        // Batch: A = diag(1/P00, 1/P11) + Σ z zᵀ, b = (y_0/P00, 0) + Σ z y,
        // z = (1, τ).
        let mut a = [[1.0 / p00, 0.0], [0.0, 1.0 / p11]];
        for t in 1..frames {
            let tau = t as f64;
            a[0][0] += 1.0;
            a[0][1] += tau;
            a[1][0] += tau;
            a[1][1] += tau * tau;
        }
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        let inv = [
            [a[1][1] / det, -a[0][1] / det],
            [-a[1][0] / det, a[0][0] / det],
        ];
        let last = (frames - 1) as f64;
        for c in 0..3 {
            let mut b = [ys[0][c] / p00, 0.0];
            for (t, y) in ys.iter().enumerate().skip(1) {
                b[0] += y[c];
                b[1] += t as f64 * y[c];
            }
            let b0 = inv[0][0] * b[0] + inv[0][1] * b[1];
            let b1 = inv[1][0] * b[0] + inv[1][1] * b[1];
            let want = [b0 + last * b1, b1];
            for k in 0..2 {
                assert!(
                    close(s.beta[c][k], want[k], 1e-9),
                    "T = {frames}, channel {c}, β{k}: {} vs batch {}",
                    s.beta[c][k],
                    want[k]
                );
            }
        }
        // P = S^(T−1) A⁻¹ S^(T−1)ᵀ with S^k = [[1, k], [0, 1]].
        let (p00, p01, p11) = (inv[0][0], inv[0][1], inv[1][1]);
        let want = [
            p00 + 2.0 * last * p01 + last * last * p11,
            p01 + last * p11,
            p11,
        ];
        for k in 0..3 {
            assert!(
                close(s.p[k], want[k], 1e-9),
                "T = {frames}, P[{k}]: {} vs batch {}",
                s.p[k],
                want[k]
            );
        }
    }
}

/// TIME-ORIGIN: the shifted recursion and the one in absolute time
/// (`z = (1, t)`, origin at the first frame) give the same outputs to 1e-9.
#[test]
fn shifted_and_absolute_time_origins_agree() {
    let mut rng = Rng(5);
    let lambda = TEMPORAL_LAMBDA as f64;
    let ys: Vec<[f64; 3]> = (0..200)
        .map(|t| {
            std::array::from_fn(|c| 1.0 + c as f64 + (t as f64 * 0.05).sin() + 0.2 * rng.normal())
        })
        .collect();
    let mut s = PixelState::reset(ys[0], [0.0; 3], SPEC_PRIOR);
    let mut beta: [[f64; 2]; 3] = ys[0].map(|v| [v, 0.0]);
    let mut p = [[1.0 / DELTA, 0.0], [0.0, 1.0 / DELTA]];
    let mut worst = 0.0f64;
    for (t, y) in ys.iter().enumerate().skip(1) {
        s = s.shifted();
        s.update(*y, lambda);
        let z = [1.0, t as f64];
        let pz = [
            p[0][0] * z[0] + p[0][1] * z[1],
            p[1][0] * z[0] + p[1][1] * z[1],
        ];
        let den = lambda + z[0] * pz[0] + z[1] * pz[1];
        let g = [pz[0] / den, pz[1] / den];
        // zᵀP = (Pz)ᵀ (P symmetric).
        p = [
            [
                (p[0][0] - g[0] * pz[0]) / lambda,
                (p[0][1] - g[0] * pz[1]) / lambda,
            ],
            [
                (p[1][0] - g[1] * pz[0]) / lambda,
                (p[1][1] - g[1] * pz[1]) / lambda,
            ],
        ];
        for c in 0..3 {
            let r = y[c] - (beta[c][0] + beta[c][1] * z[1]);
            beta[c][0] += g[0] * r;
            beta[c][1] += g[1] * r;
            let absolute = beta[c][0] + beta[c][1] * z[1];
            let shifted = s.predict()[c];
            worst = worst.max((absolute - shifted).abs() / (1.0 + absolute.abs()));
        }
    }
    assert!(worst <= 1e-9, "outputs differ by {worst:e}");
}

/// A synthetic sequence: a plane seen by a camera panning 0.7 px a frame
/// (positions move), with a box in front of it over a band of columns that
/// slides 2 px a frame (disocclusions behind it), invalid pixels and a
/// non-finite colour; the colour is a function of the world position plus
/// noise.
struct Synthetic {
    w: usize,
    h: usize,
    color: [Vec<f32>; 3],
    position: [Vec<f32>; 3],
    variance: [Vec<f32>; 3],
    error: [Vec<f32>; 3],
    depth: Vec<f32>,
    spp: Vec<f32>,
}

fn synthetic(w: usize, h: usize, t: usize, rng: &mut Rng) -> Synthetic {
    let n = w * h;
    let s = 0.008;
    let mut f = Synthetic {
        w,
        h,
        color: std::array::from_fn(|_| vec![0.0; n]),
        position: std::array::from_fn(|_| vec![0.0; n]),
        variance: std::array::from_fn(|_| vec![1e-7; n]),
        error: std::array::from_fn(|_| vec![0.0025; n]),
        depth: vec![0.0; n],
        spp: vec![16.0; n],
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let box_x0 = 5 + 2 * t;
            let in_box = (box_x0..box_x0 + 6).contains(&x) && y > 3;
            let (wx, wy, wz, d) = if in_box {
                ((x as f64 + 0.7 * t as f64) * s, y as f64 * s, -0.3, 0.7)
            } else {
                ((x as f64 + 0.7 * t as f64) * s, y as f64 * s, 0.0, 1.0)
            };
            let base = [
                0.5 + 0.4 * (wx * 40.0).sin(),
                0.3 + 0.2 * (wy * 30.0).cos(),
                if in_box { 2.0 } else { 0.1 },
            ];
            for c in 0..3 {
                f.color[c][i] = (base[c] + 0.05 * rng.normal()).max(0.0) as f32;
            }
            f.position[0][i] = wx as f32;
            f.position[1][i] = wy as f32;
            f.position[2][i] = wz as f32;
            f.depth[i] = d as f32;
        }
    }
    f.spp[3] = 0.0;
    f.color[1][w + 2] = f32::NAN;
    f
}

fn inputs(f: &Synthetic) -> TemporalInputs<'_> {
    TemporalInputs {
        color: [&f.color[0], &f.color[1], &f.color[2]],
        position: [&f.position[0], &f.position[1], &f.position[2]],
        position_variance: [&f.variance[0], &f.variance[1], &f.variance[2]],
        depth: &f.depth,
        spp: &f.spp,
        error: [&f.error[0], &f.error[1], &f.error[2]],
    }
}

fn push(w: usize, h: usize, flags: u32) -> TemporalPush {
    TemporalPush {
        width: w as u32,
        height: h as u32,
        flags,
        lambda: TEMPORAL_LAMBDA,
        p00: TEMPORAL_RESET_P00,
        p11: TEMPORAL_RESET_P11,
        ..Default::default()
    }
}

/// The twin's frame: `(next state, output planes, source)`.
fn twin_frame(
    p: &TemporalPush,
    f: &Synthetic,
    prev: &[f32],
) -> (Vec<f32>, [Vec<f32>; 3], Vec<f32>) {
    let n = f.w * f.h;
    let mut next = vec![0.0; TEMPORAL_STATE * n];
    let mut out: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut source = vec![0.0; n];
    let [r, g, b] = &mut out;
    twin::lp_temporal(p, &inputs(f), prev, &mut next, [r, g, b], &mut source);
    (next, out, source)
}

/// TEMPORAL-MOTION's offsets at half resolution for frame `f` over the
/// state `prev` (the twin's search, where `p` asks for it; a zero plane
/// otherwise).
fn twin_motion(p: &TemporalPush, f: &Synthetic, prev: &[f32]) -> [Vec<f32>; 2] {
    match twin::frame_motion(p, &inputs(f), prev) {
        Some(m) => [m.ox, m.oy],
        None => [vec![0.0], vec![0.0]],
    }
}

/// `lp_temporal`'s input bindings for frame `f` over the state `prev` and
/// the offsets `motion`.
fn kernel_inputs<'a>(
    f: &'a Synthetic,
    prev: &'a [f32],
    motion: &'a [Vec<f32>; 2],
) -> Vec<&'a [f32]> {
    let mut ins: Vec<&[f32]> = Vec::new();
    ins.extend(f.color.iter().map(|v| &v[..]));
    ins.extend(f.position.iter().map(|v| &v[..]));
    ins.extend(f.variance.iter().map(|v| &v[..]));
    ins.extend([&f.depth[..], &f.spp[..]]);
    ins.extend(f.error.iter().map(|v| &v[..]));
    ins.push(prev);
    ins.extend(motion.iter().map(|v| &v[..]));
    ins
}

/// The GPU's frame: next state, output R, G, B and source (the window
/// centred by the twin's motion search).
fn gpu_frame(p: &TemporalPush, f: &Synthetic, prev: &[f32], prec: Precision) -> Vec<Vec<f32>> {
    let n = f.w * f.h;
    let motion = twin_motion(p, f, prev);
    run_planes(
        &gpu(),
        &lp_temporal::DECL,
        prec,
        bytemuck::bytes_of(p),
        f.w,
        f.h,
        &kernel_inputs(f, prev, &motion),
        &[TEMPORAL_STATE * n, n, n, n, n],
        lp_temporal::FLOPS_PER_PIXEL,
    )
    .unwrap()
    .0
}

/// `lp_temporal` and `lp_temporal_gain` against their twins over a
/// synthetic sequence, each frame from the twin's previous state; with
/// TEMPORAL-PRIOR's reset, and on the largest frame also with §10.1's and
/// with a free slope of prior 0.01 (the slope's arithmetic).
#[test]
fn lp_temporal_matches_its_twin() {
    let ctx = gpu();
    let ours = (TEMPORAL_RESET_P00, TEMPORAL_RESET_P11);
    let spec = (SPEC_PRIOR.0 as f32, SPEC_PRIOR.1 as f32);
    for &((w, h), (p00, p11)) in &[
        ((29usize, 17usize), ours),
        ((29, 17), spec),
        ((29, 17), (1.0, 0.01)),
        ((1, 9), ours),
        ((8, 8), ours),
    ] {
        let n = w * h;
        let mut rng = Rng(3 + w as u64);
        let mut prev = vec![0.0f32; TEMPORAL_STATE * n];
        for t in 0..6 {
            let f = synthetic(w, h, t, &mut rng);
            let flags = match t {
                0 => TEMPORAL_RESET,
                3 => TEMPORAL_NO_SEARCH,
                4 => 0,
                _ => TEMPORAL_MOTION,
            };
            // TEMPORAL-TEST-SCALE's factor on odd frames (0 reads as 1).
            let inflate_scale = if t % 2 == 1 { 0.17 } else { 0.0 };
            let p = TemporalPush {
                p00,
                p11,
                inflate_scale,
                ..push(w, h, flags)
            };
            let (next, out, source) = twin_frame(&p, &f, &prev);
            let motion = twin_motion(&p, &f, &prev);
            for prec in precisions() {
                let ins = kernel_inputs(&f, &prev, &motion);
                let g = gpu_frame(&p, &f, &prev, prec);
                let what = format!("{w}x{h} prior ({p00}, {p11}) frame {t} {prec:?}");
                assert_close(&format!("{what} state"), &g[0], &next, 0.99);
                for c in 0..3 {
                    // NaN passes through in both.
                    let (gg, cc): (Vec<f32>, Vec<f32>) = g[1 + c]
                        .iter()
                        .zip(&out[c])
                        .filter(|(a, _)| a.is_finite())
                        .map(|(a, b)| (*a, *b))
                        .unzip();
                    assert_close(&format!("{what} colour {c}"), &gg, &cc, 0.99);
                }
                let agree = agreement(&g[4], &source);
                assert!(agree >= 0.98, "{what}: source agrees on {agree}");
                // The gain on an error estimate, from the same state.
                let err: Vec<Vec<f32>> = (0..3)
                    .map(|c| {
                        (0..n)
                            .map(|i| 0.01 * (1 + (i * 7 + c) % 13) as f32)
                            .collect()
                    })
                    .collect();
                let mut want: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
                {
                    let [a, b, c] = &mut want;
                    let e = [&err[0][..], &err[1][..], &err[2][..]];
                    gain_twin::lp_temporal_gain(&p, &inputs(&f), &prev, e, [a, b, c]);
                }
                let mut ins = ins.clone();
                ins.extend(err.iter().map(|v| &v[..]));
                let (gg, _) = run_planes(
                    &ctx,
                    &lp_temporal_gain::DECL,
                    prec,
                    bytemuck::bytes_of(&p),
                    w,
                    h,
                    &ins,
                    &[n, n, n],
                    lp_temporal_gain::FLOPS_PER_PIXEL,
                )
                .unwrap();
                for c in 0..3 {
                    assert_close(&format!("{what} gain {c}"), &gg[c], &want[c], 0.99);
                    // Never above the error it scales.
                    assert!(gg[c].iter().zip(&err[c]).all(|(g, e)| g <= e));
                }
                if t > 0 && flags & TEMPORAL_NO_SEARCH == 0 {
                    assert!(
                        gg[0].iter().zip(&err[0]).any(|(g, e)| g < e),
                        "{what}: no gain"
                    );
                }
            }
            prev = next;
        }
        check_validation(&ctx);
    }
}

/// TEMPORAL-INFLATE on a pixel whose error estimate is 0 (a lamp): a step
/// in its colour inflates `P` by a ratio near 1e18, after which the
/// update must leave `P₀₀` at about one frame's (the history restarts at
/// the step), not cancel it to 0 — a state with `P₀₀ = 0` never moves
/// again. GPU (each precision) and twin, frame after frame.
#[test]
fn an_inflated_history_restarts_at_the_step() {
    let ctx = gpu();
    let (w, h) = (8usize, 8usize);
    let n = w * h;
    let frame = |v: f32| Synthetic {
        w,
        h,
        color: std::array::from_fn(|_| vec![v; n]),
        position: std::array::from_fn(|k| (0..n).map(|i| (i * 3 + k) as f32 * 0.01).collect()),
        variance: std::array::from_fn(|_| vec![0.0; n]),
        error: std::array::from_fn(|_| vec![0.0; n]),
        depth: vec![1.0; n],
        spp: vec![16.0; n],
    };
    let values = [1.0f32, 1.0, 1000.0, 2000.0];
    for prec in precisions() {
        let mut prev = vec![0.0f32; TEMPORAL_STATE * n];
        let mut twin_prev = prev.clone();
        for (t, &v) in values.iter().enumerate() {
            let f = frame(v);
            let p = push(
                w,
                h,
                if t == 0 {
                    TEMPORAL_RESET
                } else {
                    TEMPORAL_NO_SEARCH
                },
            );
            let (next, out, _) = twin_frame(&p, &f, &twin_prev);
            let g = gpu_frame(&p, &f, &prev, prec);
            for (who, state, color) in [("gpu", &g[0], &g[1]), ("twin", &next, &out[0])] {
                let p00 = state[TEMPORAL_P00 * n + 9];
                let what = format!("{prec:?} {who} frame {t}");
                if t >= 2 {
                    assert!((0.5..=1.01).contains(&p00), "{what}: P00 {p00}");
                    let c = color[9];
                    assert!((c - v).abs() <= 1e-3 * v, "{what}: colour {c}, frame {v}");
                }
            }
            prev = g[0].clone();
            twin_prev = next;
        }
    }
    check_validation(&ctx);
}

/// TEMPORAL-TEST-SCALE: the factor scales the error estimate in
/// TEMPORAL-INFLATE's test. A still pixel's second frame misses its history
/// by half the test's threshold: with the factor 1 the history keeps its
/// weight (the update's gain `P₀₀/(λ + P₀₀)`, about a half), with 0.17 the
/// miss is 2.9 times the threshold and `P` grows by that ratio, so the
/// output moves further towards the new frame. GPU (each precision) and
/// twin.
#[test]
fn the_inflate_scale_scales_the_colour_test() {
    let ctx = gpu();
    let (w, h) = (4usize, 4usize);
    let n = w * h;
    let e = 0.01f32;
    let t2 = mcdenoise::reference::t_threshold3(16.0).powi(2);
    // miss² = 0.5 t3² E (1 + P₀₀) with P₀₀ = 1 after the first frame.
    let d = (0.5 * t2 * e as f64 * 2.0).sqrt() as f32;
    let frame = |v: f32| Synthetic {
        w,
        h,
        color: std::array::from_fn(|_| vec![v; n]),
        position: std::array::from_fn(|k| (0..n).map(|i| (i * 3 + k) as f32 * 0.01).collect()),
        variance: std::array::from_fn(|_| vec![e; n]),
        error: std::array::from_fn(|_| vec![e; n]),
        depth: vec![1.0; n],
        spp: vec![16.0; n],
    };
    let gain = |q: f64| {
        let p = TEMPORAL_RESET_P00 as f64 * q;
        p / (TEMPORAL_LAMBDA as f64 + p)
    };
    for (scale, q) in [(1.0f32, 1.0f64), (0.17, 0.5 / 0.17)] {
        let want = 1.0 + gain(q) * d as f64;
        for prec in precisions() {
            let mut prev = vec![0.0f32; TEMPORAL_STATE * n];
            let mut twin_prev = prev.clone();
            for (t, v) in [1.0f32, 1.0 + d].into_iter().enumerate() {
                let f = frame(v);
                let flags = if t == 0 {
                    TEMPORAL_RESET
                } else {
                    TEMPORAL_NO_SEARCH
                };
                let p = TemporalPush {
                    inflate_scale: scale,
                    ..push(w, h, flags)
                };
                let (next, out, _) = twin_frame(&p, &f, &twin_prev);
                let g = gpu_frame(&p, &f, &prev, prec);
                if t == 1 {
                    for (who, c) in [("gpu", g[1][5]), ("twin", out[0][5])] {
                        assert!(
                            (c as f64 - want).abs() <= 1e-4,
                            "{prec:?} {who}, factor {scale}: colour {c}, want {want}"
                        );
                    }
                }
                prev = g[0].clone();
                twin_prev = next;
            }
        }
    }
    assert!(gain(0.5 / 0.17) > gain(1.0) + 0.2);
    check_validation(&ctx);
}

/// TEMPORAL-RIM on a still 8×8 frame (each pixel's own state): the rim
/// pixel (3, 3) of a one-pixel lamp at (4, 3) is lit (3.0, a large error
/// estimate) in two frames and quiet (0.1, a tiny one) in the third; the
/// lamp beside it is where it was, so the history stays (the output stays
/// near 3 instead of restarting at 0.1). When the lamp moves on to (5, 3)
/// instead, the pixel it left (4, 3) is quiet beside a pixel that was not
/// bright before: its history restarts, no ghost. So does the pixel a
/// two-pixel light leaves when it moves on by one: beside it the light is
/// where it was, but the pixel's history is as bright as the light. GPU
/// (each precision) and twin.
#[test]
fn a_static_rim_keeps_its_history_and_a_moved_light_does_not() {
    let ctx = gpu();
    let (w, h) = (8usize, 8usize);
    let n = w * h;
    // Pixel values and error estimates other than the background's (0.1,
    // 1e-4); each pixel's own state is carried (no search), so the
    // positions do not matter.
    let frame = |lit: &[((usize, usize), f32, f32)]| {
        let mut f = on_a_plane((w, h), |_| 0.1, |i| ((i % w) as f64, (i / w) as f64));
        f.error = std::array::from_fn(|_| vec![1e-4; n]);
        for &((x, y), v, e) in lit {
            for c in 0..3 {
                f.color[c][y * w + x] = v;
                f.error[c][y * w + x] = e;
            }
        }
        f
    };
    let lamp = ((4, 3), 30.0, 1e-3);
    let rim_lit = ((3, 3), 3.0, 1.0);
    let rim = [
        frame(&[lamp, rim_lit]),
        frame(&[lamp, rim_lit]),
        frame(&[lamp]),
    ];
    let moved = [
        frame(&[lamp]),
        frame(&[lamp]),
        frame(&[((5, 3), 30.0, 1e-3)]),
    ];
    // A light two pixels wide that moves one pixel and stops: the pixel it
    // left has a static bright neighbour too, but its history is as bright
    // as that neighbour, not between the two.
    let wide = |x0: usize| frame(&[((x0, 3), 30.0, 1e-3), ((x0 + 1, 3), 30.0, 1e-3)]);
    let left = [wide(3), wide(3), wide(4)];
    for prec in precisions() {
        for (name, seq, (x, y), keeps) in [
            ("rim", &rim, (3, 3), true),
            ("moved", &moved, (4, 3), false),
            ("left", &left, (3, 3), false),
        ] {
            let mut prev = vec![0.0f32; TEMPORAL_STATE * n];
            let mut twin_prev = prev.clone();
            for (t, f) in seq.iter().enumerate() {
                let p = push(
                    w,
                    h,
                    if t == 0 {
                        TEMPORAL_RESET
                    } else {
                        TEMPORAL_NO_SEARCH
                    },
                );
                let (next, out, _) = twin_frame(&p, f, &twin_prev);
                let g = gpu_frame(&p, f, &prev, prec);
                let (gc, tc) = (g[1][y * w + x], out[0][y * w + x]);
                let what = format!("{prec:?} {name} frame {t}");
                assert!(
                    (gc - tc).abs() <= 1e-3 * tc.abs().max(1.0),
                    "{what}: gpu {gc}, twin {tc}"
                );
                if t == 2 {
                    if keeps {
                        assert!(tc > 1.0, "{what}: the rim's history restarted ({tc})");
                    } else {
                        assert!(tc < 0.2, "{what}: the light's history stayed ({tc})");
                    }
                }
                prev = g[0].clone();
                twin_prev = next;
            }
        }
    }
    check_validation(&ctx);
}

/// What the twin does on the synthetic pan: the first frame resets every
/// pixel; later frames carry the plane's state over (from one column to
/// the right, where its points were, or a neighbour), reset the columns the
/// box uncovered (their points were hidden: the nearest plane state is more
/// than 1 % of the depth away, away from the box's top edge), and pass
/// invalid and non-finite pixels through without state.
#[test]
fn twin_reprojects_the_pan_and_resets_disocclusions() {
    let (w, h) = (40, 12);
    let n = w * h;
    let mut rng = Rng(9);
    let mut prev = vec![0.0f32; TEMPORAL_STATE * n];
    let (mut plane, mut aligned) = (0, 0);
    for t in 0..5 {
        let f = synthetic(w, h, t, &mut rng);
        let p = push(w, h, if t == 0 { TEMPORAL_RESET } else { 0 });
        let (next, _, source) = twin_frame(&p, &f, &prev);
        assert_eq!(source[3], TEMPORAL_SOURCE_NONE);
        assert_eq!(source[w + 2], TEMPORAL_SOURCE_NONE);
        assert_eq!(next[12 * n + 3], 0.0, "an invalid pixel keeps no state");
        for y in 4..h {
            for x in 0..w - 4 {
                let s = source[y * w + x];
                if t == 0 {
                    assert_eq!(s, TEMPORAL_SOURCE_RESET);
                } else if (x == 3 + 2 * t || x == 4 + 2 * t) && y >= 6 {
                    assert_eq!(
                        s, TEMPORAL_SOURCE_RESET,
                        "uncovered ({x}, {y}) at frame {t}"
                    );
                } else if x + 4 < 3 + 2 * t {
                    assert!(s >= 0.0, "plane ({x}, {y}) at frame {t} was reset");
                    plane += 1;
                    aligned += (s == 24.0 || s == 25.0) as usize;
                }
            }
        }
        prev = next;
    }
    assert!(
        plane > 50 && aligned * 10 >= plane * 9,
        "{aligned} of {plane} from the same row"
    );
}

/// A static pixel's filtered value converges: over 60 frames of noise
/// around a constant, the filter's output error is well below the input's.
#[test]
fn twin_reduces_noise_on_a_static_pixel() {
    let mut rng = Rng(21);
    let lambda = TEMPORAL_LAMBDA as f64;
    let prior = (TEMPORAL_RESET_P00 as f64, TEMPORAL_RESET_P11 as f64);
    let mut s = PixelState::reset([1.0; 3], [0.0; 3], prior);
    let (mut in_sq, mut out_sq) = (0.0, 0.0);
    for t in 1..60 {
        let y: [f64; 3] = std::array::from_fn(|_| 1.0 + 0.1 * rng.normal());
        s = s.shifted();
        s.update(y, lambda);
        if t >= 30 {
            in_sq += (y[0] - 1.0).powi(2);
            out_sq += (s.predict()[0] - 1.0).powi(2);
        }
    }
    assert!(out_sq < 0.3 * in_sq, "output MSE {out_sq} vs input {in_sq}");
}

/// TEMPORAL-PRIOR: the frame that starts a history counts as one
/// observation (§10.1's `P = I/δ` would make the second frame's output
/// that frame's colour alone), and the slope stays 0: a recursive mean
/// with forgetting.
#[test]
fn a_history_starts_as_one_observation_without_slope() {
    let lambda = TEMPORAL_LAMBDA as f64;
    let prior = (TEMPORAL_RESET_P00 as f64, TEMPORAL_RESET_P11 as f64);
    let ys = [1.0, 3.0, 2.0, 6.0, 4.0];
    let mut s = PixelState::reset([ys[0]; 3], [0.0; 3], prior);
    let (mut num, mut den) = (ys[0], 1.0);
    for &y in &ys[1..] {
        s = s.shifted();
        s.update([y; 3], lambda);
        (num, den) = (lambda * num + y, lambda * den + 1.0);
        let want = num / den;
        assert!(
            close(s.predict()[0], want, 1e-12),
            "output {} against the forgetting mean {want}",
            s.predict()[0]
        );
        assert_eq!(s.beta[0][1], 0.0, "the slope moved");
    }
}

// ---- The filter in the facade, on rendered sequences ----

use std::sync::atomic::AtomicBool;

use mcdenoise::render::adaptive::{render, LoopConfig};
use mcdenoise::render::{sequence, Renderer, Scene};
use mcdenoise::{metrics, Config, Denoiser, Layer, Method, RgbImage, Source, StatsImage, Temporal};

/// Renders `frames` frames of the still scene `name` at `size`, `spp`
/// uniform samples, each with a seed of its own: a static camera over a
/// static scene.
fn still_frames(name: &str, size: usize, spp: u32, frames: u64) -> Vec<StatsImage> {
    let ctx = gpu();
    let scene = Scene::by_name_or_file(name).unwrap();
    let cfg = LoopConfig::new(Method::None, spp, false);
    (0..frames)
        .map(|f| {
            let r = Renderer::new(&ctx, &scene, size, size, 100 + f).unwrap();
            render(&ctx, &r, &cfg, &AtomicBool::new(false), |_| {}).unwrap();
            r.statistics().unwrap()
        })
        .collect()
}

/// The statistics of the first `frames` frames of the built-in
/// `moving_box` at `size`², 8 spp uniform, seed 1.
fn moving_box(size: usize, frames: u32) -> Vec<StatsImage> {
    let ctx = gpu();
    let scene = Scene::by_name_or_file("moving_box").unwrap();
    let cfg = LoopConfig::new(Method::None, 8, false);
    let mut stats = Vec::new();
    let stop = AtomicBool::new(false);
    let size = (size, size);
    sequence::render_frames(
        &ctx,
        &scene,
        0..frames,
        size,
        1,
        &cfg,
        Temporal::Off,
        &stop,
        |f| {
            stats.push(f.stats);
            Ok(())
        },
    )
    .unwrap();
    stats
}

/// A sequence rendered with the filter (`render --frames --temporal lp`)
/// is filtered bit for bit as the library filters its statistics, under a
/// moving camera too: `pan_room`'s lens centre moves every frame, and the
/// renderer accumulates positions relative to one origin for the whole
/// sequence (the final denoiser finalises every frame with its own
/// layout's), and the frames' statistics are finalised on the GPU as that
/// denoiser finalises them (`Renderer::statistics_at`). With each frame's
/// own lens centre, frames 1 and 2 were 0.0008 and 0.0012 rMSE away from
/// the library's; with the statistics finalised on the host in f64, LP's
/// frames were 1e-4 away (64², 4 spp).
#[test]
fn a_rendered_sequence_is_filtered_as_the_library_filters_it() {
    let ctx = gpu();
    let scene = Scene::by_name_or_file("pan_room").unwrap();
    for method in [Method::Wlr, Method::Lp] {
        let cfg = LoopConfig::new(method, 4, false);
        let stop = AtomicBool::new(false);
        let (mut stats, mut rendered) = (Vec::new(), Vec::new());
        sequence::render_frames(
            &ctx,
            &scene,
            0..3,
            (64, 64),
            1,
            &cfg,
            Temporal::Lp,
            &stop,
            |f| {
                stats.push(f.stats);
                rendered.push(f.result.frame.color);
                Ok(())
            },
        )
        .unwrap();
        let d = temporal_denoiser(method, &stats[0]);
        for (t, (s, r)) in stats.iter().zip(&rendered).enumerate() {
            let lib = d.denoise(s, None).unwrap().color;
            assert_eq!(r.planes, lib.planes, "{}, frame {t}", method.name());
        }
    }
    check_validation(&ctx);
}

/// A frame renders the same alone or in any range (`render --help`): its
/// positions are accumulated relative to one origin of the whole scene
/// (the lens centre of its frame 0), not of the range's first frame. With
/// the range's, `pan_room`'s frame 2 rendered in 0..3 and in 2..3 differed
/// in every position layer (`position_variance` by 5 %).
#[test]
fn a_frame_renders_the_same_in_any_range() {
    let ctx = gpu();
    let scene = Scene::by_name_or_file("pan_room").unwrap();
    let cfg = LoopConfig::new(Method::Wlr, 4, false);
    let stop = AtomicBool::new(false);
    let frame2 = |range: std::ops::Range<u32>| {
        let mut out = None;
        sequence::render_frames(
            &ctx,
            &scene,
            range,
            (24, 16),
            1,
            &cfg,
            Temporal::Off,
            &stop,
            |f| {
                if f.number == 2 {
                    out = Some((f.stats, f.result.frame.color));
                }
                Ok(())
            },
        )
        .unwrap();
        out.unwrap()
    };
    let (a, b) = (frame2(0..3), frame2(2..3));
    for (layer, planes) in a.0.layers() {
        assert_eq!(Some(planes), b.0.get(layer), "{}", layer.name());
    }
    assert_eq!(a.1.planes, b.1.planes);
    check_validation(&ctx);
}

fn temporal_denoiser(method: Method, img: &StatsImage) -> Denoiser {
    let mut c = Config::new(method);
    c.temporal = Temporal::Lp;
    c.debug = true;
    Denoiser::new(&gpu(), Source::of_image(img), c).unwrap()
}

fn spatial(method: Method, img: &StatsImage) -> RgbImage {
    let d = Denoiser::new(&gpu(), Source::of_image(img), Config::new(method)).unwrap();
    d.denoise(img, None).unwrap().color
}

fn debug<'a>(f: &'a mcdenoise::Frame, name: &str) -> &'a [f32] {
    &f.debug.iter().find(|(n, _)| n == name).unwrap().1
}

/// A static camera over a static scene: the first frame only initialises
/// (the output is the method's), and as frames accumulate the filtered
/// Monte Carlo mean approaches the reference — the error of the last
/// frames is well below a single frame's. A cut (`reset`) forgets the
/// history: the next frame is the method's output again, every pixel
/// reset.
#[test]
fn static_sequence_converges_and_reset_forgets() {
    let frames = still_frames("cornell", 32, 32, 14);
    let reference = {
        let s = still_frames("cornell", 32, 1024, 1);
        mcdenoise::colour_of(&s[0])
    };
    let d = temporal_denoiser(Method::None, &frames[0]);
    let (mut alone, mut filtered) = (Vec::new(), Vec::new());
    for (t, img) in frames.iter().enumerate() {
        let out = d.denoise(img, None).unwrap();
        let own = spatial(Method::None, img);
        if t == 0 {
            assert_eq!(out.color, own, "the first frame only initialises");
            assert!(debug(&out, "temporal_source").iter().all(|&s| s < 0.0));
        } else {
            // RESET-NOISE: the noise of the mean positions (32², 32 spp)
            // does not reset a static camera's pixels (28 % without it).
            let reset = debug(&out, "temporal_source")
                .iter()
                .filter(|&&s| s < 0.0)
                .count();
            assert!(reset * 50 <= 32 * 32, "frame {t}: {reset} pixels reset");
        }
        alone.push(metrics::rmse(&own, &reference));
        filtered.push(metrics::rmse(&out.color, &reference));
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (a, f) = (mean(&alone[10..]), mean(&filtered[10..]));
    assert!(
        f < 0.6 * a,
        "frames 10–13: rMSE {f:.5} filtered vs {a:.5} alone"
    );
    assert!(
        mean(&filtered[10..]) < mean(&filtered[2..5]),
        "the error keeps falling: {filtered:?}"
    );
    d.reset();
    let out = d.denoise(&frames[0], None).unwrap();
    assert_eq!(
        out.color,
        spatial(Method::None, &frames[0]),
        "a cut forgets"
    );
    assert!(debug(&out, "temporal_source").iter().all(|&s| s < 0.0));
    check_validation(&gpu());
}

/// The moving box: where the box uncovers the wall behind it, no state
/// of the previous frame lies within 1 % of the viewing distance, so the
/// pixel is reset and shows this frame's own reconstruction — not the
/// box's colour smeared over. The uncovered pixels are found from the
/// statistics themselves (positions and depths of both frames).
#[test]
fn disoccluded_pixels_are_reset_not_smeared() {
    let ctx = gpu();
    let size = 64;
    let stats = moving_box(size, 8);
    let d = temporal_denoiser(Method::Wlr, &stats[0]);
    let n = size * size;
    let mut uncovered = 0;
    for t in 0..stats.len() {
        let out = d.denoise(&stats[t], None).unwrap();
        if t == 0 {
            continue;
        }
        let own = spatial(Method::Wlr, &stats[t]);
        let source = debug(&out, "temporal_source");
        let (pos, dep) = (
            stats[t].get(Layer::Position).unwrap(),
            stats[t].get(Layer::Depth).unwrap(),
        );
        let prev = stats[t - 1].get(Layer::Position).unwrap();
        let pvar = stats[t].get(Layer::PositionVariance).unwrap();
        let prev_dep = stats[t - 1].get(Layer::Depth).unwrap();
        for y in 0..size {
            for x in 0..size {
                let i = y * size + x;
                // The box was in front here a frame ago, the wall is now.
                if !(prev_dep[0][i] > 0.0 && prev_dep[0][i] < 0.9 * dep[0][i]) {
                    continue;
                }
                // RESET's distance with RESET-NOISE, doubled (the chain's
                // positions are sanitised and prefiltered).
                let var: f64 = (0..3).map(|k| pvar[k][i] as f64).sum();
                let limit = (0.01 * (dep[0][i] as f64).max(1e-3)).powi(2) + 18.0 * var;
                let near = (y.saturating_sub(3)..(y + 4).min(size)).any(|jy| {
                    (x.saturating_sub(3)..(x + 4).min(size)).any(|jx| {
                        let j = jy * size + jx;
                        let e: f64 = (0..3)
                            .map(|k| (prev[k][j] as f64 - pos[k][i] as f64).powi(2))
                            .sum();
                        e <= 4.0 * limit
                    })
                });
                if near {
                    continue;
                }
                uncovered += 1;
                assert_eq!(
                    source[i], TEMPORAL_SOURCE_RESET,
                    "frame {t}, pixel ({x}, {y})"
                );
                for c in 0..3 {
                    let (o, s) = (out.color.planes[c][i], own.planes[c][i]);
                    assert!(
                        (o - s).abs() <= 1e-3 * (s.abs() + 1e-3),
                        "frame {t}, pixel ({x}, {y}), channel {c}: {o} is not this frame's {s}"
                    );
                }
            }
        }
        assert!(
            source.iter().filter(|&&s| s >= 0.0).count() > n / 2,
            "most pixels continue"
        );
    }
    assert!(
        uncovered >= 5,
        "only {uncovered} uncovered pixels in the sequence"
    );
    check_validation(&ctx);
}

/// Configurations the filter cannot run are refused when the denoiser is
/// made: without the position layer, and on the CPU backend.
#[test]
fn temporal_needs_positions_and_the_gpu() {
    let img = &still_frames("cornell", 8, 4, 1)[0];
    let mut c = Config::new(Method::Wlr);
    c.temporal = Temporal::Lp;
    let mut without = img.clone();
    without.remove(Layer::Position);
    let e = Denoiser::new(&gpu(), Source::of_image(&without), c.clone()).unwrap_err();
    assert!(e.to_string().contains("position"), "{e}");
    let e = Denoiser::new_cpu(Source::of_image(img), c).unwrap_err();
    assert!(e.to_string().contains("GPU"), "{e}");
}

/// TEMPORAL-MAP: an adaptive pass's denoiser that reads the final
/// denoiser's temporal state sends relatively more of its budget to the
/// pixels the filter will restart (where the moving box uncovers the
/// wall) than the same pass without it, and no more to the rest.
#[test]
fn adaptive_maps_read_the_temporal_state() {
    let ctx = gpu();
    let size = 48;
    let stats = moving_box(size, 8);
    let last = temporal_denoiser(Method::Wlr, &stats[0]);
    for img in &stats[..7] {
        last.denoise(img, None).unwrap();
    }
    let pass = |state: bool| {
        let mut c = Config::new(Method::Wlr);
        c.pass = mcdenoise::Pass::Intermediate;
        if state {
            c.temporal = Temporal::Lp;
            c.temporal_state = last.temporal_state();
        }
        let d = Denoiser::new(&ctx, Source::of_image(&stats[7]), c).unwrap();
        let budget = (8 * size * size) as u32;
        let out = d.denoise(&stats[7], Some(budget)).unwrap();
        // The map reads the filter's state; the colour is the method's.
        assert_eq!(out.color, spatial_pass(&stats[7]));
        out.samples.unwrap()
    };
    let (aware, plain) = (pass(true), pass(false));
    assert_eq!(
        aware.iter().map(|&c| c as u64).sum::<u64>(),
        plain.iter().map(|&c| c as u64).sum::<u64>()
    );
    let out = last.denoise(&stats[7], None).unwrap();
    let source = debug(&out, "temporal_source");
    let share = |map: &[u32], reset: bool| {
        let (s, k) = map
            .iter()
            .zip(source)
            .filter(|(_, &s)| (s == TEMPORAL_SOURCE_RESET) == reset)
            .fold((0u64, 0u64), |(s, k), (&c, _)| (s + c as u64, k + 1));
        s as f64 / k.max(1) as f64
    };
    let restarted = source
        .iter()
        .filter(|&&s| s == TEMPORAL_SOURCE_RESET)
        .count();
    assert!(restarted >= 10, "{restarted} pixels restart");
    let (ra, ca) = (share(&aware, true), share(&aware, false));
    let (rp, cp) = (share(&plain, true), share(&plain, false));
    assert!(
        ra / ca > 1.05 * (rp / cp),
        "samples per restarting pixel over the rest: {:.2} aware, {:.2} without",
        ra / ca,
        rp / cp
    );
    assert!(
        ca < cp,
        "continuing pixels: {ca:.2} aware vs {cp:.2} without"
    );
    check_validation(&ctx);
}

fn spatial_pass(img: &StatsImage) -> RgbImage {
    let mut c = Config::new(Method::Wlr);
    c.pass = mcdenoise::Pass::Intermediate;
    Denoiser::new(&gpu(), Source::of_image(img), c)
        .unwrap()
        .denoise(img, None)
        .unwrap()
        .color
}

/// The filter reads the method's error estimate (TEMPORAL-INFLATE): a
/// denoiser that does not download it (`Config::error = false`) filters
/// exactly as one that does, for the methods that skip planes nobody
/// reads.
#[test]
fn filtering_does_not_depend_on_downloading_the_error() {
    let stats = moving_box(32, 4);
    for method in [Method::Wlr, Method::Lp] {
        let run = |error: bool| {
            let mut c = Config::new(method);
            c.temporal = Temporal::Lp;
            c.error = error;
            let d = Denoiser::new(&gpu(), Source::of_image(&stats[0]), c).unwrap();
            stats
                .iter()
                .map(|s| d.denoise(s, None).unwrap().color)
                .collect::<Vec<_>>()
        };
        assert_eq!(run(false), run(true), "{method:?}");
    }
}

// ---- The two-way filter (TEMPORAL-SMOOTH) ----

use mcdenoise::kernels::lp_smooth;
use mcdenoise::reference::lp_smooth::{self as smooth_twin, Direction};
use mcdenoise::shared::{full_information, TwoWayPush, SMOOTH_SHORT};
use mcdenoise::{SequenceDenoiser, Smoother};

/// The twin's two-way combination of `forward` and `backward` (each its
/// colour and `P₀₀`) on a frame whose method output is `y`.
fn twin_smooth(
    p: &TwoWayPush,
    y: [&[f32]; 3],
    forward: ([&[f32]; 3], &[f32]),
    backward: ([&[f32]; 3], &[f32]),
) -> [Vec<f32>; 3] {
    let mut out: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; y[0].len()]);
    let [r, g, b] = &mut out;
    smooth_twin::lp_smooth(
        p,
        y,
        &Direction {
            color: forward.0,
            p00: forward.1,
        },
        &Direction {
            color: backward.0,
            p00: backward.1,
        },
        [r, g, b],
    );
    out
}

/// `lp_smooth` against its twin: random colours and `P₀₀` of both
/// directions, some pixels without state (`P₀₀ = 0`, one direction or
/// both), where the forward colour is kept.
#[test]
fn lp_smooth_matches_its_twin() {
    let ctx = gpu();
    for &(w, h) in &[(29usize, 17usize), (1, 9), (8, 8)] {
        let n = w * h;
        let mut rng = Rng(41 + w as u64);
        let mut plane = |scale: f64| -> Vec<f32> {
            (0..n)
                .map(|_| (scale * rng.normal().abs()) as f32)
                .collect()
        };
        let y: Vec<Vec<f32>> = (0..3).map(|_| plane(1.0)).collect();
        let f: Vec<Vec<f32>> = (0..3).map(|_| plane(1.0)).collect();
        let b: Vec<Vec<f32>> = (0..3).map(|_| plane(1.0)).collect();
        let mut pf: Vec<f32> = plane(0.3).iter().map(|p| p.min(1.0) + 0.02).collect();
        let mut pb: Vec<f32> = plane(0.3).iter().map(|p| p.min(1.0) + 0.02).collect();
        pf[0] = 0.0;
        pb[n - 1] = 0.0;
        (pf[n / 2], pb[n / 2]) = (0.0, 0.0);
        fn three(v: &[Vec<f32>]) -> [&[f32]; 3] {
            [&v[0][..], &v[1][..], &v[2][..]]
        }
        let mut ins: Vec<&[f32]> = y.iter().map(|v| &v[..]).collect();
        ins.extend(f.iter().map(|v| &v[..]));
        ins.push(&pf);
        ins.extend(b.iter().map(|v| &v[..]));
        ins.push(&pb);
        // No direction short of its full information; many; the two
        // directions' full informations apart.
        for (full_forward, full_backward) in [(1.0, 1.0), (20.0, 20.0), (4.0, 30.0)] {
            let p = TwoWayPush {
                width: w as u32,
                height: h as u32,
                full_forward,
                full_backward,
                ..Default::default()
            };
            let want = twin_smooth(&p, three(&y), (three(&f), &pf), (three(&b), &pb));
            for i in [0, n - 1, n / 2] {
                assert_eq!(want[0][i], f[0][i], "pixel {i} without state keeps F");
            }
            for prec in precisions() {
                let (g, _) = run_planes(
                    &ctx,
                    &lp_smooth::DECL,
                    prec,
                    bytemuck::bytes_of(&p),
                    w,
                    h,
                    &ins,
                    &[n, n, n],
                    lp_smooth::FLOPS_PER_PIXEL,
                )
                .unwrap();
                for c in 0..3 {
                    let what = format!("{w}x{h} {prec:?} {c} full {full_forward} {full_backward}");
                    assert_close(&what, &g[c], &want[c], 0.99);
                }
            }
        }
    }
    check_validation(&ctx);
}

/// TEMPORAL-SMOOTH's invariant: with `λ = 1` (and no change test), the
/// filter in frame order and in reverse order, combined, give every frame
/// the mean of the whole sequence.
#[test]
fn two_way_with_lambda_one_is_the_mean_of_every_frame() {
    let prior = (TEMPORAL_RESET_P00 as f64, TEMPORAL_RESET_P11 as f64);
    let ys = [1.0, 3.0, 2.0, 6.0, 4.0, 0.5, 2.5];
    let mean = ys.iter().sum::<f64>() / ys.len() as f64;
    let run = |order: &mut dyn Iterator<Item = &f64>| -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let mut s: Option<PixelState> = None;
        for &y in order {
            s = Some(match s {
                None => PixelState::reset([y; 3], [0.0; 3], prior),
                Some(s) => {
                    let mut s = s.shifted();
                    s.update([y; 3], 1.0);
                    s
                }
            });
            let s = s.as_ref().unwrap();
            out.push((s.predict()[0], s.p[0]));
        }
        out
    };
    let forward = run(&mut ys.iter());
    let mut backward = run(&mut ys.iter().rev());
    backward.reverse();
    for (t, &y) in ys.iter().enumerate() {
        // With λ = 1 a direction that met no change holds one unit per frame.
        let n = ys.len() as u64;
        let full = (
            full_information(t as u64 + 1, 1.0, prior.0),
            full_information(n - t as u64, 1.0, prior.0),
        );
        let v = smooth_twin::combine(y, forward[t], backward[t], full);
        assert!(
            close(v, mean, 1e-12),
            "frame {t}: {v} against the mean {mean}"
        );
    }
}

/// SMOOTH-SHORT: a direction short of the information its frames give (it
/// met a change) caps the other's weight at its own; a direction at its
/// full information leaves the combination TEMPORAL-SMOOTH's. The kernel
/// mirrors the crate's fraction.
#[test]
fn a_direction_that_met_a_change_caps_the_other() {
    let (y, f, b) = (1.0, 2.0, 4.0);
    // Forward: 10 frames' information of 11 possible (not short); reverse:
    // 2 of 6 (short).
    let full = (11.0, 6.0);
    let two_way = |af: f64, ab: f64| (af * f + ab * b - y) / (af + ab - 1.0);
    let capped = smooth_twin::combine(y, (f, 0.1), (b, 0.5), full);
    assert!(close(capped, two_way(2.0, 2.0), 1e-12), "{capped}");
    assert!(!close(capped, two_way(10.0, 2.0), 1e-3));
    // The reverse direction at its full information: no cap.
    let full = (11.0, 2.0);
    let plain = smooth_twin::combine(y, (f, 0.1), (b, 0.5), full);
    assert!(close(plain, two_way(10.0, 2.0), 1e-12), "{plain}");
    // Both short: the weaker weighs as itself, the stronger as the weaker.
    let both = smooth_twin::combine(y, (f, 0.25), (b, 0.5), (11.0, 6.0));
    assert!(close(both, two_way(2.0, 2.0), 1e-12), "{both}");
    // Just above the fraction: not short.
    let edge = smooth_twin::combine(
        y,
        (f, 0.1),
        (b, 0.5),
        (11.0, 2.0 / SMOOTH_SHORT as f64 - 1e-6),
    );
    assert!(close(edge, two_way(10.0, 2.0), 1e-12), "{edge}");
    let source = include_str!("../spirv/lp_smooth.comp");
    let value: f32 = common::shader_define(source, "SMOOTH_SHORT");
    assert_eq!(value, SMOOTH_SHORT);
    // The information of a history without a change: 1, then λa + 1.
    let mut a = 0.0;
    for k in 0..30u64 {
        a = if k == 0 { 1.0 } else { 0.98 * a + 1.0 };
        assert!(close(full_information(k + 1, 0.98, 1.0), a, 1e-12), "{k}");
    }
    assert_eq!(full_information(0, 0.98, 1.0), 0.0);
}

/// SMOOTH-SHORT's frame counts in the facade: each frame `k` of `n` of a
/// `SequenceDenoiser`'s two-way filter is the twin's combination of the
/// filter in frame order and the filter over the reversed frames with the
/// full informations of `k + 1` and `n − k` frames; with the two swapped
/// some frame differs (the noise makes directions short).
#[test]
fn two_way_counts_each_directions_frames() {
    let frames = still_frames("cornell", 24, 4, 6);
    let n = frames.len();
    let run = |order: Vec<&StatsImage>| -> Vec<(RgbImage, Vec<f32>)> {
        let d = temporal_denoiser(Method::None, &frames[0]);
        order
            .into_iter()
            .map(|s| {
                let f = d.denoise(s, None).unwrap();
                let p00 = debug(&f, "temporal_p00").to_vec();
                (f.color, p00)
            })
            .collect()
    };
    let forward = run(frames.iter().collect());
    let mut backward = run(frames.iter().rev().collect());
    backward.reverse();
    let mut c = Config::new(Method::None);
    c.temporal = Temporal::LpSmooth;
    let mut seq = SequenceDenoiser::new(&gpu(), Source::of_image(&frames[0]), c).unwrap();
    for img in &frames {
        seq.push(img).unwrap();
    }
    let out = seq.finish().unwrap();
    let full = |m: usize| {
        full_information(m as u64, TEMPORAL_LAMBDA as f64, TEMPORAL_RESET_P00 as f64) as f32
    };
    let mut swapped_differs = false;
    for k in 0..n {
        let y = spatial(Method::None, &frames[k]);
        let combine = |full_forward: f32, full_backward: f32| {
            let p = TwoWayPush {
                full_forward,
                full_backward,
                ..Default::default()
            };
            twin_smooth(
                &p,
                y.plane_slices(),
                (forward[k].0.plane_slices(), &forward[k].1),
                (backward[k].0.plane_slices(), &backward[k].1),
            )
        };
        let want = combine(full(k + 1), full(n - k));
        for c in 0..3 {
            assert_close(
                &format!("frame {k} {c}"),
                &out[k].1.color.planes[c],
                &want[c],
                0.99,
            );
        }
        let swapped = combine(full(n - k), full(k + 1));
        swapped_differs |= (0..3).any(|c| {
            swapped[c]
                .iter()
                .zip(&want[c])
                .any(|(a, b)| (a - b).abs() > 1e-4 * (1.0 + b.abs()))
        });
    }
    assert!(swapped_differs, "no frame depends on the counts");
    check_validation(&gpu());
}

/// The two-way filter in the facade, on a static camera over a static
/// scene: every frame comes out of `finish`, in order; each is well below
/// its frame alone's rMSE and, but for the last (where the two are the
/// same), below the filter in frame order's, the first as well (it sees
/// the frames after it, where the filter in frame order has only the frame
/// itself); `finish` ends the sequence, and a sequence of one frame is
/// that frame's own reconstruction.
#[test]
fn two_way_gives_every_frame_the_whole_sequence() {
    let ctx = gpu();
    let frames = still_frames("cornell", 32, 32, 8);
    let reference = {
        let s = still_frames("cornell", 32, 1024, 1);
        mcdenoise::colour_of(&s[0])
    };
    let mut c = Config::new(Method::None);
    c.temporal = Temporal::LpSmooth;
    let mut seq = SequenceDenoiser::new(&ctx, Source::of_image(&frames[0]), c).unwrap();
    assert_eq!(seq.lag(), None);
    for img in &frames {
        assert!(seq.push(img).unwrap().is_empty());
    }
    assert_eq!(seq.pushed(), frames.len());
    let out = seq.finish().unwrap();
    assert_eq!(seq.pushed(), 0);
    assert_eq!(
        out.iter().map(|(t, _)| *t).collect::<Vec<_>>(),
        (0..frames.len()).collect::<Vec<_>>()
    );
    let d = temporal_denoiser(Method::None, &frames[0]);
    for (t, (_, f)) in out.iter().enumerate() {
        let alone = metrics::rmse(&spatial(Method::None, &frames[t]), &reference);
        let forward = metrics::rmse(&d.denoise(&frames[t], None).unwrap().color, &reference);
        let both = metrics::rmse(&f.color, &reference);
        assert!(
            both < 0.6 * alone,
            "frame {t}: {both:.5} two-way, {alone:.5} alone"
        );
        // The last frame: the reverse pass holds the frame alone, and the
        // combination is the forward filter's.
        let bound = if t + 1 < out.len() {
            forward
        } else {
            1.0001 * forward
        };
        assert!(
            both <= bound,
            "frame {t}: {both:.5} two-way, {forward:.5} in frame order"
        );
    }
    seq.push(&frames[3]).unwrap();
    let one = seq.finish().unwrap();
    let own = spatial(Method::None, &frames[3]);
    for c in 0..3 {
        assert_close("one frame", &one[0].1.color.planes[c], &own.planes[c], 1.0);
    }
    check_validation(&ctx);
}

/// A `Smoother` keeps every frame of its denoiser's sequence right after
/// its call: a denoiser without the filter, a frame skipped, a history
/// from before the sequence or a reset within it are errors that keep
/// nothing; `Temporal::LpSmooth` is refused by a `Denoiser` and
/// `Temporal::Lp` by a `SequenceDenoiser`.
#[test]
fn the_smoother_refuses_what_it_cannot_combine() {
    let ctx = gpu();
    let frames = still_frames("cornell", 16, 4, 3);
    let source = Source::of_image(&frames[0]);
    let plain = Denoiser::new(&ctx, source.clone(), Config::new(Method::Wlr)).unwrap();
    let e = Smoother::new(&ctx, &plain).unwrap_err().to_string();
    assert!(e.contains("temporal lp"), "{e}");
    let d = temporal_denoiser(Method::Wlr, &frames[0]);
    let mut s = Smoother::new(&ctx, &d).unwrap();
    let f0 = d.denoise(&frames[0], None).unwrap();
    s.keep(&d, &f0.color).unwrap();
    d.denoise(&frames[1], None).unwrap();
    let f2 = d.denoise(&frames[2], None).unwrap();
    let e = s.keep(&d, &f2.color).unwrap_err().to_string();
    assert!(e.contains("ran 2 frame(s) since the last keep"), "{e}");
    assert_eq!(s.len(), 1);
    d.reset();
    let f = d.denoise(&frames[1], None).unwrap();
    let e = s.keep(&d, &f.color).unwrap_err().to_string();
    assert!(e.contains("was reset"), "{e}");
    assert_eq!(s.finish().unwrap().len(), 1);
    assert!(s.is_empty());
    let f = d.denoise(&frames[2], None).unwrap();
    let e = s.keep(&d, &f.color).unwrap_err().to_string();
    assert!(e.contains("reset it (Denoiser::reset)"), "{e}");
    let mut c = Config::new(Method::Wlr);
    c.temporal = Temporal::LpSmooth;
    let e = Denoiser::new(&ctx, source.clone(), c)
        .unwrap_err()
        .to_string();
    assert!(e.contains("use a SequenceDenoiser"), "{e}");
    let mut c = Config::new(Method::Wlr);
    c.temporal = Temporal::Lp;
    let e = SequenceDenoiser::new(&ctx, source, c)
        .unwrap_err()
        .to_string();
    assert!(e.contains("temporal lp-smooth"), "{e}");
    check_validation(&ctx);
}

/// A `Smoother` keeps its frames in a temporary file and empties it at
/// `finish`: the same frames kept again after a reset come out bit for bit
/// the same, and `finish_each` hands them over last first.
#[test]
fn the_smoother_reuses_its_file_and_hands_frames_last_first() {
    let ctx = gpu();
    let frames = still_frames("cornell", 16, 4, 4);
    let d = temporal_denoiser(Method::Wlr, &frames[0]);
    let mut s = Smoother::new(&ctx, &d).unwrap();
    let keep_all = |s: &mut Smoother| {
        d.reset();
        for img in &frames {
            let f = d.denoise(img, None).unwrap();
            s.keep(&d, &f.color).unwrap();
        }
        assert_eq!(s.len(), frames.len());
    };
    keep_all(&mut s);
    let first = s.finish().unwrap();
    assert!(s.is_empty());
    keep_all(&mut s);
    let mut order = Vec::new();
    s.finish_each(|t, color, _| {
        order.push(t);
        for c in 0..3 {
            assert_eq!(
                color.planes[c], first[t].0.planes[c],
                "frame {t}, channel {c}"
            );
        }
        Ok(())
    })
    .unwrap();
    assert_eq!(order, vec![3, 2, 1, 0]);
    assert!(s.is_empty());
    check_validation(&ctx);
}

/// A position field: pixel `(x, y)` of the previous frame saw the point
/// `field(x, y)`; a smooth, one-to-one surface.
fn field(x: f64, y: f64) -> [f32; 3] {
    [
        (0.01 * x) as f32,
        (0.01 * y) as f32,
        (0.1 * (0.07 * x).sin()) as f32,
    ]
}

/// Two frames of a static scene under a camera that moved: frame 1's pixel
/// `(x, y)` sees what frame 0's `(x + sx, y + sy)` saw.
fn panned(w: usize, h: usize, (sx, sy): (i32, i32), rng: &mut Rng) -> [Synthetic; 2] {
    let n = w * h;
    std::array::from_fn(|t| {
        let (ox, oy) = if t == 0 { (0, 0) } else { (sx, sy) };
        let mut f = Synthetic {
            w,
            h,
            color: std::array::from_fn(|_| vec![0.0; n]),
            position: std::array::from_fn(|_| vec![0.0; n]),
            variance: std::array::from_fn(|_| vec![1e-7; n]),
            error: std::array::from_fn(|_| vec![0.0025; n]),
            depth: vec![1.0; n],
            spp: vec![16.0; n],
        };
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let p = field((x as i32 + ox) as f64, (y as i32 + oy) as f64);
                for k in 0..3 {
                    f.position[k][i] = p[k];
                    f.color[k][i] = (0.4 + 0.3 * p[k] as f64 + 0.05 * rng.normal()).max(0.0) as f32;
                }
            }
        }
        f
    })
}

/// Where each pixel's reprojected state came from, as one number: the
/// offset `(dx, dy)` from the pixel (the window's centre `(mx, my)` plus
/// the debug plane `source`'s offset) as `dy · 1000 + dx`; `source` itself
/// where the pixel was reset or passed through.
fn absolute(source: &[f32], mx: &[f32], my: &[f32]) -> Vec<f32> {
    source
        .iter()
        .zip(mx.iter().zip(my))
        .map(|(&s, (&x, &y))| {
            if s < 0.0 {
                return s;
            }
            let (dx, dy) = (s as i32 % 7 - 3 + x as i32, s as i32 / 7 - 3 + y as i32);
            (dy * 1000 + dx) as f32
        })
        .collect()
}

/// `temporal_motion` against its twin on one level: random positions and
/// counts (some pixels empty), with and without a coarser level's offsets.
#[test]
fn temporal_motion_matches_its_twin() {
    let ctx = gpu();
    let (w, h, cw, ch) = (23usize, 14usize, 12usize, 7usize);
    let n = w * h;
    let mut rng = Rng(41);
    let plane = |rng: &mut Rng, scale: f64| -> Vec<f32> {
        (0..n).map(|_| (scale * rng.normal()) as f32).collect()
    };
    let counts = |rng: &mut Rng| -> Vec<f32> {
        (0..n)
            .map(|_| if rng.normal() > -1.5 { 4.0 } else { 0.0 })
            .collect()
    };
    let cur: Vec<Vec<f32>> = vec![
        plane(&mut rng, 1.0),
        plane(&mut rng, 1.0),
        plane(&mut rng, 1.0),
        counts(&mut rng),
    ];
    let prev: Vec<Vec<f32>> = vec![
        plane(&mut rng, 1.0),
        plane(&mut rng, 1.0),
        plane(&mut rng, 1.0),
        counts(&mut rng),
    ];
    let coarse: Vec<Vec<f32>> = (0..2)
        .map(|_| {
            (0..cw * ch)
                .map(|_| (rng.normal() * 2.0).round() as f32)
                .collect()
        })
        .collect();
    for has_coarse in [0u32, 1] {
        let push = MotionPush {
            width: w as u32,
            height: h as u32,
            coarse: has_coarse,
            coarse_width: cw as u32,
            coarse_height: ch as u32,
            radius: 2,
            ..Default::default()
        };
        let mut want: [Vec<f32>; 2] = std::array::from_fn(|_| vec![0.0; n]);
        {
            let [a, b] = &mut want;
            let c4 = [&cur[0][..], &cur[1][..], &cur[2][..], &cur[3][..]];
            let p4 = [&prev[0][..], &prev[1][..], &prev[2][..], &prev[3][..]];
            motion_twin::temporal_motion(&push, c4, p4, [&coarse[0], &coarse[1]], [a, b]);
        }
        if has_coarse == 1 {
            assert!(
                want[0].iter().any(|&v| v.abs() > 2.0),
                "the coarse offsets move the centre"
            );
        }
        let ins: Vec<&[f32]> = cur
            .iter()
            .chain(&prev)
            .chain(&coarse)
            .map(|v| &v[..])
            .collect();
        for prec in precisions() {
            let (g, _) = run_planes(
                &ctx,
                &temporal_motion::DECL,
                prec,
                bytemuck::bytes_of(&push),
                w,
                h,
                &ins,
                &[n, n],
                temporal_motion::FLOPS_PER_PIXEL,
            )
            .unwrap();
            for k in 0..2 {
                let agree = agreement(&g[k], &want[k]);
                assert!(
                    agree >= 0.98,
                    "coarse {has_coarse} {prec:?} offset {k}: {agree}"
                );
            }
        }
    }
    check_validation(&ctx);
}

/// TEMPORAL-MOTION: a camera that moved 17 pixels across and 5 up between
/// two frames, beyond the 7×7 window. Without the motion search every
/// pixel resets; with it (twin), the windows centre within a pixel of
/// the shift and the pixels whose surface was in view continue their
/// history; the GPU's stage (each precision) does what the twin does.
#[test]
fn motion_follows_a_pan_beyond_the_window() {
    use mcdenoise::gpu::{buffer::read_slice, Batch, PlaneSet};
    use mcdenoise::kernels::lp_temporal::TemporalIn;
    use mcdenoise::methods::temporal::TemporalStage;

    let (w, h, shift) = (96usize, 64usize, (17i32, -5i32));
    let n = w * h;
    let frames = panned(w, h, shift, &mut Rng(5));
    let seen = |i: usize| {
        let (x, y) = ((i % w) as i32 + shift.0, (i / w) as i32 + shift.1);
        x >= 0 && y >= 0 && x < w as i32 && y < h as i32
    };
    let inside: Vec<usize> = (0..n).filter(|&i| seen(i)).collect();
    let mut twin_sources = Vec::new();
    for flags in [0, TEMPORAL_MOTION] {
        let (s0, _, _) = twin_frame(
            &push(w, h, TEMPORAL_RESET),
            &frames[0],
            &vec![0.0; TEMPORAL_STATE * n],
        );
        let p = push(w, h, flags);
        let (_, out, source) = twin_frame(&p, &frames[1], &s0);
        let carried = inside.iter().filter(|&&i| source[i] >= 0.0).count();
        if flags == 0 {
            assert!(
                carried * 20 <= inside.len(),
                "without motion {carried} of {} carried",
                inside.len()
            );
            continue;
        }
        assert!(
            carried * 20 >= inside.len() * 19,
            "with motion {carried} of {} carried",
            inside.len()
        );
        let m = twin::frame_motion(&p, &inputs(&frames[1]), &s0).unwrap();
        let near = inside
            .iter()
            .filter(|&&i| {
                let c = m.centre(i % w, i / w);
                (c.0 - shift.0).abs() <= 1 && (c.1 - shift.1).abs() <= 1
            })
            .count();
        assert!(
            near * 20 >= inside.len() * 19,
            "{near} of {} centred on the shift",
            inside.len()
        );
        let tx: Vec<f32> = (0..n).map(|i| m.centre(i % w, i / w).0 as f32).collect();
        let ty: Vec<f32> = (0..n).map(|i| m.centre(i % w, i / w).1 as f32).collect();
        let from = absolute(&source, &tx, &ty);
        twin_sources = vec![source, out[0].clone(), from];
    }
    let ctx = gpu();
    for prec in precisions() {
        let stage = TemporalStage::new(&ctx, w, h).unwrap();
        let planes = PlaneSet::new(&ctx, "test.inputs", n, 14).unwrap();
        let mut last = Vec::new();
        for f in &frames {
            let data: Vec<&Vec<f32>> = f
                .color
                .iter()
                .chain(&f.position)
                .chain(&f.variance)
                .chain([&f.depth, &f.spp])
                .chain(&f.error)
                .collect();
            for (k, v) in data.into_iter().enumerate() {
                planes.upload_plane(k, v).unwrap();
            }
            let inp = TemporalIn::from_planes(|k| planes.plane(k));
            let mut batch = Batch::new(&ctx).unwrap();
            stage.record(&mut batch, prec, &inp).unwrap();
            batch.finish().unwrap();
            last = vec![
                read_slice(&ctx, stage.source(), n).unwrap(),
                read_slice(&ctx, stage.color()[0], n).unwrap(),
            ];
        }
        // Where each pixel's state came from (the centre plus the source's
        // offset), as the centres may differ on a tie (a shift of 5 is 2.5
        // at half resolution) where the window finds the same pixel.
        let dbg = stage.debug_layers(last[0].clone()).unwrap();
        let gpu_from = absolute(&last[0], &dbg[2].1, &dbg[3].1);
        let agree = agreement(&gpu_from, &twin_sources[2]);
        assert!(agree >= 0.98, "{prec:?}: source agrees on {agree}");
        assert_close(
            &format!("{prec:?} colour"),
            &last[1],
            &twin_sources[1],
            0.98,
        );
    }
    check_validation(&ctx);
}

/// A frame of the plane z = 0 at 0.01 per pixel: pixel `i` sees the
/// point `at(i)` (in pixels of the previous frame), grey `colour(i)`,
/// noiseless positions, error 0.01, depth 1, 16 spp.
fn on_a_plane(
    (w, h): (usize, usize),
    colour: impl Fn(usize) -> f64,
    at: impl Fn(usize) -> (f64, f64),
) -> Synthetic {
    let n = w * h;
    Synthetic {
        w,
        h,
        color: std::array::from_fn(|_| (0..n).map(|i| colour(i) as f32).collect()),
        position: [
            (0..n).map(|i| (0.01 * at(i).0) as f32).collect(),
            (0..n).map(|i| (0.01 * at(i).1) as f32).collect(),
            vec![0.0; n],
        ],
        variance: std::array::from_fn(|_| vec![0.0; n]),
        error: std::array::from_fn(|_| vec![0.01; n]),
        depth: vec![1.0; n],
        spp: vec![16.0; n],
    }
}

/// TEMPORAL-MISREG: where the surface moved on screen, a state carried from
/// another pixel counts for less where the previous frame's picture
/// changes fast around it. A long
/// history (`P00` 0.05) of a step edge (1 left of x = 5, 10 from it),
/// every pixel's surface moved one pixel left: the pixel whose state comes
/// from beside the edge keeps about one frame's weight, one whose state
/// comes from the flat part keeps its history.
#[test]
fn a_state_from_another_pixel_weighs_less_across_an_edge() {
    let (w, h) = (9usize, 3usize);
    let n = w * h;
    let level = |x: usize| if x < 5 { 1.0f64 } else { 10.0 };
    let mut prev = vec![0.0f32; TEMPORAL_STATE * n];
    for y in 0..h {
        for x in 0..w {
            let s = PixelState {
                beta: [[level(x), 0.0]; 3],
                p: [0.05, 0.0, 0.0],
                w: [0.01 * x as f64, 0.01 * y as f64, 0.0],
            };
            twin::store(&mut prev, n, y * w + x, Some(&s));
        }
    }
    // Each pixel sees what its right neighbour saw.
    let f = on_a_plane(
        (w, h),
        |i| level((i % w + 1).min(w - 1)),
        |i| ((i % w + 1) as f64, (i / w) as f64),
    );
    let p = push(w, h, 0);
    // The motion search's offset (1, 0), or none (the window on the pixel).
    let p00 =
        |x: usize, centre: (i32, i32)| match twin::step(&p, &inputs(&f), &prev, (x, 1), centre) {
            twin::Step::Continue(s, (dx, dy)) => {
                let from = (centre.0 + dx, centre.1 + dy);
                assert_eq!(from, (1, 0), "pixel {x} continues its surface");
                s.p[0]
            }
            other => panic!("pixel {x}: {other:?}"),
        };
    assert!(p00(2, (1, 0)) < 0.1, "flat: P00 {}", p00(2, (1, 0)));
    assert!(
        p00(3, (1, 0)) > 0.9,
        "beside the edge: P00 {}",
        p00(3, (1, 0))
    );
    assert!(p00(5, (1, 0)) < 0.1, "flat: P00 {}", p00(5, (1, 0)));
    // Where the search saw no motion the state counts as it did.
    assert!(p00(3, (0, 0)) < 0.1, "no motion: P00 {}", p00(3, (0, 0)));
}

/// TEMPORAL-SUBPIXEL: under a camera that moved by (1.4, 0.3) pixels, over
/// a plane whose colour is a linear ramp, the state carried from the
/// previous frame is resampled at the surface point the pixel now sees,
/// which its position says: the prediction is the ramp there, and the
/// output with it. Where the search saw no motion the state is carried by
/// whole pixels, 0.4 of a pixel off.
#[test]
fn a_state_between_pixels_is_resampled_where_the_surface_moved() {
    let (w, h) = (12usize, 8usize);
    let n = w * h;
    let ramp = |x: f64, _y: f64| 0.2 + 0.05 * x;
    let mut prev = vec![0.0f32; TEMPORAL_STATE * n];
    for y in 0..h {
        for x in 0..w {
            let s = PixelState {
                beta: [[ramp(x as f64, y as f64), 0.0]; 3],
                p: [0.05, 0.0, 0.0],
                w: [0.01 * x as f64, 0.01 * y as f64, 0.0],
            };
            twin::store(&mut prev, n, y * w + x, Some(&s));
        }
    }
    let (sx, sy) = (1.4, 0.3);
    let at = |i: usize| ((i % w) as f64 + sx, (i / w) as f64 + sy);
    let f = on_a_plane((w, h), |i| ramp(at(i).0, at(i).1), at);
    let p = push(w, h, 0);
    let mut checked = 0;
    for y in 1..h - 2 {
        for x in 1..w - 3 {
            let (tx, ty) = at(y * w + x);
            let truth = ramp(tx, ty);
            match twin::step(&p, &inputs(&f), &prev, (x, y), (1, 0)) {
                twin::Step::Continue(s, _) => {
                    let out = s.predict()[0];
                    assert!(
                        (out - truth).abs() < 1e-6,
                        "pixel ({x}, {y}): {out} against the ramp's {truth}"
                    );
                    checked += 1;
                }
                other => panic!("pixel ({x}, {y}): {other:?}"),
            }
            // Where the search saw no motion the state is carried as it is.
            if let twin::Step::Continue(s, _) = twin::step(&p, &inputs(&f), &prev, (x, y), (0, 0)) {
                let from = s.predict()[0];
                assert!(
                    (from - truth).abs() > 0.01,
                    "({x}, {y}) unmoved: {from}, {truth}"
                );
            }
        }
    }
    assert!(checked >= 30, "{checked} pixels");
    // The kernel, with the motion search finding the move, does the same.
    let p = push(w, h, TEMPORAL_MOTION);
    let (_, want, _) = twin_frame(&p, &f, &prev);
    for prec in precisions() {
        let g = gpu_frame(&p, &f, &prev, prec);
        for y in 1..h - 2 {
            for x in 1..w - 3 {
                let i = y * w + x;
                let (tx, ty) = at(i);
                let truth = ramp(tx, ty) as f32;
                assert!(
                    (g[1][i] - want[0][i]).abs() < 1e-5 && (g[1][i] - truth).abs() < 1e-5,
                    "{prec:?} ({x}, {y}): {} against the twin's {} and the ramp's {truth}",
                    g[1][i],
                    want[0][i]
                );
            }
        }
    }
}
