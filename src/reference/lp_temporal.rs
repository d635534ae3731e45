//! Scalar twin of `spirv/lp_temporal.comp`: spec §10.1, the LP temporal
//! filter. Per pixel a recursive least-squares fit of `(1, τ) → y` over the
//! frames, with the time origin at the current frame (TIME-ORIGIN), a
//! forgetting factor `λ`, the state reprojected from the previous frame by
//! a 7×7 search on the world position (SEARCH-7) and reinitialised where no
//! surface lies within 1 % of the viewing distance, plus the noise of the
//! mean position (RESET, RESET-NOISE; the search considers only those,
//! TEMPORAL-GATE), its history weighing less where its prediction misses
//! the frame's colour (TEMPORAL-INFLATE; less so beside a static bright
//! pixel, TEMPORAL-RIM). A history starts from its first
//! frame as one observation, its slope held at 0 (TEMPORAL-PRIOR).
//!
//! [`PixelState`] is one pixel's filter in f64 (what the invariants of
//! §10.1 are stated on); [`lp_temporal`] runs one frame over an image as
//! the kernel does, reading and writing the state as f32 planes.

use super::temporal_motion::{motion, Motion};
use crate::shared::{
    TemporalPush, TEMPORAL_DEPTH_FLOOR, TEMPORAL_MOTION, TEMPORAL_NO_SEARCH, TEMPORAL_P00,
    TEMPORAL_RESET, TEMPORAL_RESET_NOISE, TEMPORAL_RESET_REL, TEMPORAL_RIM_CONTRAST,
    TEMPORAL_RIM_HISTORY, TEMPORAL_RIM_TOL, TEMPORAL_SEARCH, TEMPORAL_SOURCE_NONE,
    TEMPORAL_SOURCE_RESET, TEMPORAL_STATE, TEMPORAL_SUBPIXEL_GATE, TEMPORAL_SUBPIXEL_REACH,
    TEMPORAL_VALID,
};

/// One pixel's temporal state (§10.1), origin at the frame it was last
/// updated in.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct PixelState {
    /// `β[ch] = (intercept, slope)` per channel.
    pub beta: [[f64; 2]; 3],
    /// `P = [[p00, p01], [p01, p11]]` as `[p00, p01, p11]`, shared by the
    /// channels.
    pub p: [f64; 3],
    /// The world position `W` the state was last updated at.
    pub w: [f64; 3],
}

impl PixelState {
    /// RESET: `β = (y, 0)`, `P = diag(p00, p11)` (TEMPORAL-PRIOR; §10.1
    /// has `I/δ`) at position `w`.
    pub fn reset(y: [f64; 3], w: [f64; 3], (p00, p11): (f64, f64)) -> PixelState {
        PixelState {
            beta: y.map(|v| [v, 0.0]),
            p: [p00, 0.0, p11],
            w,
        }
    }

    /// TIME-ORIGIN: the state with its origin moved one frame on,
    /// `β ← Sβ`, `P ← S P Sᵀ` with `S = [[1, 1], [0, 1]]`.
    pub fn shifted(&self) -> PixelState {
        let [a, b, c] = self.p;
        PixelState {
            beta: self.beta.map(|[b0, b1]| [b0 + b1, b1]),
            p: [a + 2.0 * b + c, b + c, c],
            w: self.w,
        }
    }

    /// The prediction at the origin, `β[ch]ᵀ(1, 0)`.
    pub fn predict(&self) -> [f64; 3] {
        self.beta.map(|b| b[0])
    }

