//! Scalar twin of `spirv/sanitize_quads.comp`: stage 0 of
//! [`super::sanitize::sanitize`] (spec §0.4 steps 1–2); the kernel reads four
//! pixels at a time, the result is the same.

use crate::shared::SanitizePush;

/// [`super::sanitize::sanitize`] with `push.stage` forced to 0.
pub fn sanitize_quads(
    push: &SanitizePush,
    value_in: &[f32],
    var_in: &[f32],
    spp: &[f32],
    value_out: &mut [f32],
    var_out: &mut [f32],
    counters: &mut [u32; 4],
) {
    let push = SanitizePush { stage: 0, ..*push };
    super::sanitize::sanitize(&push, value_in, var_in, spp, value_out, var_out, counters)
}
