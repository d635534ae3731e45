//! Scalar twin of `spirv/sample_upsample.comp`: a coarse sample map's
//! priority at the full resolution (MAP-COARSE).

use crate::shared::PyramidPush;

/// Each fine pixel of the push's `width × height` image takes the value of
/// the coarse pixel (of `other_width × other_height`) whose 2×2 block
/// holds it.
pub fn sample_upsample(push: &PyramidPush, coarse: &[f32], dst: &mut [f32]) {
    let (w, h) = (push.width as usize, push.height as usize);
    let (cw, ch) = (push.other_width as usize, push.other_height as usize);
    for y in 0..h {
        for x in 0..w {
            dst[y * w + x] = coarse[(y / 2).min(ch - 1) * cw + (x / 2).min(cw - 1)];
        }
    }
}
