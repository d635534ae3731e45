//! Scalar twin of `spirv/apr_gather.comp`: APR's blend (spec §4.3, Eq. 6)
//! for every pixel and channel. A valid pixel averages, with the weights
//! `K_h^c(i)`, the outputs `x_iᵀβ` of the sparse blocks within 14 that
//! accept it (in raster order), their `ξ̂_c` and `tr H_c`; a pixel none
//! accepts takes its own extra block's values (COVER, written by
//! `apr_block` in extra mode). Every stage but the last writes `ŷ_t` and
//! `σ̂_t²` (the blend of `H s`, squared); the last writes the colour
//! (clamped ≥ 0), `ξ̂_i`, the mean over the channels of `tr H` (the local
//! dimension `d_i` of §9.1) and the extra-centre mask.
//!
//! An invalid pixel (§0.2) outputs the mean of the valid pixels of its 3×3
//! neighbourhood in `y` (0 if none), error `v_i`, dimension 1; in an
//! intermediate stage it keeps `y_i`, `v_i`.

use super::apr_block::{
    covering, row_in, weight, Inputs, NF, P, STATE, ST_BETA_S, ST_BETA_Y, ST_SCALES,
};

pub use crate::shared::{
    APR_EXTRA_PLANES as EXTRA_PLANES, APR_OUTPUTS as OUTPUTS, APR_STAGE_OUTPUTS as STAGE_OUTPUTS,
};

/// One state record of `state` (a channel's `grid` of blocks): `None` for
/// an invalid centre (all-zero record, degenerate flag unset and `β` zero
/// can not tell; the caller checks validity).
fn eval(inp: &Inputs, st: &[f32], c: usize, i: usize, s: bool, temporal: bool) -> f64 {
    let mut scales = [0.0; NF];
    for (j, sc) in scales.iter_mut().enumerate() {
        *sc = st[ST_SCALES + j] as f64;
    }
    let x = row_in(inp, inp, c, &scales, i, temporal.then_some(0));
    let off = if s { ST_BETA_S } else { ST_BETA_Y };
    (0..P).map(|j| x[j] * st[off + j] as f64).sum()
}

/// The gather of one stage: `inp[ch]` the channels' inputs (the stage's
/// `yprev`/`s2prev` are not read), `state[ch]` their block states
/// (`grid` order, [`STATE`] f32 each), `extra` the `3·EXTRA_PLANES` extra
/// planes. Returns [`OUTPUTS`] planes when `last`, else [`STAGE_OUTPUTS`].
pub fn apr_gather(
    inp: &[Inputs; 3],
    state: &[Vec<f32>; 3],
    extra: &[Vec<f32>],
    last: bool,
) -> Vec<Vec<f32>> {
    apr_gather_in(inp, state, extra, last, false)
}

/// [`apr_gather`] of the centre frame of a temporal window (§10.2) when
/// `temporal`: the blocks' temporal design at `τ = 0`.
pub fn apr_gather_in(
    inp: &[Inputs; 3],
    state: &[Vec<f32>; 3],
    extra: &[Vec<f32>],
    last: bool,
    temporal: bool,
) -> Vec<Vec<f32>> {
    let (w, h) = (inp[0].w, inp[0].h);
    let n = w * h;
    let (gw, _) = super::apr_block::grid(w, h);
    let r = super::apr_block::RADIUS as usize;
    let mut out = vec![vec![0.0f32; n]; if last { OUTPUTS } else { STAGE_OUTPUTS }];
    for i in 0..n {
        let mut dim = 0.0;
        for ch in 0..3 {
            let pl = &inp[ch];
            let (y, s, e, d, ex) = if !pl.valid(i) {
                let fill = invalid_fill(pl, i);
                let v = (pl.v[i] as f64).max(0.0);
                (
                    if last { fill } else { pl.y[i] as f64 },
                    v.sqrt(),
                    pl.v[i] as f64,
                    1.0,
                    0.0,
                )
            } else {
                let limit = pl.pixel_test.then(|| {
                    super::pixel_test_limit(
                        w,
                        h,
                        |q| pl.v[q] as f64,
                        |q| (pl.y[q] as f64 - pl.y[i] as f64).powi(2),
                        |q| pl.valid(q),
                        pl.spp,
                        i,
                    )
                });
                let yi = pl.y[i] as f64;
                let mut missed = false;
                let (mut ws, mut ay, mut as_, mut ae, mut ad) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for c in covering(w, h, i) {
                    if !pl.valid(c) || !pl.accepts(c, i) {
                        continue;
                    }
                    let b = (c / w / r) * gw + (c % w) / r;
                    let st = &state[ch][b * STATE..(b + 1) * STATE];
                    let k = weight(w, c, i);
                    let fy = eval(pl, st, c, i, false, temporal);
                    if limit.is_some_and(|l| (fy - yi).powi(2) > l) {
                        missed = true;
                        continue;
                    }
                    ws += k;
                    ay += k * fy;
                    if !last {
                        as_ += k * eval(pl, st, c, i, true, temporal);
                    }
                    ae += k * st[1] as f64;
                    ad += k * st[2] as f64;
                }
                if ws > 0.0 {
                    (ay / ws, as_ / ws, ae / ws, ad / ws, 0.0)
                } else if missed {
                    // APR-PIXEL-TEST left out every accepting block.
                    let v = pl.v[i] as f64;
                    (yi, v.max(0.0).sqrt(), v, 0.0, 0.0)
                } else {
                    let x = |k: usize| extra[ch * super::apr_gather::EXTRA_PLANES + k][i] as f64;
                    (x(0), x(1), x(2), x(3), 1.0)
                }
            };
            if last {
                out[ch][i] = y.max(0.0) as f32;
                out[3 + ch][i] = e as f32;
                out[7 + ch][i] = ex as f32;
                dim += d / 3.0;
            } else {
                out[ch][i] = y as f32;
                out[3 + ch][i] = (s * s) as f32;
            }
        }
        if last {
            out[6][i] = dim as f32;
        }
    }
    out
}

