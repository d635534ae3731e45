//! Scalar twin of `spirv/lp_reach.comp`: the horizontal half of LP's
//! coverage test (spec §3.5). Pixel `i` is covered by centre `c` when
//! `max(|dx|, |dy|) <= r_opt(c)`. With
//! `reach(x, y) = max{ r_opt(c) : c in row y, |x − c_x| <= r_opt(c) }`
//! (−1 if none) over the centres made before the current pass
//! (PASS-SNAPSHOT), `i` is covered by one of them iff some row `y'` has
//! `reach(x_i, y') >= |y_i − y'|`: the centre attaining the maximum reaches
//! `x_i` horizontally and, having the largest radius, vertically too. The
//! centre kernel's coverage test then reads 19 values of this plane instead
//! of the 361 of the centre map (the GPU gather reads none: it lists its
//! tile's centres itself, LP-GATHER-UNION; this twin's gather still skips
//! rows by it).

use super::lp::RADIUS;
use crate::shared::LpPush;

/// `reach` for every pixel (`row0` and `ring_rows` ignored: the whole
/// plane) from state plane 0 (`(pass + 1, r_opt, ·, ·)` per pixel, vec4),
/// over the centres made in a pass before `push.pass` (PASS-SNAPSHOT; 5:
/// all of them).
pub fn lp_reach(push: &LpPush, state0: &[f32], reach: &mut [f32]) {
    let (w, h) = (push.width as usize, push.height as usize);
    let before = push.pass as f32;
    for y in 0..h {
        for x in 0..w {
            let mut best = -1.0f32;
            for qx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                let q = y * w + qx;
                let r = state0[4 * q + 1];
                let made = state0[4 * q];
                if made > 0.0 && made <= before && qx.abs_diff(x) as f32 <= r && r > best {
                    best = r;
                }
            }
            reach[y * w + x] = best;
        }
    }
}
