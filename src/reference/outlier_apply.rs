//! Scalar twin of `spirv/outlier_apply.comp`: at the detected pixels, the
//! replacement colour and variance ([`super::outlier_median`]'s output) go
//! into the statistics (spec §4.4 step 3); other pixels are untouched.

/// `color[ch][o] = rep[ch][o]` and `var[ch][o] = rep[3 + ch][o]` for every
/// `o` of `detected`.
pub fn outlier_apply(
    detected: &[usize],
    rep: [&[f32]; 6],
    color: [&mut [f32]; 3],
    var: [&mut [f32]; 3],
) {
    for (ch, (c, v)) in color.into_iter().zip(var).enumerate() {
        for &o in detected {
            c[o] = rep[ch][o];
            v[o] = rep[3 + ch][o];
        }
    }
}
