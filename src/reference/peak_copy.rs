//! Scalar twin of `spirv/peak_copy.comp`: `dst[i] = src[i]`.

use crate::shared::PeakPush;

/// The first `push.width × push.height` words (`row0` ignored).
pub fn peak_copy(push: &PeakPush, src: &[f32], dst: &mut [f32]) {
    let n = push.width as usize * push.height as usize;
    dst[..n].copy_from_slice(&src[..n]);
}