/// §0.2: the mean of the valid pixels of `i`'s 3×3 neighbourhood in `y`
/// (0 if none).
pub fn invalid_fill(pl: &Inputs, i: usize) -> f64 {
    super::valid_mean_3x3(pl.w, pl.h, i, |q| pl.valid(q), |q| pl.y[q] as f64)
}

/// The whole of APR on one image with the twins, in the kernels' order
/// (per stage: sparse blocks, extra blocks, gather): `inp[ch]` with
/// `yprev = y`, `s2prev = v`; `eps` the pivot threshold (1e-12 for f64).
/// Returns the last gather's [`OUTPUTS`] planes and the last stage's
/// states.
pub fn run(inp: &[Inputs; 3], stages: usize, eps: f64) -> (Vec<Vec<f32>>, [Vec<f32>; 3]) {
    let stages = stages.max(1);
    let mut prev: Option<Vec<Vec<f32>>> = None;
    for stage in 1..=stages {
        let last = stage == stages;
        let chans: [Inputs; 3] = std::array::from_fn(|ch| {
            let mut c = inp[ch];
            if let Some(p) = &prev {
                c.yprev = &p[ch];
                c.s2prev = &p[3 + ch];
            }
            c
        });
        let one: [[Option<Inputs>; 1]; 3] = std::array::from_fn(|ch| [Some(chans[ch])]);
        let (state, extra) = stage_blocks(std::array::from_fn(|ch| &one[ch][..]), last, eps);
        let out = apr_gather(&chans, &state, &extra, last);
        if last {
            return (out, state);
        }
        prev = Some(out);
    }
    unreachable!("stages >= 1")
}

/// §10.2, APR's temporal window, on a sequence with the twins:
/// `frames[t][ch]` each frame's inputs (`yprev = y`, `s2prev = v`). Stage
/// by stage over the whole sequence: every frame's blocks fit the frames
/// `t−2..t+2` that exist (stage `s ≥ 2` on their stage-`s−1` planes), its
/// gather writes its own planes. Returns each frame's last [`OUTPUTS`]
/// planes.
pub fn run_sequence(frames: &[[Inputs; 3]], stages: usize, eps: f64) -> Vec<Vec<Vec<f32>>> {
    use super::apr_block::{FRAMES, HALF};
    let nf = frames.len();
    let stages = stages.max(1);
    let mut prev: Vec<Vec<Vec<f32>>> = Vec::new();
    for stage in 1..=stages {
        let last = stage == stages;
        let chans = |t: usize| -> [Inputs; 3] {
            std::array::from_fn(|ch| {
                let mut c = frames[t][ch];
                if let Some(p) = prev.get(t) {
                    c.yprev = &p[ch];
                    c.s2prev = &p[3 + ch];
                }
                c
            })
        };
        let mut outs = Vec::with_capacity(nf);
        for t in 0..nf {
            let centre = chans(t);
            let window: [[Option<Inputs>; FRAMES]; 3] = std::array::from_fn(|ch| {
                std::array::from_fn(|k| {
                    let t2 = (t + k).checked_sub(HALF).filter(|&t2| t2 < nf)?;
                    Some(chans(t2)[ch])
                })
            });
            let (state, extra) = stage_blocks(std::array::from_fn(|ch| &window[ch][..]), last, eps);
            outs.push(apr_gather_in(&centre, &state, &extra, last, true));
        }
        if last {
            return outs;
        }
        prev = outs;
    }
    unreachable!("stages >= 1")
}

/// One stage's blocks of the three channels, each over the frames of its
/// window (one frame, or §10.2's five): the sparse blocks' states (`grid`
/// order, an invalid centre all zero) and the extra planes (COVER), as
/// `apr_block` writes them.
fn stage_blocks(
    windows: [&[Option<Inputs>]; 3],
    last: bool,
    eps: f64,
) -> ([Vec<f32>; 3], Vec<Vec<f32>>) {
    use super::apr_block::{self as b};
    let state = std::array::from_fn(|ch| {
        b::sparse(windows[ch], !last, eps)
            .iter()
            .flat_map(|blk| blk.as_ref().map_or([0.0f32; STATE], |blk| blk.state()))
            .collect()
    });
    let centre = windows[0].iter().flatten().next().expect("a centre frame");
    let n = centre.w * centre.h;
    let mut extra = vec![vec![0.0f32; n]; 3 * EXTRA_PLANES];
    for (ch, window) in windows.iter().enumerate() {
        for i in 0..n {
            if let Some(blk) = b::extra(window, i, !last, eps) {
                extra[ch * EXTRA_PLANES][i] = blk.beta_y[0] as f32;
                extra[ch * EXTRA_PLANES + 1][i] = blk.beta_s[0] as f32;
                extra[ch * EXTRA_PLANES + 2][i] = blk.xi as f32;
                extra[ch * EXTRA_PLANES + 3][i] = blk.trace as f32;
            }
        }
    }
    (state, extra)
}
