//! Scalar twin of `spirv/sanitize_low_spp.comp`: stage 1 of
//! [`super::sanitize::sanitize`] (spec §0.4 step 3).

use crate::shared::SanitizePush;

/// [`super::sanitize::sanitize`] with `push.stage` forced to 1.
pub fn sanitize_low_spp(
    push: &SanitizePush,
    value_in: &[f32],
    var_in: &[f32],
    spp: &[f32],
    value_out: &mut [f32],
    var_out: &mut [f32],
    counters: &mut [u32; 4],
) {
    let push = SanitizePush { stage: 1, ..*push };
    super::sanitize::sanitize(&push, value_in, var_in, spp, value_out, var_out, counters)
}
