//! Scalar twin of `spirv/channel_mean.comp`: `out = (a + b + c)/3` per pixel
//! (e.g. `vbar` from the three colour variances, §0.1 GREY).

use crate::shared::ChannelMeanPush;

/// For every pixel of the `push.width × push.height` image (`row0` ignored).
pub fn channel_mean(push: &ChannelMeanPush, a: &[f32], b: &[f32], c: &[f32], out: &mut [f32]) {
    let n = push.width as usize * push.height as usize;
    for i in 0..n {
        out[i] = ((a[i] as f64 + b[i] as f64 + c[i] as f64) / 3.0) as f32;
    }
}
