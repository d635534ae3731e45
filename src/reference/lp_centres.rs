//! Scalar twin of `spirv/lp_centres.comp`: one sparse-centre pass of LP
//! (spec §3.5) — every candidate of granularity `g` that no centre of an
//! earlier pass covers ([`super::lp_select`]) becomes a centre and gets its
//! optimisation of §3.3–3.4 ([`super::lp::centre_fit`]).

use super::lp::{centre_fit, FitOptions, Planes, StateLayout};
use crate::shared::LpPush;

/// One pass. `reach` is the [`lp_reach`](super::lp_reach) plane of the state
/// as it was after the earlier passes (PASS-SNAPSHOT).
/// `state` = the [`StateLayout::PLANES`] vec4 planes (`4·W·H` floats each):
/// only the pixels that become centres are written. Returns the number of
/// new centres.
pub fn lp_centres(push: &LpPush, p: &Planes, reach: &[f32], state: &mut [Vec<f32>]) -> usize {
    assert_eq!(state.len(), StateLayout::PLANES, "lp_centres: state planes");
    let w = p.width;
    let o = FitOptions::from_bits(push.options);
    let (_, gh) = push.centre_grid();
    let cand: Vec<(usize, usize)> = super::lp_select::lp_select(push, p, reach, (0, gh))
        .into_iter()
        .map(|q| (q as usize % w, q as usize / w))
        .collect();
    let results: Vec<(usize, [f32; StateLayout::LEN])> = super::par_map(cand.len(), |i| {
        let (px, py) = cand[i];
        (py * w + px, centre_fit(p, px, py, o).state(push.pass))
    });
    for (q, st) in &results {
        for (i, v) in st.iter().enumerate() {
            state[i / 4][4 * q + i % 4] = *v;
        }
    }
    results.len()
}
