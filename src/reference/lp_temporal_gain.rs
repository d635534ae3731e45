//! Scalar twin of `spirv/lp_temporal_gain.comp`: the LP temporal filter's
//! factor on an adaptive pass's error estimate (TEMPORAL-MAP).

use super::lp_temporal::{centre, frame_motion, step, Step, TemporalInputs};
use crate::shared::TemporalPush;

/// Per pixel, the filter's [`step`] from the state planes `prev` (read
/// only): `g = min(P00, 1)` after the update where the state continues, 1
/// where the pixel is reset or passed through; `scaled = g · error` per
/// channel.
pub fn lp_temporal_gain(
    push: &TemporalPush,
    inp: &TemporalInputs,
    prev: &[f32],
    error: [&[f32]; 3],
    scaled: [&mut [f32]; 3],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    let [sr, sg, sb] = scaled;
    let motion = frame_motion(push, inp, prev);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let g = match step(push, inp, prev, (x, y), centre(motion.as_ref(), (x, y))) {
                Step::Continue(s, _) => s.p[0].min(1.0),
                Step::Reset(_) | Step::PassThrough => 1.0,
            };
            sr[i] = (g * error[0][i] as f64) as f32;
            sg[i] = (g * error[1][i] as f64) as f32;
            sb[i] = (g * error[2][i] as f64) as f32;
        }
    }
}
