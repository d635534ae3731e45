//! Scalar twin of `spirv/sample_scan.comp`: the down-sweep of the sampling
//! allocation's prefix sum and the final counts (spec §9.2 ROUNDING steps
//! 2–3), block by block.

use super::sampling::{eff_bits, quantise, ref_bits, share_of, BLOCK};
use super::spp_of;
use crate::shared::SampleTreePush;
use crate::shared::{SCAN_INNER as MODE_INNER, SCAN_NO_LEVEL as NO_LEVEL};

/// For every block of 64 elements of the level: the inclusive prefix within
/// the block plus the block's offset `tree[par_off + block]` (0 if
/// `par_off = NO_LEVEL`). Inner mode writes the exclusive prefixes to
/// `tree[dst_off..]`; leaf mode writes `counts[i] = floor(T P_i/U) −
/// floor(T P_{i−1}/U)` (`U = tree[u_off]`; `U = 0` takes `P_i = i + 1`,
/// `U = N`). Grid fields of `push` are ignored.
pub fn sample_scan(
    push: &SampleTreePush,
    r: &[f32],
    spp: &[f32],
    tree: &mut [u64],
    counts: &mut [u32],
) {
    let n = push.n as usize;
    for block in 0..n.div_ceil(BLOCK) {
        let mut v = [0u64; BLOCK];
        for (lid, a) in v.iter_mut().enumerate() {
            let i = block * BLOCK + lid;
            if i >= n {
                continue;
            }
            *a = if push.mode == MODE_INNER {
                tree[push.src_off as usize + i]
            } else {
                let m = tree[push.max_off as usize];
                let mb = m as u32;
                let q = quantise(
                    eff_bits(r[i].to_bits(), spp_of(spp[i]) >= 1.0, mb, (m >> 32) != 0),
                    ref_bits(mb),
                );
                share_of(q, tree[push.s_off as usize])
            };
        }
        let base = if push.par_off == NO_LEVEL {
            0
        } else {
            tree[push.par_off as usize + block]
        };
        let mut incl = base;
        for lid in 0..BLOCK {
            let i = block * BLOCK + lid;
            if i >= n {
                break;
            }
            incl += v[lid];
            if push.mode == MODE_INNER {
                tree[push.dst_off as usize + i] = incl - v[lid];
                continue;
            }
            let t = push.budget as u64;
            let (p1, p0, u_total) = match tree[push.u_off as usize] {
                0 => (i as u64 + 1, i as u64, n as u64),
                u => (incl, incl - v[lid], u),
            };
            let (f, np) = (push.spread as u64, n as u64);
            let even = (f * (i as u64 + 1) / np - f * i as u64 / np) as u32;
            counts[i] = even + (t * p1 / u_total - t * p0 / u_total) as u32;
        }
    }
}
