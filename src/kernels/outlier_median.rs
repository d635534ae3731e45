//! `outlier_median`: outlier replacement (spec §4.4 steps 2–3) at the pixels
//! [`super::outlier_detect`] queued: each takes the colour and variance of
//! its window's median pixel (an 8-step radix selection over the window,
//! 4-bit digits), written to the replacement planes, and `e = y_o − y_q*`;
//! a second dispatch ([`Step::Apply`]) writes the replacements into the
//! statistics. Dispatched indirectly, one invocation per queued pixel.
//! Twin: `reference::outlier_median`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::{OutlierPush, OUTLIER_APPLY};

/// Declaration of `spirv/outlier_median.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "outlier_median",
    bindings: &[
        write("cr"),
        write("cg"),
        write("cb"),
        write("vr"),
        write("vg"),
        write("vb"),
        read("keys"),
        read("queue").sized_by_record(),
        write("out_r"),
        write("out_g"),
        write("out_b"),
        write("out_vr"),
        write("out_vg"),
        write("out_vb"),
        write("er"),
        write("eg"),
        write("eb"),
    ],
    push_size: std::mem::size_of::<OutlierPush>() as u32,
};

/// Invocations per workgroup (`local_size_x`); `outlier_detect` counts the
/// workgroups of the indirect dispatch in units of it.
pub const GROUP: u32 = 64;

/// Fraction of pixels assumed detected, for the cost estimate (measured on
/// 4-spp renders of the built-in scenes: well under 1 %).
pub const DETECTED_FRACTION: f64 = 0.01;

/// Pixels of the `(2R+1)²` window.
fn window_pixels(radius: u32) -> f64 {
    (2.0 * radius as f64 + 1.0).powi(2)
}

/// Per queued pixel, at most 9 scans of the `(2R+1)²` window (≈ 12
/// operations per pixel each: the 16 digit counters): one per 4-bit digit
/// (the first also counts the window's valid pixels) and the one that
/// finds the median's pixel. An upper bound: MEDIAN-EARLY stops choosing
/// digits once a single key carries those chosen, so the bench's rate for
/// this kernel is a bound too (integer work, counted as operations).
pub fn flops_per_entry(radius: u32) -> f64 {
    9.0 * window_pixels(radius) * 12.0
}

/// The two dispatches of the kernel, in this order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Each queued pixel's median pixel: its colour and variance into
    /// `out`, and `excess`.
    Find,
    /// [`OUTLIER_APPLY`]: at the queued pixels, `out` into `color` and
    /// `var`, in place; nothing else is read or written (so the stage never
    /// copies the statistics).
    Apply,
}

/// Records one step of the replacement of the queued pixels (`keys` from
/// `outlier_grey`, 0 where invalid; `queue` from `outlier_detect`): the
/// medians into `out` (6: R, G, B, var R, G, B) and `excess`, or those into
/// `color` and `var`. Both steps take the same bindings.
///
/// A dispatch cannot be split into bands. Its worst case is bounded:
/// OUTLIER-ISOLATED (and OUTLIER-RIM) never detects two 8-neighbours, so
/// at most a quarter of the pixels are queued (the queue's capacity; the
/// kernels drop any excess): ≈ 0.1 MFLOP per entry at R = 14, at most ≈ 25
/// GFLOP per megapixel, milliseconds on a discrete GPU. At most 65535 workgroups are
/// dispatched; the invocations stride over more entries. The cost estimate
/// assumes [`DETECTED_FRACTION`].
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &OutlierPush,
    step: Step,
    color: [BufferSlice; 3],
    var: [BufferSlice; 3],
    keys: BufferSlice,
    queue: BufferSlice,
    out: [BufferSlice; 6],
    excess: [BufferSlice; 3],
) -> Result<()> {
    let (mode, flops, bytes) = match step {
        // Per entry: the window's keys, its own 18 values.
        Step::Find => (
            0,
            flops_per_entry(push.radius),
            window_pixels(push.radius) * 4.0 + 72.0,
        ),
        Step::Apply => (OUTLIER_APPLY, 1.0, 52.0),
    };
    let words = super::outlier_detect::queue_words(push.width as usize, push.height as usize);
    DECL.require(7, &queue, 4 * words as u64)?;
    let push = OutlierPush { mode, ..*push };
    let groups: [&[BufferSlice]; 5] = [&color, &var, &[keys, queue], &out, &excess];
    super::dispatch_queued(batch, &DECL, precision, &push, &groups, queue, flops, bytes)
}