    /// The recursive update with the observation `y` at `z = (1, 0)` and
    /// forgetting factor `lambda`: `G = Pz / (λ + zᵀPz)`,
    /// `P ← (P − G zᵀP)/λ`, `β ← β + G (y − βᵀz)`.
    pub fn update(&mut self, y: [f64; 3], lambda: f64) {
        let [p00, p01, p11] = self.p;
        let den = lambda + p00;
        let g = [p00 / den, p01 / den];
        // `(P₀₀ − G₀P₀₀)/λ = P₀₀/(λ + P₀₀)` (and `P₀₁` alike), in the form
        // that does not cancel to 0 when an inflated `P₀₀` rounds `G₀` to 1.
        self.p = [p00 / den, p01 / den, (p11 - g[1] * p01) / lambda];
        for (b, v) in self.beta.iter_mut().zip(y) {
            let r = v - b[0];
            b[0] += g[0] * r;
            b[1] += g[1] * r;
        }
    }
}

/// The state planes ([`TEMPORAL_STATE`] of them) of a pixel as a
/// [`PixelState`], or `None` where its valid flag is not set.
pub fn load(state: &[f32], n: usize, i: usize) -> Option<PixelState> {
    let v = |k: usize| state[k * n + i] as f64;
    (v(TEMPORAL_VALID) == 1.0).then(|| PixelState {
        beta: [[v(0), v(1)], [v(2), v(3)], [v(4), v(5)]],
        p: [v(TEMPORAL_P00), v(7), v(8)],
        w: [v(9), v(10), v(11)],
    })
}

/// Stores `s` (or, with `None`, an invalid pixel: every plane 0) into
/// pixel `i` of the state planes, rounded to f32.
pub fn store(state: &mut [f32], n: usize, i: usize, s: Option<&PixelState>) {
    let vals: [f64; TEMPORAL_STATE] = match s {
        Some(s) => [
            s.beta[0][0],
            s.beta[0][1],
            s.beta[1][0],
            s.beta[1][1],
            s.beta[2][0],
            s.beta[2][1],
            s.p[0],
            s.p[1],
            s.p[2],
            s.w[0],
            s.w[1],
            s.w[2],
            1.0,
        ],
        None => [0.0; TEMPORAL_STATE],
    };
    for (k, v) in vals.into_iter().enumerate() {
        state[k * n + i] = v as f32;
    }
}

