//! The energy-preserving outlier stage of spec §4.4, for every method, in f64
//! from its definitions (no box sums, no merges): the reference the kernels'
//! twins (`outlier_grey`, `outlier_rows`, `outlier_detect`, `outlier_median`,
//! `box_rows`, `outlier_weights`, `outlier_spread`) and the CPU path use.
//!
//! * Steps 1–3 ([`detect`], [`replace`]), before the G-buffer prefilter and
//!   the method (§1): a valid pixel `o` is an outlier when
//!   `grey_o − m_o > 3·sd_o`, with `m_o`, `sd_o` the mean and (population)
//!   standard deviation of `grey` over the valid pixels of `Ω_o(14) \ {o}`
//!   (EXCL-CENTRE, SPIKE-SIDE). Its colour and variance are replaced by those
//!   of the pixel of median grey in `Ω_o(14)` (WHOLE-PIXEL) and the removed
//!   excess `e_o = y_o − y_q*` is kept per channel.
//! * Step 4 ([`redistribute`]), after the method: `ρ_o = e_o / Σ_{Ω_o(43)} ŷ`,
//!   `ŷ_final = ŷ·(1 + Σ_o ρ_o)`, or `e_o/|Ω_o|` added uniformly when the
//!   window is dark (DARK-WINDOW).
//!
//! Decisions of ours where the spec is silent:
//! * Decision OUTLIER-MIN-N (ours): a pixel with fewer than [`MIN_NEIGHBOURS`] valid
//!   neighbours in `Ω_o(14) \ {o}` is never an outlier (with one neighbour,
//!   `sd = 0` and every pixel brighter than it would be "detected").
//! * Decision OUTLIER-NOISE (ours): a pixel is a spike only if its excess over the
//!   neighbourhood is within `3·se_o` of its own mean, `se_o = (√v_R + √v_G +
//!   √v_B)/3` (the standard error of grey when the channels move together).
//!   A firefly (one sample of value x among n) has `se = y` exactly; a pixel
//!   that is bright in every sample, such as a small light seen directly,
//!   has `se ≈ 0` and is signal, not an outlier: without this test such a
//!   light is removed and its energy smeared over 87×87 pixels.
//! * Decision OUTLIER-ISOLATED (ours): a pixel is a spike only if none of its 8 neighbours
//!   is itself above `m_o + 3·sd_o`. Samples are independent per pixel, so a
//!   firefly is a single-pixel event; bright neighbours mean a feature (a
//!   highlight seen through glass, the edge of a light) whose energy belongs
//!   there and not spread over 87×87 pixels.
//! * Decision OUTLIER-RIM (ours, `outliers.rim`): for a pixel whose excess
//!   is at most [`RIM_LONE`] of its standard errors (one or two rare
//!   paths), a bright neighbour whose own excess over `m_o` is within `3·se`
//!   of its mean (by OUTLIER-NOISE, itself a rare path) keeps `o` from
//!   detection only with at least [`RIM_SHARE`] of `o`'s excess (a cluster
//!   of similar ones), and a steady one only with less (a lit surface,
//!   such as a caustic's body). A light seen directly is steady and
//!   brighter, and the partial hits of its edge fainter rare paths, so one
//!   sample among many that see the dark wall beside a lamp is a spike.
//! * Decision OUTLIER-MEDIAN (ours): the median of an even count is the lower one (rank
//!   `(n−1)/2` of the sorted greys); among pixels whose grey equals it, the
//!   lowest raster index is `q*`.
//! * Decision OUTLIER-CLAMP (ours): the redistributed image is clamped to ≥ 0 (spec §0.4
//!   step 5); [`redistribute`] itself does not clamp, so energy is exact.
//! * Decision OUTLIER-CLIP (ours): `m_o` and `sd_o` are taken over the pixels
//!   that survive `rounds` rounds of clipping ([`kept_after_clip`]): in each
//!   round every pixel still kept whose excess over the mean of the kept
//!   pixels of its own window is above `3·sd` and either above `3·se` (a
//!   light: bright, and signal by OUTLIER-NOISE) or above [`CLIP_FAR`]`·sd`
//!   (a spike no part of the window's noise) leaves the statistics. A small
//!   lamp, or a far brighter spike, in a dark window otherwise inflates `sd`
//!   so much that a firefly beside it passes the test; nearer spikes stay
//!   in the statistics, as the spec has them. OUTLIER-NOISE,
//!   OUTLIER-ISOLATED and the median still see every valid pixel.
//!   `rounds = 0` is the spec.
//! * Decision OUTLIER-WIDE (ours): an outlier whose grey excess is above
//!   [`WIDE_FRACTION`] of the grey sum of ŷ over its 87×87 window carries
//!   more than that window can hold: a rare path (a caustic from a tiny
//!   lamp, a firefly of thousands) whose expected energy is spread far wider.
//!   Its excess is spread, after the others', over a [`WIDE_RADIUS`] window
//!   in proportion to ŷ as it then is ([`redistribute`]). The energy is
//!   still exact per pass; `wide = 0` is the spec.

