//! Scalar twin of `spirv/temporal_motion.comp`: one level of TEMPORAL-MOTION's
//! coarse-to-fine search for where each pixel's surface was in the
//! previous frame, and ([`motion`]) the whole search as the LP temporal
//! filter runs it before its 7×7 window.

use super::finalize_stats::spp_of;
use super::pyramid_pool::{coarse_size, pyramid_pool};
use crate::shared::{
    MotionPush, PyramidPush, PYRAMID_COUNT, PYRAMID_MEAN, TEMPORAL_MOTION_LEVELS,
    TEMPORAL_MOTION_RADIUS, TEMPORAL_VALID,
};

/// One level over the push's image: per pixel, the search centred on twice
/// its coarser block's offset (`coarse`, read where `push.coarse` is set;
/// 0 otherwise) among the previous frame's pixels within `push.radius` of
/// it whose count `prev[3]` is at least 1, for the least squared distance
/// between their position `prev[0..3]` and the pixel's `cur[0..3]` (the
/// centre first, then raster order, a later one only if strictly nearer);
/// a pixel whose count `cur[3]` is below 1, or without a candidate, keeps
/// the centre. Writes the offsets X, Y into `out`.
pub fn temporal_motion(
    push: &MotionPush,
    cur: [&[f32]; 4],
    prev: [&[f32]; 4],
    coarse: [&[f32]; 2],
    out: [&mut [f32]; 2],
) {
    let (w, h) = (push.width as i32, push.height as i32);
    let (cw, ch) = (push.coarse_width as usize, push.coarse_height as usize);
    let r = push.radius;
    let [ox, oy] = out;
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let centre = if push.coarse != 0 {
                let k = (y as usize / 2).min(ch - 1) * cw + (x as usize / 2).min(cw - 1);
                (2 * coarse[0][k] as i32, 2 * coarse[1][k] as i32)
            } else {
                (0, 0)
            };
            let mut best = centre;
            if spp_of(cur[3][i]) >= 1.0 {
                let p = [0, 1, 2].map(|k| cur[k][i] as f64);
                let mut best_cost: Option<f64> = None;
                let window = (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)));
                for (dx, dy) in std::iter::once((0, 0)).chain(window.filter(|&d| d != (0, 0))) {
                    let (jx, jy) = (x + centre.0 + dx, y + centre.1 + dy);
                    if jx < 0 || jy < 0 || jx >= w || jy >= h {
                        continue;
                    }
                    let j = (jy * w + jx) as usize;
                    if spp_of(prev[3][j]) < 1.0 {
                        continue;
                    }
                    let cost: f64 = (0..3).map(|k| (prev[k][j] as f64 - p[k]).powi(2)).sum();
                    if best_cost.map_or(true, |b| cost < b) {
                        best_cost = Some(cost);
                        best = (centre.0 + dx, centre.1 + dy);
                    }
                }
            }
            ox[i] = best.0 as f32;
            oy[i] = best.1 as f32;
        }
    }
}

/// The search's result: the offsets at half resolution (level 1), which
/// centre the LP temporal filter's window.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// Level 1's width (the frame's, halved and rounded up).
    pub width: usize,
    /// Level 1's height.
    pub height: usize,
    /// Offset X per level-1 pixel, in level-1 pixels.
    pub ox: Vec<f32>,
    /// Offset Y.
    pub oy: Vec<f32>,
}

impl Motion {
    /// The centre of pixel `(x, y)`'s window in the frame: twice its block's
    /// offset.
    pub fn centre(&self, x: usize, y: usize) -> (i32, i32) {
        let k = (y / 2).min(self.height - 1) * self.width + (x / 2).min(self.width - 1);
        (2 * self.ox[k] as i32, 2 * self.oy[k] as i32)
    }
}

/// A level of the pyramids: positions X, Y, Z and counts, of this frame
/// and of the previous one.
struct Level {
    size: (usize, usize),
    cur: [Vec<f32>; 4],
    prev: [Vec<f32>; 4],
}

/// The pooled level of `fine` (`[X, Y, Z, count]` of a `(fw, fh)` image).
fn pool(fine: [&[f32]; 4], (fw, fh): (usize, usize)) -> ((usize, usize), [Vec<f32>; 4]) {
    let (w, h) = coarse_size(fw, fh);
    let out = std::array::from_fn(|k| {
        let push = PyramidPush {
            width: w as u32,
            height: h as u32,
            kind: if k == 3 { PYRAMID_COUNT } else { PYRAMID_MEAN },
            other_width: fw as u32,
            other_height: fh as u32,
            ..Default::default()
        };
        let mut dst = vec![0.0; w * h];
        pyramid_pool(&push, fine[k], fine[3], &mut dst);
        dst
    });
    ((w, h), out)
}

/// TEMPORAL-MOTION over a `width × height` frame: the pyramids of this
/// frame's `position` (weighted by `spp`) and of the previous state's
/// positions (the [`TEMPORAL_STATE`](crate::shared::TEMPORAL_STATE) planes `prev`, weighted by their valid
/// flags), levels 1 to [`TEMPORAL_MOTION_LEVELS`], each level's search
/// ([`temporal_motion`], radius [`TEMPORAL_MOTION_RADIUS`]) from the
/// coarsest to level 1.
pub fn motion(
    (width, height): (usize, usize),
    position: [&[f32]; 3],
    spp: &[f32],
    prev: &[f32],
) -> Motion {
    let n = width * height;
    let state = |k: usize| &prev[k * n..(k + 1) * n];
    let mut levels: Vec<Level> = Vec::new();
    for _ in 0..TEMPORAL_MOTION_LEVELS {
        let (fine_size, cur, prv) = match levels.last() {
            None => (
                (width, height),
                [position[0], position[1], position[2], spp],
                [state(9), state(10), state(11), state(TEMPORAL_VALID)],
            ),
            Some(f) => (
                f.size,
                f.cur.each_ref().map(|v| &v[..]),
                f.prev.each_ref().map(|v| &v[..]),
            ),
        };
        let (size, cur) = pool(cur, fine_size);
        let (_, prv) = pool(prv, fine_size);
        levels.push(Level {
            size,
            cur,
            prev: prv,
        });
    }
    // The offsets of the level below the current one, as a Motion.
    let mut coarse: Option<Motion> = None;
    for level in levels.iter().rev() {
        let (w, h) = level.size;
        let push = MotionPush {
            width: w as u32,
            height: h as u32,
            coarse: coarse.is_some() as u32,
            coarse_width: coarse.as_ref().map_or(1, |c| c.width) as u32,
            coarse_height: coarse.as_ref().map_or(1, |c| c.height) as u32,
            radius: TEMPORAL_MOTION_RADIUS,
            ..Default::default()
        };
        let zero = [0.0f32];
        let planes = coarse
            .as_ref()
            .map_or([&zero[..], &zero[..]], |c| [&c.ox[..], &c.oy[..]]);
        let (mut ox, mut oy) = (vec![0.0; w * h], vec![0.0; w * h]);
        temporal_motion(
            &push,
            level.cur.each_ref().map(|v| &v[..]),
            level.prev.each_ref().map(|v| &v[..]),
            planes,
            [&mut ox, &mut oy],
        );
        coarse = Some(Motion {
            width: w,
            height: h,
            ox,
            oy,
        });
    }
    coarse.expect("at least one level")
}
