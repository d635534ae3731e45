//! Scalar twin of `spirv/lp_select.comp`: the candidates of one band of one
//! sparse-centre pass of LP (spec §3.5) that become centres — valid, and
//! covered by no centre of an earlier pass (PASS-SNAPSHOT).

use super::lp::{covered, Planes};
use crate::shared::LpPush;

/// The pixels (`y·W + x`, raster order) of the candidates of grid rows
/// `rows` (`[first, end)` of [`LpPush::centre_grid`]) that become centres.
/// `reach` is the [`lp_reach`](super::lp_reach) plane of the state after the
/// earlier passes. The GPU queue holds the same set in an arbitrary order.
pub fn lp_select(push: &LpPush, p: &Planes, reach: &[f32], rows: (u32, u32)) -> Vec<u32> {
    let (w, h) = (p.width, p.height);
    let g = push.granularity.max(1) as usize;
    let (fx, fy) = push.phase_xy();
    let (gw, _) = push.centre_grid();
    let mut out = Vec::new();
    for gy in rows.0 as usize..rows.1 as usize {
        let py = fy as usize + gy * g;
        if py >= h {
            break;
        }
        for gx in 0..gw as usize {
            let px = fx as usize + gx * g;
            let q = py * w + px;
            if p.valid(q) && !covered(reach, w, h, px, py) {
                out.push(q as u32);
            }
        }
    }
    out
}
