//! Scalar twin of `spirv/lp_smooth.comp`: the LP temporal filter's two
//! directions combined, a two-filter smoother (TEMPORAL-SMOOTH), each
//! direction weighing at most as much as the other where that one has met
//! a change (SMOOTH-SHORT).

use crate::shared::{TwoWayPush, SMOOTH_SHORT};

/// One direction of the filter on a frame: its output colour and `P₀₀`
/// after its update (0 where it passed the pixel through).
#[derive(Copy, Clone, Debug)]
pub struct Direction<'a> {
    /// The filtered colour R, G, B.
    pub color: [&'a [f32]; 3],
    /// `P₀₀` per pixel.
    pub p00: &'a [f32],
}

/// The combination at one pixel of a channel: with `a = 1/P₀₀` of each
/// direction (its estimate's information in units of one frame's; both
/// hold the frame's own `y` once) and `full` the information each would
/// hold had it met no change ([`TwoWayPush::full_forward`],
/// [`TwoWayPush::full_backward`]), each direction's weight `w` is its `a`,
/// but at most the other's `a` where the other is below [`SMOOTH_SHORT`]
/// of its `full` (SMOOTH-SHORT); the output is
/// `max((w_f F + w_b B − y)/(w_f + w_b − 1), 0)`; `F` where either
/// direction has no state (`P₀₀ ≤ 0`) or the denominator is not above
/// `1e-6`.
pub fn combine(y: f64, (f, pf): (f64, f64), (b, pb): (f64, f64), full: (f64, f64)) -> f64 {
    if !(pf > 0.0 && pb > 0.0) {
        return f;
    }
    let (af, ab) = (1.0 / pf, 1.0 / pb);
    let short = SMOOTH_SHORT as f64;
    let wf = if ab < short * full.1 { af.min(ab) } else { af };
    let wb = if af < short * full.0 { ab.min(af) } else { ab };
    let den = wf + wb - 1.0;
    if den.is_nan() || den <= 1e-6 {
        return f;
    }
    ((wf * f + wb * b - y) / den).max(0.0)
}

/// [`combine`] over every pixel and channel of `y`, `forward` and
/// `backward` into `out`, with the push's full informations.
pub fn lp_smooth(
    push: &TwoWayPush,
    y: [&[f32]; 3],
    forward: &Direction,
    backward: &Direction,
    out: [&mut [f32]; 3],
) {
    let full = (push.full_forward as f64, push.full_backward as f64);
    for (c, o) in out.into_iter().enumerate() {
        for (i, v) in o.iter_mut().enumerate() {
            let f = (forward.color[c][i] as f64, forward.p00[i] as f64);
            let b = (backward.color[c][i] as f64, backward.p00[i] as f64);
            *v = combine(y[c][i] as f64, f, b, full) as f32;
        }
    }
}