/// The inputs of one frame: the spatial reconstruction `y` (§3's `f̂(t)`,
/// any method's), the position and depth layers and the sample count.
#[derive(Copy, Clone, Debug)]
pub struct TemporalInputs<'a> {
    /// The spatially filtered colour R, G, B.
    pub color: [&'a [f32]; 3],
    /// The `position` layer X, Y, Z (`W_i(t)`).
    pub position: [&'a [f32]; 3],
    /// The `position_variance` layer (of the mean position, per axis).
    pub position_variance: [&'a [f32]; 3],
    /// The `depth` layer (`dep_i`).
    pub depth: &'a [f32],
    /// The sample count (a pixel with `spp < 1` is invalid, §0.2).
    pub spp: &'a [f32],
    /// The method's error estimate `E_i` of `color` per channel.
    pub error: [&'a [f32]; 3],
}

/// A push constant's factor on the error estimate: 0 (or less) reads as 1.
fn factor(v: f32) -> f64 {
    if v > 0.0 {
        v as f64
    } else {
        1.0
    }
}

/// The reprojection of pixel `(x, y)` (§10.1): among the valid previous
/// states in the 7×7 window centred at `(x, y) + centre` (TEMPORAL-MOTION;
/// clipped to the image) whose position is within
/// `limit` of `wi` (`eW ≤ limit`, TEMPORAL-GATE, RESET-NOISE), each shifted to the
/// current frame, the one with the least `(eW + εW)(ey + εy)` (the first in
/// raster order on a tie), and its offset `(dx, dy)` from the centre;
/// `None` (RESET) where there is none.
fn reproject(
    prev: &[f32],
    (w, h): (usize, usize),
    (x, y): (usize, usize),
    centre: (i32, i32),
    wi: [f64; 3],
    yi: [f64; 3],
    limit: f64,
) -> Option<(PixelState, (i32, i32))> {
    let n = w * h;
    let ew_floor = 1e-12 * (1.0 + wi.iter().map(|v| v * v).sum::<f64>());
    let r = TEMPORAL_SEARCH;
    let mut best: Option<(f64, PixelState, (i32, i32))> = None;
    for dy in -r..=r {
        for dx in -r..=r {
            let (jx, jy) = (x as i32 + centre.0 + dx, y as i32 + centre.1 + dy);
            if jx < 0 || jy < 0 || jx >= w as i32 || jy >= h as i32 {
                continue;
            }
            let Some(s) = load(prev, n, jy as usize * w + jx as usize) else {
                continue;
            };
            let s = s.shifted();
            let ew: f64 = (0..3).map(|k| (s.w[k] - wi[k]).powi(2)).sum();
            if ew > limit {
                continue;
            }
            let pred = s.predict();
            let ey: f64 = (0..3).map(|c| (yi[c] - pred[c]).powi(2)).sum();
            let cost = (ew + ew_floor) * (ey + 1e-12);
            if best.as_ref().map_or(true, |b| cost < b.0) {
                best = Some((cost, s, (dx, dy)));
            }
        }
    }
    best.map(|(_, s, d)| (s, d))
}

/// TEMPORAL-MISREG: what a state carried from pixel `j` to another pixel,
/// where the motion search moved the window, adds to its `P00`: the
/// variance of a shift uniform over a pixel along the previous state's
/// gradient at `j` (central differences of the
/// shifted intercepts; a neighbour outside the image or without state
/// reads `b0`, pixel `j`'s), `(gx² + gy²)/12`, over the pixel's error `e`
/// (the method's estimate times its error scale), the largest over the
/// channels.
fn misregistration(
    prev: &[f32],
    (w, h): (usize, usize),
    (jx, jy): (i32, i32),
    b0: [f64; 3],
    e: [f64; 3],
) -> f64 {
    let n = w * h;
    let at = |x: i32, y: i32| -> [f64; 3] {
        if x < 0 || y < 0 || x >= w as i32 || y >= h as i32 {
            return b0;
        }
        load(prev, n, y as usize * w + x as usize).map_or(b0, |s| s.shifted().predict())
    };
    let (xp, xm, yp, ym) = (
        at(jx + 1, jy),
        at(jx - 1, jy),
        at(jx, jy + 1),
        at(jx, jy - 1),
    );
    (0..3)
        .map(|c| {
            let gx = (xp[c] - xm[c]) * 0.5;
            let gy = (yp[c] - ym[c]) * 0.5;
            (gx * gx + gy * gy) / (12.0 * e[c] + 1e-12)
        })
        .fold(0.0f64, f64::max)
}

/// TEMPORAL-SUBPIXEL: the state `s` carried from pixel `j` resampled where
/// the surface point at `wi` lies between the previous frame's pixels: the
/// offset `d` solving `W(j + d) = wi` to first order (least squares on the
/// previous states' position derivatives at `j`, central where both
/// neighbours are on `j`'s surface — within `gate` of `W_j`, squared —
/// else one-sided; unchanged where an axis has neither), each component
/// clamped to [`TEMPORAL_SUBPIXEL_REACH`], then the shifted `β` interpolated bilinearly
/// between `j` and its neighbours towards `d`, a neighbour not on `j`'s
/// surface reading `j`'s.
fn resample(
    prev: &[f32],
    (w, h): (usize, usize),
    (jx, jy): (i32, i32),
    wi: [f64; 3],
    gate: f64,
    s: &mut PixelState,
) {
    let n = w * h;
    let near = |x: i32, y: i32| -> Option<PixelState> {
        if x < 0 || y < 0 || x >= w as i32 || y >= h as i32 {
            return None;
        }
        let c = load(prev, n, y as usize * w + x as usize)?;
        let d2: f64 = (0..3).map(|k| (c.w[k] - s.w[k]).powi(2)).sum();
        (d2 <= gate).then(|| c.shifted())
    };
    let derivative = |ax: i32, ay: i32| -> Option<[f64; 3]> {
        let (up, down) = (near(jx + ax, jy + ay), near(jx - ax, jy - ay));
        match (up, down) {
            (Some(u), Some(d)) => Some(std::array::from_fn(|k| (u.w[k] - d.w[k]) * 0.5)),
            (Some(u), None) => Some(std::array::from_fn(|k| u.w[k] - s.w[k])),
            (None, Some(d)) => Some(std::array::from_fn(|k| s.w[k] - d.w[k])),
            (None, None) => None,
        }
    };
    let (Some(ex), Some(ey)) = (derivative(1, 0), derivative(0, 1)) else {
        return;
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (a, o, c) = (dot(ex, ex), dot(ex, ey), dot(ey, ey));
    let det = a * c - o * o;
    // Also where a derivative is not finite (NaN compares false).
    if det.partial_cmp(&(1e-6 * a * c)) != Some(std::cmp::Ordering::Greater) {
        return;
    }
    let dw = std::array::from_fn(|k| wi[k] - s.w[k]);
    let (rx, ry) = (dot(ex, dw), dot(ey, dw));
    let dx = ((c * rx - o * ry) / det).clamp(-TEMPORAL_SUBPIXEL_REACH, TEMPORAL_SUBPIXEL_REACH);
    let dy = ((a * ry - o * rx) / det).clamp(-TEMPORAL_SUBPIXEL_REACH, TEMPORAL_SUBPIXEL_REACH);
    let (sx, sy) = (if dx < 0.0 { -1 } else { 1 }, if dy < 0.0 { -1 } else { 1 });
    let (fx, fy) = (dx.abs(), dy.abs());
    let mut beta = s.beta.map(|b| b.map(|v| v * (1.0 - fx) * (1.0 - fy)));
    for ((cx, cy), wk) in [
        ((jx + sx, jy), fx * (1.0 - fy)),
        ((jx, jy + sy), (1.0 - fx) * fy),
        ((jx + sx, jy + sy), fx * fy),
    ] {
        let cb = near(cx, cy).map_or(s.beta, |c| c.beta);
        for (acc, b) in beta.iter_mut().zip(cb) {
            acc[0] += wk * b[0];
            acc[1] += wk * b[1];
        }
    }
    s.beta = beta;
}

/// TEMPORAL-RIM: the miss of prediction `b0` at pixel `(x, y)` becomes its
/// distance from the range of this frame's colours in the 3×3 window where
/// the window's brightest pixel (the greatest R + G + B, the first in
/// raster order) is at least [`TEMPORAL_RIM_CONTRAST`] times as bright as
/// this pixel and has a previous state at the same pixel whose intercepts
/// are within [`TEMPORAL_RIM_TOL`] of its colour (summed over the
/// channels), and `b0` is at most [`TEMPORAL_RIM_HISTORY`] of its
/// brightness: a static bright neighbour makes a history between this
/// pixel's colour and the neighbour's plausible, as on the rim of a light
/// seen directly, whose frames are quiet or lit; a history as bright as
/// the light is of a pixel the light has left.
fn rim_miss(
    inp: &TemporalInputs,
    prev: &[f32],
    (w, h): (usize, usize),
    (x, y): (usize, usize),
    yi: [f64; 3],
    b0: [f64; 3],
    miss: &mut [f64; 3],
) {
    let n = w * h;
    let (mut lo, mut hi) = (yi, yi);
    let mut best = (-1.0f64, y * w + x);
    for ky in y.saturating_sub(1)..(y + 2).min(h) {
        for kx in x.saturating_sub(1)..(x + 2).min(w) {
            let m = ky * w + kx;
            let c = inp.color.map(|p| p[m]);
            if super::finalize_stats::spp_of(inp.spp[m]) < 1.0 || c.iter().any(|v| !v.is_finite()) {
                continue;
            }
            let c = c.map(|v| v as f64);
            for k in 0..3 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
            let l = c[0] + c[1] + c[2];
            if l > best.0 {
                best = (l, m);
            }
        }
    }
    // Every colour here is finite.
    if best.0 <= TEMPORAL_RIM_CONTRAST * (yi[0] + yi[1] + yi[2] + 0.01)
        || b0[0] + b0[1] + b0[2] > TEMPORAL_RIM_HISTORY * best.0
    {
        return;
    }
    let Some(s) = load(prev, n, best.1) else {
        return;
    };
    let cb = inp.color.map(|p| p[best.1] as f64);
    let was = s.shifted().predict();
    let d: f64 = (0..3).map(|k| (was[k] - cb[k]).abs()).sum();
    if d <= TEMPORAL_RIM_TOL * best.0 {
        *miss = std::array::from_fn(|k| (lo[k] - b0[k]).max(0.0) + (b0[k] - hi[k]).max(0.0));
    }
}

/// What the filter does at one pixel of a frame.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Step {
    /// An invalid pixel or a non-finite colour: passed through, no state.
    PassThrough,
    /// Reinitialised (RESET, or the first frame): `β = (y, 0)`,
    /// `P = diag(p00, p11)` (TEMPORAL-PRIOR).
    Reset(PixelState),
    /// The state reprojected from offset `(dx, dy)` from the window's centre
    /// in the previous frame, updated with this frame's colour.
    Continue(PixelState, (i32, i32)),
}

/// The filter at pixel `(x, y)` of a `push.width × push.height` frame
/// (§10.1): reprojection from the state planes `prev` in the window
/// centred at `(x, y) + centre` (unless [`TEMPORAL_RESET`];
/// [`TEMPORAL_NO_SEARCH`]: pixel `i`'s own state), RESET, and the update
/// with forgetting factor `push.lambda`.
pub fn step(
    push: &TemporalPush,
    inp: &TemporalInputs,
    prev: &[f32],
    (x, y): (usize, usize),
    centre: (i32, i32),
) -> Step {
    let (w, h) = (push.width as usize, push.height as usize);
    let n = w * h;
    let i = y * w + x;
    let col = inp.color.map(|p| p[i]);
    let yi = col.map(|v| v as f64);
    let wi = inp.position.map(|p| p[i] as f64);
    let valid = super::finalize_stats::spp_of(inp.spp[i]) >= 1.0;
    if !valid || col.iter().any(|v| !v.is_finite()) {
        return Step::PassThrough;
    }
    let found = if push.flags & TEMPORAL_RESET != 0 {
        None
    } else if push.flags & TEMPORAL_NO_SEARCH != 0 {
        load(prev, n, i).map(|s| (s.shifted(), (0, 0)))
    } else {
        let var: f64 = inp.position_variance.iter().map(|p| p[i] as f64).sum();
        let limit = (TEMPORAL_RESET_REL * (inp.depth[i] as f64).max(TEMPORAL_DEPTH_FLOOR)).powi(2)
            + TEMPORAL_RESET_NOISE * var;
        reproject(prev, (w, h), (x, y), centre, wi, yi, limit).map(|(mut s, (dx, dy))| {
            let j = (x as i32 + centre.0 + dx, y as i32 + centre.1 + dy);
            if centre != (0, 0) && j != (x as i32, y as i32) {
                let scale = factor(push.error_scale);
                let ei = inp.error.map(|e| scale * e[i].max(0.0) as f64);
                s.p[0] += misregistration(prev, (w, h), j, s.predict(), ei);
                resample(prev, (w, h), j, wi, TEMPORAL_SUBPIXEL_GATE * limit, &mut s);
            }
            (s, (dx, dy))
        })
    };
    // TEMPORAL-INFLATE: where the prediction misses this frame's colour by
    // more than `t3² E (1 + P00)` in some channel, `P` grows by the ratio,
    // so the history weighs only as much as that miss allows.
    let found = found.map(|(mut s, offset)| {
        let t2 = super::t_threshold3(super::finalize_stats::spp_of(inp.spp[i])).powi(2);
        // TEMPORAL-TEST-SCALE: `E` times the method's factor.
        let tscale = factor(push.inflate_scale);
        let pred = s.predict();
        let mut miss: [f64; 3] = std::array::from_fn(|c| yi[c] - pred[c]);
        if centre == (0, 0) {
            rim_miss(inp, prev, (w, h), (x, y), yi, pred, &mut miss);
        }
        let q = (0..3)
            .map(|c| {
                let e = inp.error[c][i].max(0.0) as f64;
                miss[c].powi(2) / (t2 * tscale * e * (1.0 + s.p[0]) + 1e-12)
            })
            .fold(1.0f64, f64::max);
        s.p = s.p.map(|v| v * q);
        (s, offset)
    });
    match found {
        Some((mut s, offset)) => {
            s.update(yi, push.lambda as f64);
            s.w = wi;
            Step::Continue(s, offset)
        }
        None => Step::Reset(PixelState::reset(
            yi,
            wi,
            (push.p00 as f64, push.p11 as f64),
        )),
    }
}

/// TEMPORAL-MOTION for a frame: the coarse-to-fine search
/// ([`motion`]) where `push.flags` has
/// [`TEMPORAL_MOTION`] and neither [`TEMPORAL_RESET`] nor
/// [`TEMPORAL_NO_SEARCH`]; `None` (every window centred on its pixel)
/// otherwise.
pub fn frame_motion(push: &TemporalPush, inp: &TemporalInputs, prev: &[f32]) -> Option<Motion> {
    let searching = push.flags & (TEMPORAL_RESET | TEMPORAL_NO_SEARCH) == 0;
    (searching && push.flags & TEMPORAL_MOTION != 0).then(|| {
        let size = (push.width as usize, push.height as usize);
        motion(size, inp.position, inp.spp, prev)
    })
}

/// The centre of pixel `(x, y)`'s window under `motion` (0 without).
pub fn centre(motion: Option<&Motion>, (x, y): (usize, usize)) -> (i32, i32) {
    motion.map_or((0, 0), |m| m.centre(x, y))
}

/// One frame of the filter over a `width × height` image (`row0` ignored):
/// [`frame_motion`], then per pixel [`step`], from the previous frame's
/// state planes `prev` into `next` (both [`TEMPORAL_STATE`] planes), the
/// output `β[ch][0]` clamped to ≥ 0 into `out` (the colour itself where
/// passed through), and the debug plane `source`
/// ([`TEMPORAL_SOURCE_RESET`]). A pixel passed through has no state.
pub fn lp_temporal(
    push: &TemporalPush,
    inp: &TemporalInputs,
    prev: &[f32],
    next: &mut [f32],
    out: [&mut [f32]; 3],
    source: &mut [f32],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    let n = w * h;
    let [or, og, ob] = out;
    let r = TEMPORAL_SEARCH;
    let motion = frame_motion(push, inp, prev);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (s, src) = match step(push, inp, prev, (x, y), centre(motion.as_ref(), (x, y))) {
                Step::PassThrough => {
                    store(next, n, i, None);
                    (or[i], og[i], ob[i]) = (inp.color[0][i], inp.color[1][i], inp.color[2][i]);
                    source[i] = TEMPORAL_SOURCE_NONE;
                    continue;
                }
                Step::Reset(s) => (s, TEMPORAL_SOURCE_RESET),
                Step::Continue(s, (dx, dy)) => (s, ((dy + r) * (2 * r + 1) + dx + r) as f32),
            };
            store(next, n, i, Some(&s));
            let o = s.predict().map(|v| v.max(0.0) as f32);
            (or[i], og[i], ob[i]) = (o[0], o[1], o[2]);
            source[i] = src;
        }
    }
}
