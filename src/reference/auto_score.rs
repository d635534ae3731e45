//! Scalar twin of `spirv/auto_score.comp`: one member's score map for
//! `--method auto` (AUTO-BLEND).

use crate::shared::{AutoPush, AUTO_SCORE_MAX};

/// One member's planes: colour R, G, B or error R, G, B.
pub type Rgb<'a> = [&'a [f32]; 3];

/// `v` as f32, or [`AUTO_SCORE_MAX`] where that is not finite.
pub fn finite_or_max(v: f64) -> f32 {
    let s = v as f32;
    if s.is_finite() {
        s
    } else {
        AUTO_SCORE_MAX
    }
}

/// Per pixel (`row0` ignored): `score = Σ_c max(E_c, 0) / (f_c² + 0.01)`
/// of the member with colour `f` and error `E`; [`AUTO_SCORE_MAX`] where
/// that is not finite.
pub fn auto_score(push: &AutoPush, color: Rgb, error: Rgb, score: &mut [f32]) {
    let n = (push.width * push.height) as usize;
    for (i, s) in score.iter_mut().enumerate().take(n) {
        let v: f64 = (0..3)
            .map(|c| {
                let f = color[c][i] as f64;
                (error[c][i] as f64).max(0.0) / (f * f + 0.01)
            })
            .sum();
        *s = finite_or_max(v);
    }
}
