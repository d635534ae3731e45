//! `outlier_apply`: writes the replacements [`super::outlier_median`] found
//! into the statistics at the queued pixels, in place (spec §4.4 step 3).
//! Twin: [`crate::reference::outlier_apply`].

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::OutlierPush;

/// Declaration of `spirv/outlier_apply.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_apply",
    bindings: &[
        read("rep_r"),
        read("rep_g"),
        read("rep_b"),
        read("rep_vr"),
        read("rep_vg"),
        read("rep_vb"),
        write("cr"),
        write("cg"),
        write("cb"),
        write("vr"),
        write("vg"),
        write("vb"),
        read("queue"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Records the copy of `rep` (colour R, G, B, variance R, G, B, written by
/// `outlier_median` at the pixels of `queue`) into `color` and `var` at
/// those pixels. One indirect dispatch (a unit: 12 words per entry); the
/// cost estimate assumes [`super::outlier_median::DETECTED_FRACTION`].
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    rep: [BufferSlice; 6],
    color: [BufferSlice; 3],
    var: [BufferSlice; 3],
    queue: BufferSlice,
) -> Result<()> {
    let bindings: Vec<BufferSlice> = [&rep[..], &color, &var, &[queue]].concat();
    let entries = push.width as f64 * push.height as f64 * super::outlier_median::DETECTED_FRACTION;
    batch.dispatch_indirect(
        &DECL,
        precision,
        &bindings,
        bytemuck::bytes_of(push),
        queue.sub(0, 12)?,
        entries,
        entries * 52.0,
    )
}