use super::spp_of;

/// OUTLIER-RIM: the rule applies to a pixel whose excess is at most this
/// many of its standard errors (one rare path among `n` samples gives 1,
/// two about 1.4; a lamp's edge that many samples see, more);
/// `RIM_LONE` in `spirv/outlier_detect.comp`.
pub const RIM_LONE: f64 = 1.5;

/// OUTLIER-RIM: the share of `o`'s excess from which a bright neighbour
/// within its own noise keeps `o` from detection, and below which a steady
/// one does (`RIM_SHARE` in `spirv/outlier_detect.comp`).
pub const RIM_SHARE: f64 = 0.5;

/// `Ω_o(14)`: the detection and median window (29×29).
pub const DETECT_RADIUS: usize = 14;
/// `Ω_o(43)`: the redistribution window (87×87).
pub const SPREAD_RADIUS: usize = 43;
/// OUTLIER-WIDE: the window (431×431) of the outliers whose excess is too
/// much for their 87×87 one.
pub const WIDE_RADIUS: usize = 5 * SPREAD_RADIUS;
/// OUTLIER-WIDE: the default fraction of its 87×87 window's grey sum above
/// which an outlier's excess goes to the wide window (`outliers.wide`).
pub const WIDE_FRACTION: f64 = 0.05;
/// Detection threshold in standard deviations.
pub const K_SIGMA: f64 = 3.0;
/// Fewest valid neighbours (centre excluded) a detection needs (OUTLIER-MIN-N).
pub const MIN_NEIGHBOURS: u32 = 8;
/// OUTLIER-CLIP: a pixel this many standard deviations above its window's
/// kept mean leaves the statistics even when it is noise (mirrored as
/// `CLIP_FAR` in `spirv/outlier_clip.comp`).
pub const CLIP_FAR: f64 = 50.0;
/// DARK-WINDOW: a window whose `Σ ŷ <= DARK · |Ω_o|` gets `e_o` uniformly.
pub const DARK: f64 = 1e-8;

/// `grey = (R + G + B)/3` (spec §0.1 GREY), in f64.
pub fn grey(color: [&[f32]; 3], i: usize) -> f64 {
    (color[0][i] as f64 + color[1][i] as f64 + color[2][i] as f64) / 3.0
}

/// The standard error of `grey_o` for channels that move together (as a
/// spike's do): `(√v_R + √v_G + √v_B)/3` (OUTLIER-NOISE).
pub fn grey_sd(var: [&[f32]; 3], i: usize) -> f64 {
    (0..3)
        .map(|c| (var[c][i].max(0.0) as f64).sqrt())
        .sum::<f64>()
        / 3.0
}

/// Visits the valid pixels of the clipped square window of radius `r` around
/// `(x, y)` in raster order.
pub fn window(
    w: usize,
    h: usize,
    x: usize,
    y: usize,
    r: usize,
    spp: &[f32],
    mut f: impl FnMut(usize),
) {
    for qy in y.saturating_sub(r)..(y + r + 1).min(h) {
        for qx in x.saturating_sub(r)..(x + r + 1).min(w) {
            let q = qy * w + qx;
            if spp_of(spp[q]) >= 1.0 {
                f(q);
            }
        }
    }
}

/// The mean and population standard deviation of grey over the pixels of
/// `Ω_o(14) \ {o}` that are valid and `kept` (OUTLIER-CLIP), or `None` when
/// fewer than [`MIN_NEIGHBOURS`] are (OUTLIER-MIN-N).
fn window_stats(
    w: usize,
    h: usize,
    color: [&[f32]; 3],
    spp: &[f32],
    kept: &[bool],
    o: usize,
) -> Option<(f64, f64)> {
    let (x, y) = (o % w, o / w);
    let mut g = Vec::with_capacity((2 * DETECT_RADIUS + 1).pow(2));
    window(w, h, x, y, DETECT_RADIUS, spp, |q| {
        if q != o && kept[q] {
            g.push(grey(color, q));
        }
    });
    mean_sd(&g, MIN_NEIGHBOURS)
}

