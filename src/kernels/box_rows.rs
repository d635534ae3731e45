//! `box_rows`: the row part of a box sum (or count) over valid pixels; the
//! outlier redistribution's column kernels finish it (spec §4.4 step 4).
//! Twin: `reference::box_rows`.

use crate::error::{Error, Result};
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{OutlierPush, BOX_COUNT_LAST};

/// Declaration of `spirv/box_rows.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "box_rows",
    bindings: &[
        read("value0"),
        read("value1"),
        read("value2"),
        read("value3"),
        read("spp"),
        write("out0"),
        write("out1"),
        write("out2"),
        write("out3"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Pixels per invocation (`SPAN` in the shader): one full window sum, then
/// a running sum, both exact pairs (TwoSum).
pub const SPAN: u32 = 32;

/// Per invocation: `2R+1` taps for the first pixel, then 2 per pixel, ×
/// (validity test, one TwoSum of 6 adds per plane).
pub fn flops_per_invocation(radius: u32, planes: usize) -> f64 {
    ((2.0 * radius as f64 + 1.0) + 2.0 * SPAN as f64) * (1.0 + 6.0 * planes as f64)
}

/// What the planes of one [`record`] hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxPlanes<'a> {
    /// The row sums of 2 or 4 value planes.
    Sums(&'a [BufferSlice]),
    /// The row sums of three value planes, and the valid count as a fourth.
    SumsAndCount(&'a [BufferSlice; 3]),
}

/// Records the row sums of `planes` into as many `out` planes (the valid
/// count into the fourth with [`BoxPlanes::SumsAndCount`]); `push.mode` is
/// set here. One dispatch for all of them: each tap's validity is read once.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    planes: BoxPlanes<'_>,
    spp: BufferSlice,
    out: &[BufferSlice],
) -> Result<()> {
    let (values, mode): (Vec<BufferSlice>, u32) = match planes {
        BoxPlanes::Sums(v) if v.len() == 2 || v.len() == 4 => (v.to_vec(), v.len() as u32),
        // The count's value slot is bound to the count plane and not read.
        BoxPlanes::SumsAndCount(v) => (vec![v[0], v[1], v[2], spp], 4 | BOX_COUNT_LAST),
        BoxPlanes::Sums(v) => {
            return Err(Error::InvalidArgument(format!(
                "box_rows sums 2 or 4 planes per dispatch, got {}",
                v.len()
            )))
        }
    };
    if out.len() != values.len() {
        return Err(Error::InvalidArgument(format!(
            "box_rows: {} planes into {} outputs",
            values.len(),
            out.len()
        )));
    }
    let push = OutlierPush { mode, ..*push };
    // Unused slots (two planes) are bound to the first and never accessed.
    let mut b: Vec<BufferSlice> = (0..4).map(|k| values[k % values.len()]).collect();
    b.push(spp);
    b.extend((0..4).map(|k| out[k % out.len()]));
    batch.dispatch(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        push.width.div_ceil(SPAN),
        push.height,
        flops_per_invocation(push.radius, values.len()),
    )
}
