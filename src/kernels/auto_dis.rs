//! `auto_dis`: how far each pair of `--method auto`'s 3 or 4 members
//! disagrees (AUTO-BLEND), `Σ_c (f_a,c − f_b,c)² / (f̄_c² + 0.01)` per pair
//! of [`crate::shared::auto_pairs`]. Twin: `reference::auto_dis`.

use crate::error::{Error, Result};
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{auto_pairs, AutoPush, AUTO_MAX_MEMBERS, AUTO_MAX_PAIRS};

/// Declaration of `spirv/auto_dis.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "auto_dis",
    bindings: &[
        read("c0r"),
        read("c0g"),
        read("c0b"),
        read("c1r"),
        read("c1g"),
        read("c1b"),
        read("c2r"),
        read("c2g"),
        read("c2b"),
        read("c3r"),
        read("c3g"),
        read("c3b"),
        write("dis0"),
        write("dis1"),
        write("dis2"),
        write("dis3"),
        write("dis4"),
        write("dis5"),
    ],
    push_size: std::mem::size_of::<AutoPush>() as u32,
};

/// Per pixel and pair: three channels, each a difference, a square and a
/// division, summed; per pixel the members' mean and its squares.
pub fn flops_per_pixel(members: usize) -> f64 {
    auto_pairs(members).len() as f64 * (3.0 * 4.0 + 2.0) + 3.0 * (members as f64 + 3.0)
}

/// `Err` unless `members` is 3 or 4 and, with `dis`, `dis` has one map
/// per pair of them.
pub fn check_members(members: usize, dis: Option<usize>) -> Result<()> {
    if !(3..=AUTO_MAX_MEMBERS).contains(&members) {
        return Err(Error::InvalidArgument(format!(
            "auto blends 3 or 4 members, not {members}"
        )));
    }
    let pairs = auto_pairs(members).len();
    match dis {
        Some(d) if d != pairs => Err(Error::InvalidArgument(format!(
            "auto: {members} members need {pairs} disagreement maps, not {d}"
        ))),
        _ => Ok(()),
    }
}

/// The disagreement maps bound to a kernel's [`AUTO_MAX_PAIRS`] slots:
/// `dis`, then its first map again in the slots a smaller set does not use.
pub(crate) fn pair_slots(dis: &[BufferSlice]) -> impl Iterator<Item = BufferSlice> + '_ {
    (0..AUTO_MAX_PAIRS).map(|k| *dis.get(k).unwrap_or(&dis[0]))
}

/// Records the disagreements of the members with `colors` (3 or 4) into
/// `dis` (one map per pair of [`auto_pairs`]) over a `width × height`
/// image. The bindings a smaller set does not use get its first member's
/// colour and its first map (`pair_slots`): the kernel neither reads nor
/// writes them with three members (`dis3`–`dis5` alias `dis0` then, so a
/// write to them must stay under `push.members == 4`).
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    (width, height): (u32, u32),
    colors: &[[BufferSlice; 3]],
    dis: &[BufferSlice],
) -> Result<()> {
    check_members(colors.len(), Some(dis.len()))?;
    let push = AutoPush {
        width,
        height,
        members: colors.len() as u32,
        ..Default::default()
    };
    let mut bindings: Vec<BufferSlice> = (0..AUTO_MAX_MEMBERS)
        .flat_map(|m| colors.get(m).unwrap_or(&colors[0]).iter().copied())
        .collect();
    bindings.extend(pair_slots(dis));
    super::auto_score::dispatch(
        batch,
        &DECL,
        precision,
        &push,
        &bindings,
        flops_per_pixel(colors.len()),
    )
}