/// The mean and population standard deviation of `values` (two passes), or
/// `None` for fewer than `min_n` of them.
pub fn mean_sd(values: &[f64], min_n: u32) -> Option<(f64, f64)> {
    if (values.len() as u32) < min_n || values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let m = values.iter().sum::<f64>() / n;
    let m2: f64 = values.iter().map(|v| (v - m) * (v - m)).sum();
    Some((m, (m2 / n).sqrt()))
}

/// OUTLIER-CLIP's test: a pixel `excess` above its window's kept mean (of
/// standard deviation `sd`), with standard error `se`, leaves the
/// statistics when it is above `k·sd` and either above `k·se` (a light) or
/// above [`CLIP_FAR`]`·sd` (a far spike).
pub fn leaves_statistics(excess: f64, sd: f64, se: f64, k: f64) -> bool {
    excess > k * sd && (excess > k * se || excess > CLIP_FAR * sd)
}

/// OUTLIER-CLIP: the valid pixels that stay in the detection statistics
/// after `rounds` rounds, each testing every pixel still kept against the
/// kept pixels of its window as they were before the round.
pub fn kept_after_clip(
    w: usize,
    h: usize,
    color: [&[f32]; 3],
    var: [&[f32]; 3],
    spp: &[f32],
    rounds: u32,
) -> Vec<bool> {
    let mut kept: Vec<bool> = spp.iter().map(|&s| spp_of(s) >= 1.0).collect();
    for _ in 0..rounds {
        let before = kept.clone();
        for (o, k) in kept.iter_mut().enumerate() {
            if *k {
                if let Some((m, sd)) = window_stats(w, h, color, spp, &before, o) {
                    let excess = grey(color, o) - m;
                    *k = !leaves_statistics(excess, sd, grey_sd(var, o), K_SIGMA);
                }
            }
        }
    }
    kept
}

/// Step 1 at pixel `o`: whether it is an outlier (SPIKE-SIDE,
/// OUTLIER-NOISE, OUTLIER-MIN-N, OUTLIER-ISOLATED, with `rim` OUTLIER-RIM),
/// with the statistics over the `kept` pixels ([`kept_after_clip`]).
#[allow(clippy::too_many_arguments)]
pub fn is_outlier(
    w: usize,
    h: usize,
    color: [&[f32]; 3],
    var: [&[f32]; 3],
    spp: &[f32],
    kept: &[bool],
    rim: bool,
    o: usize,
) -> bool {
    if spp_of(spp[o]) < 1.0 {
        return false;
    }
    let (x, y) = (o % w, o / w);
    let Some((m, sd)) = window_stats(w, h, color, spp, kept, o) else {
        return false;
    };
    let excess = grey(color, o) - m;
    if excess <= K_SIGMA * sd || excess > K_SIGMA * grey_sd(var, o) {
        return false;
    }
    // OUTLIER-ISOLATED: a bright neighbour makes o part of a feature;
    // OUTLIER-RIM, when o is one or two rare paths: not a light, nor a
    // fainter rare path beside it.
    let rim = rim && excess <= RIM_LONE * grey_sd(var, o);
    let mut isolated = true;
    window(w, h, x, y, 1, spp, |q| {
        let ej = grey(color, q) - m;
        // OUTLIER-RIM: a rare path shields o when it has RIM_SHARE of o's
        // excess (a cluster), a steady pixel when it has less (a lit
        // surface, not a light).
        let rare = ej <= K_SIGMA * grey_sd(var, q);
        if q != o && ej > K_SIGMA * sd && (!rim || rare == (ej >= RIM_SHARE * excess)) {
            isolated = false;
        }
    });
    if !isolated {
        return false;
    }
    true
}

/// Steps 1–2 at pixel `o`: `Some(q*)` (step 3's replacement) if `o` is an
/// outlier, else `None`.
#[allow(clippy::too_many_arguments)]
pub fn detect_at(
    w: usize,
    h: usize,
    color: [&[f32]; 3],
    var: [&[f32]; 3],
    spp: &[f32],
    kept: &[bool],
    rim: bool,
    o: usize,
) -> Option<usize> {
    is_outlier(w, h, color, var, spp, kept, rim, o).then(|| median_at(w, h, color, spp, o))
}

