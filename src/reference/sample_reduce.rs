//! Scalar twin of `spirv/sample_reduce.comp`: one level of the sampling
//! allocation's reduction tree (spec §9.1 sanitise, §9.2 ROUNDING), block by
//! block with the same fixed-order combination as the workgroup.

use super::sampling::{eff_bits, quantise, ref_bits, sane_bits, share_of, BLOCK};
use super::spp_of;
use crate::shared::SampleTreePush;
use crate::shared::{
    REDUCE_LEAF_MAX as MODE_LEAF_MAX, REDUCE_LEAF_Q as MODE_LEAF_Q, REDUCE_MAX as MODE_MAX,
    REDUCE_SUM as MODE_SUM,
};

const LO: u64 = 0xFFFF_FFFF;

fn combine(mode: u32, a: u64, b: u64) -> u64 {
    if mode <= MODE_MAX {
        (a & LO).max(b & LO) | ((a | b) & !LO)
    } else {
        a + b
    }
}

/// For every block `b < ceil(push.n / 64)`: `tree[dst_off + b]` = the
/// reduction of elements `64b .. 64b + 63` of the level (see the modes in
/// `kernels::sample_reduce`). `r` is the f32 priority map (its bits
/// are used), `spp` the sample counts. Grid fields of `push` are ignored.
pub fn sample_reduce(push: &SampleTreePush, r: &[f32], spp: &[f32], tree: &mut [u64]) {
    let n = push.n as usize;
    for block in 0..n.div_ceil(BLOCK) {
        let mut acc = [0u64; BLOCK];
        for (lid, a) in acc.iter_mut().enumerate() {
            let i = block * BLOCK + lid;
            if i >= n {
                continue;
            }
            *a = if push.mode == MODE_MAX || push.mode == MODE_SUM {
                tree[push.src_off as usize + i]
            } else {
                let valid = spp_of(spp[i]) >= 1.0;
                if push.mode == MODE_LEAF_MAX {
                    if valid {
                        sane_bits(r[i].to_bits()) as u64
                    } else {
                        1 << 32
                    }
                } else {
                    let m = tree[push.max_off as usize];
                    let mb = (m & LO) as u32;
                    let q = quantise(
                        eff_bits(r[i].to_bits(), valid, mb, (m >> 32) != 0),
                        ref_bits(mb),
                    );
                    if push.mode == MODE_LEAF_Q {
                        q
                    } else {
                        share_of(q, tree[push.s_off as usize])
                    }
                }
            };
        }
        let mut stride = BLOCK / 2;
        while stride > 0 {
            for lid in 0..stride {
                acc[lid] = combine(push.mode, acc[lid], acc[lid + stride]);
            }
            stride /= 2;
        }
        tree[push.dst_off as usize + block] = acc[0];
    }
}
