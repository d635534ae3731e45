//! `aos_nlm`: AOS's variance-aware NL-means feature prefilter (spec §5.2)
//! of one buffer of 1 or 3 channels. Writes the filtered channels, then
//! their propagated variances, `push.stride` f32 values apart in one
//! binding. Twin: `reference::aos_nlm`. [`record_boxed`] runs the
//! `aos_nlm_vis` build of the same source, which first takes each pixel's
//! 3×3 mean of one channel (WLR-VIS: WLR's visibility); twin
//! `reference::aos_nlm::aos_nlm_boxed`.

use crate::error::Result;
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::AosPush;

/// Declaration of `spirv/aos_nlm.comp`; checked against the SPIR-V by
/// reflection.
pub const DECL: KernelDecl = KernelDecl {
    name: "aos_nlm",
    bindings: &[
        read("g0"),
        read("g1"),
        read("g2"),
        read("vg0"),
        read("vg1"),
        read("vg2"),
        read("spp"),
        write("dst").sized_by_record(),
    ],
    push_size: std::mem::size_of::<AosPush>() as u32,
};

/// Declaration of the `aos_nlm_vis` build (`WLR_VIS`: a 3×3 mean of the
/// input first); the same bindings.
pub const DECL_VIS: KernelDecl = KernelDecl {
    name: "aos_nlm_vis",
    ..DECL
};

/// Per pixel and per each of the `11²` candidate offsets (NLM-BOX, the
/// kernel's offset-by-offset form): a share `14²/64` of the workgroup's
/// patch-centre terms (per channel a difference, its square, the variance
/// terms and a division: ~8 flops, plus ~2), the 7×7 box sums of the term
/// and of the pair count as 7-row then 7-column sums (`(14·8 + 8·8)·6·2/64`
/// adds), and the weight's exponential (~20), its quotient and the weighted
/// sums.
pub fn flops_per_pixel(channels: u32) -> f64 {
    let c = channels as f64;
    let terms = 14.0 * 14.0 / 64.0 * (8.0 * c + 2.0);
    let boxes = (14.0 * 8.0 + 8.0 * 8.0) * 6.0 * 2.0 / 64.0;
    121.0 * (terms + boxes + 25.0 + 4.0 * c)
}

/// Records the prefilter of one buffer: `g` and `vg` hold `push.channels`
/// planes (the others any plane, unread), `dst` `2·channels` planes.
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    push: &AosPush,
    g: [BufferSlice; 3],
    vg: [BufferSlice; 3],
    spp: BufferSlice,
    dst: BufferSlice,
) -> Result<()> {
    let flops = flops_per_pixel(push.channels);
    record_decl(batch, &DECL, precision, push, [g, vg], spp, dst, flops)
}

/// [`record`] of the 3×3 means of one plane `g` (variances `Σ vg / n²`
/// over the window's valid pixels): the `aos_nlm_vis` build, `dst` two
/// planes.
///
/// # Panics
/// If `push.channels` is not 1.
pub fn record_boxed(
    batch: &mut Batch,
    precision: Precision,
    push: &AosPush,
    [g, vg, spp]: [BufferSlice; 3],
    dst: BufferSlice,
) -> Result<()> {
    assert_eq!(push.channels, 1, "aos_nlm_vis filters one channel");
    // The 3×3 means of the staged region's 24² pixels per 8×8 tile: 9 sums
    // of value and variance and the divisions.
    let flops = flops_per_pixel(1) + 24.0 * 24.0 / 64.0 * (9.0 * 2.0 + 4.0);
    let planes = [[g; 3], [vg; 3]];
    record_decl(batch, &DECL_VIS, precision, push, planes, spp, dst, flops)
}

#[allow(clippy::too_many_arguments)] // record's arguments, and the variant's decl and flops
fn record_decl(
    batch: &mut Batch,
    decl: &KernelDecl,
    precision: Precision,
    push: &AosPush,
    [g, vg]: [[BufferSlice; 3]; 2],
    spp: BufferSlice,
    dst: BufferSlice,
    flops: f64,
) -> Result<()> {
    // The smoothed channels and their variances, `stride` words apart.
    let planes = 2 * push.channels.max(1) as u64 - 1;
    let pixels = push.width as u64 * push.height as u64;
    decl.require(7, &dst, 4 * (planes * push.stride as u64 + pixels))?;
    let groups: [&[BufferSlice]; 3] = [&g, &vg, &[spp, dst]];
    super::dispatch_image(batch, decl, precision, push, &groups, flops)
}