/// The pixel of median grey in `Ω_o(14)`, `o` included (OUTLIER-MEDIAN).
pub fn median_at(w: usize, h: usize, color: [&[f32]; 3], spp: &[f32], o: usize) -> usize {
    let mut v = Vec::with_capacity((2 * DETECT_RADIUS + 1).pow(2));
    window(w, h, o % w, o / w, DETECT_RADIUS, spp, |q| {
        v.push((grey(color, q), q))
    });
    let mut g: Vec<f64> = v.iter().map(|p| p.0).collect();
    g.sort_by(|a, b| a.total_cmp(b));
    let med = g[(g.len() - 1) / 2];
    v.iter().find(|p| p.0 == med).map(|p| p.1).unwrap_or(o)
}

/// Steps 1–2 for every pixel, after `rounds` rounds of OUTLIER-CLIP and
/// with OUTLIER-RIM when `rim`: the replacement `q*` of each outlier. All
/// detections read the original image (spec: applied at once).
pub fn detect(
    w: usize,
    h: usize,
    color: [&[f32]; 3],
    var: [&[f32]; 3],
    spp: &[f32],
    rounds: u32,
    rim: bool,
) -> Vec<Option<usize>> {
    let kept = kept_after_clip(w, h, color, var, spp, rounds);
    (0..w * h)
        .map(|o| detect_at(w, h, color, var, spp, &kept, rim, o))
        .collect()
}

/// Step 3: replaces every outlier's colour and variance by its `q*`'s (read
/// from the original planes) and returns the excess `e_o = y_o − y_q*` per
/// channel (0 elsewhere), in f64.
pub fn replace(
    found: &[Option<usize>],
    color: &mut [Vec<f32>; 3],
    var: &mut [Vec<f32>; 3],
) -> [Vec<f64>; 3] {
    let (c0, v0) = (color.clone(), var.clone());
    let mut e: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; found.len()]);
    for (o, q) in found.iter().enumerate() {
        if let Some(q) = *q {
            for ch in 0..3 {
                e[ch][o] = c0[ch][o] as f64 - c0[ch][q] as f64;
                color[ch][o] = c0[ch][q];
                var[ch][o] = v0[ch][q];
            }
        }
    }
    e
}

/// OUTLIER-WIDE: whether outlier `o`'s excess goes to the wide window: its
/// grey excess is above `wide` times the grey sum of `yhat` over the valid
/// pixels of `Ω_o(43)` (`wide <= 0`: never, the spec).
pub fn goes_wide(
    w: usize,
    h: usize,
    spp: &[f32],
    e: &[Vec<f64>; 3],
    yhat: &[Vec<f64>; 3],
    wide: f64,
    o: usize,
) -> bool {
    if wide <= 0.0 {
        return false;
    }
    let mut s = 0.0;
    window(w, h, o % w, o / w, SPREAD_RADIUS, spp, |q| {
        s += yhat[0][q] + yhat[1][q] + yhat[2][q];
    });
    e[0][o] + e[1][o] + e[2][o] > wide * s
}

/// Step 4 in f64, unclamped: adds the excess `e` back to `yhat`, in
/// proportion to `yhat` (or uniformly when the window is dark), over the
/// valid pixels of each outlier's 87×87 window or, for the outliers that
/// [`goes_wide`] picks from `yhat` as it comes in, afterwards over their
/// [`WIDE_RADIUS`] window (OUTLIER-WIDE). `outlier` marks the pixels whose
/// `e` is redistributed. Energy: `Σ ŷ_final − Σ ŷ = Σ_o e_o` per channel.
pub fn redistribute(
    w: usize,
    h: usize,
    spp: &[f32],
    outlier: &[bool],
    e: &[Vec<f64>; 3],
    wide: f64,
    yhat: &mut [Vec<f64>; 3],
) {
    spread_both(w, h, spp, outlier, e, wide, false, yhat);
}

/// The two spreads of step 4: the outliers [`goes_wide`] leaves over their
/// 87×87 windows, then the ones it picks over their [`WIDE_RADIUS`]
/// windows (each [`spread_pass`] with `clamp`).
#[allow(clippy::too_many_arguments)]
fn spread_both(
    w: usize,
    h: usize,
    spp: &[f32],
    outlier: &[bool],
    e: &[Vec<f64>; 3],
    wide: f64,
    clamp: bool,
    yhat: &mut [Vec<f64>; 3],
) {
    let far = wide_mask(w, h, spp, outlier, e, yhat, wide);
    let near: Vec<bool> = outlier.iter().zip(&far).map(|(&o, &f)| o && !f).collect();
    spread_pass(w, h, spp, &near, e, SPREAD_RADIUS, clamp, yhat);
    spread_pass(w, h, spp, &far, e, WIDE_RADIUS, clamp, yhat);
}

