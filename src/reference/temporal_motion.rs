//! Scalar twin of `spirv/temporal_motion.comp`: one level of TEMPORAL-MOTION's
//! coarse-to-fine search for where each pixel's surface was in the
//! previous frame, and ([`motion`]) the whole search, from the coarsest
//! pooled level to the full resolution, as the LP temporal filter runs it
//! before its 7×7 window.

use super::finalize_stats::spp_of;
use super::pyramid_pool::{coarse_size, pyramid_pool};
use crate::shared::{
    MotionPush, PyramidPush, PYRAMID_COUNT, PYRAMID_MEAN, TEMPORAL_MOTION_LEVELS,
    TEMPORAL_MOTION_RADIUS, TEMPORAL_VALID,
};

/// One level over the push's image: per pixel, the search centred on twice
/// its coarser block's offset (`coarse`, read where `push.coarse` is set;
/// 0 otherwise) among the previous frame's pixels whose count `prev[3]` is
/// at least 1 — the pixel itself, the centre, then those within
/// `push.radius` of the centre in raster order — for the least squared
/// distance between their position `prev[0..3]` and the pixel's
/// `cur[0..3]` (a later one only if strictly nearer);
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
                let window = window
                    .filter(|&d| d != (0, 0))
                    .map(|(dx, dy)| (centre.0 + dx, centre.1 + dy))
                    .filter(|&o| o != (0, 0));
                let first = std::iter::once((0, 0)).chain((centre != (0, 0)).then_some(centre));
                for (dx, dy) in first.chain(window) {
                    let (jx, jy) = (x + dx, y + dy);
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
                        best = (dx, dy);
                    }
                }
            }
            ox[i] = best.0 as f32;
            oy[i] = best.1 as f32;
        }
    }
}

/// A level's offsets, in its pixels; at level 0 (the search's result) each
/// pixel's, which centre the LP temporal filter's window.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// The level's width.
    pub width: usize,
    /// Its height.
    pub height: usize,
    /// Offset X per pixel.
    pub ox: Vec<f32>,
    /// Offset Y.
    pub oy: Vec<f32>,
}

impl Motion {
    /// Pixel `(x, y)`'s offset: the centre of its window less the pixel.
    pub fn centre(&self, x: usize, y: usize) -> (i32, i32) {
        let k = y * self.width + x;
        (self.ox[k] as i32, self.oy[k] as i32)
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
/// positions (the [`TEMPORAL_STATE`](crate::shared::TEMPORAL_STATE)
/// planes `prev`, weighted by their valid flags), levels 1 to [`TEMPORAL_MOTION_LEVELS`], and each level's search
/// ([`temporal_motion`], radius [`TEMPORAL_MOTION_RADIUS`]) from the
/// coarsest to the frame itself (level 0): each pixel's offset.
pub fn motion(
    (width, height): (usize, usize),
    position: [&[f32]; 3],
    spp: &[f32],
    prev: &[f32],
) -> Motion {
    let n = width * height;
    let state = |k: usize| &prev[k * n..(k + 1) * n];
    let full_cur = [position[0], position[1], position[2], spp];
    let full_prev = [state(9), state(10), state(11), state(TEMPORAL_VALID)];
    let mut levels: Vec<Level> = Vec::new();
    for _ in 0..TEMPORAL_MOTION_LEVELS {
        let (fine_size, cur, prv) = match levels.last() {
            None => ((width, height), full_cur, full_prev),
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
    // The coarser level's offsets, as a Motion; level 0 reads the frames'
    // own planes.
    let full = ((width, height), full_cur, full_prev);
    let pooled = levels.iter().rev().map(|l| {
        let cur = l.cur.each_ref().map(|v| &v[..]);
        let prv = l.prev.each_ref().map(|v| &v[..]);
        (l.size, cur, prv)
    });
    let mut coarse: Option<Motion> = None;
    for ((w, h), cur, prv) in pooled.chain(std::iter::once(full)) {
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
        temporal_motion(&push, cur, prv, planes, [&mut ox, &mut oy]);
        coarse = Some(Motion {
            width: w,
            height: h,
            ox,
            oy,
        });
    }
    coarse.expect("at least one level")
}
