//! `gbf_pack`: packs the seven feature planes the G-buffer prefilter
//! filters (normal x y z, depth, albedo r g b) and their variances into four
//! vec4 planes for [`super::gbf_filter`]. Twin: `reference::gbf_pack`.

use crate::error::{Error, Result};
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, KernelDecl, Precision};
use crate::shared::GbfPush;

/// Declaration of `spirv/gbf_pack.comp`.
pub const DECL: KernelDecl = KernelDecl {
    name: "gbf_pack",
    bindings: &[
        read("feature0").sized_by_record(),
        read("feature1").sized_by_record(),
        read("feature2").sized_by_record(),
        read("feature3").sized_by_record(),
        read("feature4").sized_by_record(),
        read("feature5").sized_by_record(),
        read("feature6").sized_by_record(),
        read("var_feature0").sized_by_record(),
        read("var_feature1").sized_by_record(),
        read("var_feature2").sized_by_record(),
        read("var_feature3").sized_by_record(),
        read("var_feature4").sized_by_record(),
        read("var_feature5").sized_by_record(),
        read("var_feature6").sized_by_record(),
        read("spp").sized_by_record(),
        write("features_a").sized_by_record(),
        write("features_b").sized_by_record(),
        write("variances_a").sized_by_record(),
        write("variances_b").sized_by_record(),
    ],
    push_size: std::mem::size_of::<GbfPush>() as u32,
};

/// Per pixel: no arithmetic, 15/4 vec4 loads and 4 vec4 stores (counted
/// as 1 so the band estimate stays positive).
pub fn flops_per_pixel() -> f64 {
    1.0
}

/// Records the packing of the image rows `rows` (`[first, end)`, `first` a
/// multiple of 16) of `feat` and `var` (7 full planes each) and the sample
/// counts `spp` into `packed` (4 vec4 ranges of `(end − first) × width × 16`
/// bytes, starting at row `first`: features 0–3, features 4–6 and spp
/// (PACKED-SPP), variances 0–3, variances 4–6 and 0). PACK-QUADS: the
/// inputs are read as vec4s, so each must be bound as whole vec4s up to
/// pixel `end × width` (`PlaneSet::plane_quads`); an error otherwise.
#[allow(clippy::too_many_arguments)]
pub fn record(
    batch: &mut Batch,
    precision: Precision,
    width: u32,
    height: u32,
    rows: (u32, u32),
    feat: [BufferSlice; 7],
    var: [BufferSlice; 7],
    spp: BufferSlice,
    packed: [BufferSlice; 4],
) -> Result<()> {
    let (first, end) = (rows.0, rows.1.min(height));
    if first % 16 != 0 {
        return Err(Error::InvalidArgument(format!(
            "gbf_pack: first row {first} is not a multiple of 16"
        )));
    }
    // The 15 inputs, then the 4 packed outputs.
    let b: Vec<BufferSlice> = [&feat[..], &var, &[spp], &packed].concat();
    // The inputs are read as whole vec4s up to the end of `rows` (a
    // PlaneSet's plane_quads pads them); each packed output holds a vec4
    // per pixel of `rows`, from `first`.
    let read = (end as u64 * width as u64 * 4).div_ceil(16) * 16;
    let packed_bytes = 16 * width as u64 * end.saturating_sub(first) as u64;
    for (k, s) in b.iter().enumerate() {
        DECL.require(k, s, if k < 15 { read } else { packed_bytes })?;
    }
    // Push `height`: the end of the rows packed (see the shader).
    let push = GbfPush {
        width,
        height: end,
        base: first,
        ..Default::default()
    };
    // Grid rows of ceil(width / 4) quads over the run of pixels of `rows`.
    let w4 = width.div_ceil(4);
    let quad_rows = |n: u32| {
        (n as u64 * width as u64)
            .div_ceil(4)
            .div_ceil(w4.max(1) as u64) as u32
    };
    batch.dispatch_rows(
        &DECL,
        precision,
        &b,
        bytemuck::bytes_of(&push),
        w4,
        (
            (first, first + quad_rows(end.saturating_sub(first))),
            quad_rows(height),
        ),
        flops_per_pixel() * 4.0,
    )
}