/// The outliers that [`goes_wide`] sends to the wide window.
pub fn wide_mask(
    w: usize,
    h: usize,
    spp: &[f32],
    outlier: &[bool],
    e: &[Vec<f64>; 3],
    yhat: &[Vec<f64>; 3],
    wide: f64,
) -> Vec<bool> {
    (0..w * h)
        .map(|o| outlier[o] && goes_wide(w, h, spp, e, yhat, wide, o))
        .collect()
}

/// One spread of the outliers in `sel` over their windows of radius `r`,
/// every weight from `yhat` as it comes in; with `clamp`, the valid pixels
/// it reaches are clamped to ≥ 0 (OUTLIER-CLAMP, as `outlier_spread`
/// clamps them). The weights are scattered from the outliers (a wide
/// window would make a gather per pixel cost 431² steps).
pub fn spread_pass(
    w: usize,
    h: usize,
    spp: &[f32],
    sel: &[bool],
    e: &[Vec<f64>; 3],
    r: usize,
    clamp: bool,
    yhat: &mut [Vec<f64>; 3],
) {
    let n = w * h;
    let mut rs: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut add: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    for o in (0..n).filter(|&o| sel[o]) {
        let (x, y) = (o % w, o / w);
        let mut cnt = 0usize;
        let mut s = [0.0f64; 3];
        window(w, h, x, y, r, spp, |q| {
            cnt += 1;
            for ch in 0..3 {
                s[ch] += yhat[ch][q];
            }
        });
        if cnt == 0 {
            continue;
        }
        for ch in 0..3 {
            // Ω is symmetric: o's window holds i iff i's window holds o.
            let (rho, a) = if s[ch] <= DARK * cnt as f64 {
                (0.0, e[ch][o] / cnt as f64)
            } else {
                (e[ch][o] / s[ch], 0.0)
            };
            window(w, h, x, y, r, spp, |i| {
                rs[ch][i] += rho;
                add[ch][i] += a;
            });
        }
    }
    for i in (0..n).filter(|&i| spp_of(spp[i]) >= 1.0) {
        let reached = (0..3).any(|ch| rs[ch][i] != 0.0 || add[ch][i] != 0.0);
        for ch in 0..3 {
            let v = yhat[ch][i] * (1.0 + rs[ch][i]) + add[ch][i];
            yhat[ch][i] = if clamp && reached { v.max(0.0) } else { v };
        }
    }
}

/// The pre-method part (steps 1–3, `rounds` of OUTLIER-CLIP, OUTLIER-RIM
/// when `rim`) on f32 planes, in place. Returns the outlier mask and the
/// excess per channel.
pub fn remove(
    w: usize,
    h: usize,
    color: &mut [Vec<f32>; 3],
    var: &mut [Vec<f32>; 3],
    spp: &[f32],
    rounds: u32,
    rim: bool,
) -> (Vec<bool>, [Vec<f64>; 3]) {
    let found = detect(
        w,
        h,
        [&color[0], &color[1], &color[2]],
        [&var[0], &var[1], &var[2]],
        spp,
        rounds,
        rim,
    );
    let e = replace(&found, color, var);
    (found.iter().map(Option::is_some).collect(), e)
}

/// The post-method part (step 4) on f32 planes, in place: each spread
/// clamps the valid pixels it reaches to ≥ 0 as `outlier_spread` does, and
/// the result is clamped to ≥ 0 (OUTLIER-CLAMP).
pub fn restore(
    w: usize,
    h: usize,
    spp: &[f32],
    outlier: &[bool],
    e: &[Vec<f64>; 3],
    wide: f64,
    color: &mut [Vec<f32>; 3],
) {
    if !outlier.iter().any(|&o| o) {
        return;
    }
    let mut y: [Vec<f64>; 3] =
        std::array::from_fn(|ch| color[ch].iter().map(|&v| v as f64).collect());
    spread_both(w, h, spp, outlier, e, wide, true, &mut y);
    for ch in 0..3 {
        for (c, v) in color[ch].iter_mut().zip(&y[ch]) {
            *c = v.max(0.0) as f32;
        }
    }
}
