//! `auto_blend`: `--method auto`'s blend of its 3 or 4 members from their
//! smoothed maps (AUTO-BLEND), one dispatch per member: per member the
//! larger of its own relative error estimate and the n-cornered hat of the
//! pairs' disagreements, weights `1 /` that, the weighted mean of the
//! colours and the combined error estimate `(Σ w √(k E) / Σ w)²`. Twin:
//! `reference::auto_blend`.

use super::auto_dis::{check_members, pair_slots};
use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{auto_pairs, AutoPush, AUTO_SUMS};

/// Declaration of `spirv/auto_blend.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "auto_blend",
    bindings: &[
        read("cr"),
        read("cg"),
        read("cb"),
        read("er"),
        read("eg"),
        read("eb"),
        read("score"),
        read("dis0"),
        read("dis1"),
        read("dis2"),
        read("dis3"),
        read("dis4"),
        read("dis5"),
        write("base_r"),
        write("base_g"),
        write("base_b"),
        write("num_r"),
        write("num_g"),
        write("num_b"),
        write("root_r"),
        write("root_g"),
        write("root_b"),
        write("wsum"),
        write("out_r"),
        write("out_g"),
        write("out_b"),
        write("err_r"),
        write("err_g"),
        write("err_b"),
    ],
    push_size: std::mem::size_of::<AutoPush>() as u32,
};

/// Per pixel and member dispatch: the hat estimate over the pairs, the
/// maximum, the weight's and the factor's divisions, three multiply-adds
/// for the colour and three square roots with their multiply-adds for the
/// error; the normalisation on the last.
pub fn flops_per_pixel(members: usize) -> f64 {
    2.0 * auto_pairs(members).len() as f64 + 4.0 + 2.0 + 6.0 + 3.0 + 9.0 + 10.0
}

/// One member's colour and error, and its smoothed score.
#[derive(Copy, Clone, Debug)]
pub struct Member {
    /// Its colour.
    pub color: [BufferSlice; 3],
    /// Its error estimate.
    pub error: [BufferSlice; 3],
    /// Its smoothed score (`auto_score`).
    pub score: BufferSlice,
}

/// Records the blend of `members` (3 or 4, in order) from the smoothed
/// disagreements `dis` (one per pair of [`auto_pairs`]) into `color` and
/// `error` over a `width × height` image, carrying its sums in `sums`
/// between the members' dispatches.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    members: &[Member],
    dis: &[BufferSlice],
    sums: [BufferSlice; AUTO_SUMS],
    color: [BufferSlice; 3],
    error: [BufferSlice; 3],
) -> Result<()> {
    check_members(members.len(), Some(dis.len()))?;
    for (m, mem) in members.iter().enumerate() {
        let push = AutoPush {
            width,
            height,
            members: members.len() as u32,
            member: m as u32,
            last: (m + 1 == members.len()) as u32,
            ..Default::default()
        };
        let mut bindings: Vec<BufferSlice> = mem
            .color
            .iter()
            .chain(&mem.error)
            .copied()
            .chain([mem.score])
            .collect();
        bindings.extend(pair_slots(dis));
        bindings.extend(sums);
        bindings.extend(color);
        bindings.extend(error);
        super::auto_score::dispatch(
            batch,
            &DECL,
            precision,
            &push,
            &bindings,
            flops_per_pixel(members.len()),
        )?;
    }
    Ok(())
}
