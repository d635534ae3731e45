//! Scalar twin of `spirv/sanitize.comp`: input sanitation (spec §0.4), one
//! scalar channel plane per call, f64 arithmetic, f32 storage.
//!
//! The host runs the stages in order with ping-pong planes (stage outputs are
//! the next stage's inputs):
//!
//! | stage | spec §0.4 | reads | writes |
//! |---|---|---|---|
//! | 0 | steps 1–2 | value, variance (if `has_var`), spp | repaired value, clamped variance (0 without a variance layer) |
//! | 1 | step 3 | value, variance, spp | value copy, variance of `spp < 2` pixels replaced |
//! | 2 | step 4 | value, spp | value copy, estimated variance |
//!
//! Counters (`counters[c] +=`, atomics on the GPU): 0 = values repaired
//! (step 1), 1 = input variances negative or non-finite (step 2), 2 = pixels
//! handled by step 3, 3 = variances produced by the step-4 estimator (in
//! stage 2, and in stage 1 when no `spp >= 2` neighbour exists). Stage 0
//! counts every pixel of the image, valid or not.

use super::spp_of;
use crate::shared::SanitizePush;

/// Largest number of values a median is taken over (the 7×7 window of step 4);
/// `SAN_MAX` in `spirv/lib/sanitize.glsl`.
pub const SAN_MAX: usize = 49;

/// MAD → standard deviation factor for Gaussian noise (step 4).
pub const MAD_SCALE: f64 = 1.4826;

/// Median of `v` (sorted in place): the middle value, or the mean of the two
/// middle values for an even count. `v` must not be empty.
pub fn median(v: &mut [f64]) -> f64 {
    assert!(!v.is_empty(), "median of nothing");
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The step-4 variance estimator at pixel `(x, y)` (spec §0.4 step 4):
/// for every valid `q` of the 7×7 window (clipped) with at least one valid
/// neighbour in `3×3(q) \ {q}`, `e_q = b_q − mean(valid neighbours)`; then
/// `(8/9)(1.4826 · MAD(e))²` with `MAD(e) = median(|e − median(e)|)`, or 0 if
/// there is no `e`. Validity is `spp_of(spp) >= 1`; `value` must be finite on
/// valid pixels (stage 0 output). The caller handles an invalid centre.
pub fn mad_variance(
    value: &[f32],
    spp: &[f32],
    width: usize,
    height: usize,
    x: usize,
    y: usize,
) -> f64 {
    let valid = |qx: usize, qy: usize| spp_of(spp[qy * width + qx]) >= 1.0;
    let mut e = Vec::with_capacity(SAN_MAX);
    for qy in y.saturating_sub(3)..(y + 4).min(height) {
        for qx in x.saturating_sub(3)..(x + 4).min(width) {
            if !valid(qx, qy) {
                continue;
            }
            let (mut sum, mut count) = (0.0, 0usize);
            for ry in qy.saturating_sub(1)..(qy + 2).min(height) {
                for rx in qx.saturating_sub(1)..(qx + 2).min(width) {
                    if (rx, ry) != (qx, qy) && valid(rx, ry) {
                        sum += value[ry * width + rx] as f64;
                        count += 1;
                    }
                }
            }
            if count > 0 {
                e.push(value[qy * width + qx] as f64 - sum / count as f64);
            }
        }
    }
    if e.is_empty() {
        return 0.0;
    }
    let med = median(&mut e);
    for v in e.iter_mut() {
        *v = (*v - med).abs();
    }
    let s = MAD_SCALE * median(&mut e);
    8.0 / 9.0 * s * s
}

/// Runs one stage of the sanitation (spec §0.4) over the whole
/// `push.width × push.height` image (`push.row0` is ignored: the twin does
/// every band at once). `value_in`, `spp` and, when read, `var_in` are full
/// planes; `var_in` is not read in stage 0 when `push.has_var == 0`, nor in
/// stage 2 (it may then be empty). `has_var` is ignored by stages 1 and 2.
/// Outputs are full planes; `counters` is incremented, never reset.
///
/// * stage 0: a non-finite value becomes the median of the finite values of
///   the valid pixels of its 3×3 neighbourhood (centre excluded), or 0; its
///   variance the largest finite variance of the valid pixels of the 3×3
///   neighbourhood (centre included). Then a negative or non-finite variance
///   becomes 0. Without a variance layer the variance output is 0.
/// * stage 1: a valid pixel with `spp_of < 2` gets
///   `median_{q ∈ 5×5, spp_of(q) >= 2}(v_q n_q) / max(n_p, 1)`, or the
///   step-4 estimate if there is no such `q`.
/// * stage 2: every valid pixel gets the step-4 estimate ([`mad_variance`]),
///   every invalid one 0.
///
/// Panics on an unknown stage (a programming error).
pub fn sanitize(
    push: &SanitizePush,
    value_in: &[f32],
    var_in: &[f32],
    spp: &[f32],
    value_out: &mut [f32],
    var_out: &mut [f32],
    counters: &mut [u32; 4],
) {
    let (w, h) = (push.width as usize, push.height as usize);
    let valid = |qx: usize, qy: usize| spp_of(spp[qy * w + qx]) >= 1.0;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            match push.stage {
                0 => {
                    // §0.4 step 1
                    let b = value_in[i];
                    let repaired = !b.is_finite();
                    let mut value = b as f64;
                    if repaired {
                        let mut vals = Vec::with_capacity(8);
                        for qy in y.saturating_sub(1)..(y + 2).min(h) {
                            for qx in x.saturating_sub(1)..(x + 2).min(w) {
                                let q = qy * w + qx;
                                if (qx, qy) != (x, y) && valid(qx, qy) && value_in[q].is_finite() {
                                    vals.push(value_in[q] as f64);
                                }
                            }
                        }
                        value = if vals.is_empty() {
                            0.0
                        } else {
                            median(&mut vals)
                        };
                        counters[0] += u32::from(push.counts(x, y));
                    }
                    value_out[i] = value as f32;
                    // §0.4 steps 1 (variance of a repaired value) and 2
                    let mut var = 0.0;
                    if push.has_var != 0 {
                        let v = var_in[i];
                        if !v.is_finite() || v < 0.0 {
                            counters[1] += u32::from(push.counts(x, y));
                        }
                        var = v as f64;
                        if repaired {
                            let mut best = f64::NEG_INFINITY;
                            for qy in y.saturating_sub(1)..(y + 2).min(h) {
                                for qx in x.saturating_sub(1)..(x + 2).min(w) {
                                    let vq = var_in[qy * w + qx];
                                    if valid(qx, qy) && vq.is_finite() {
                                        best = best.max(vq as f64);
                                    }
                                }
                            }
                            var = best;
                        }
                        if !var.is_finite() || var < 0.0 {
                            var = 0.0;
                        }
                    }
                    var_out[i] = var as f32;
                }
                1 => {
                    // §0.4 step 3
                    value_out[i] = value_in[i];
                    let np = spp_of(spp[i]);
                    if (1.0..2.0).contains(&np) {
                        let mut vals = Vec::with_capacity(24);
                        for qy in y.saturating_sub(2)..(y + 3).min(h) {
                            for qx in x.saturating_sub(2)..(x + 3).min(w) {
                                let q = qy * w + qx;
                                let nq = spp_of(spp[q]);
                                if nq >= 2.0 {
                                    vals.push(var_in[q] as f64 * nq);
                                }
                            }
                        }
                        var_out[i] = if vals.is_empty() {
                            counters[3] += u32::from(push.counts(x, y));
                            mad_variance(value_in, spp, w, h, x, y) as f32
                        } else {
                            (median(&mut vals) / np.max(1.0)) as f32
                        };
                        counters[2] += u32::from(push.counts(x, y));
                    } else {
                        var_out[i] = var_in[i];
                    }
                }
                2 => {
                    // §0.4 step 4
                    value_out[i] = value_in[i];
                    var_out[i] = if valid(x, y) {
                        counters[3] += u32::from(push.counts(x, y));
                        mad_variance(value_in, spp, w, h, x, y) as f32
                    } else {
                        0.0
                    };
                }
                s => panic!("sanitize: unknown stage {s}"),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn push(w: usize, h: usize, stage: u32, has_var: u32) -> SanitizePush {
        SanitizePush {
            width: w as u32,
            height: h as u32,
            stage,
            has_var,
            ..Default::default()
        }
    }

    struct Out {
        value: Vec<f32>,
        var: Vec<f32>,
        counters: [u32; 4],
    }

    fn run(p: &SanitizePush, value: &[f32], var: &[f32], spp: &[f32]) -> Out {
        let n = value.len();
        let mut o = Out {
            value: vec![-1.0; n],
            var: vec![-1.0; n],
            counters: [0; 4],
        };
        sanitize(
            p,
            value,
            var,
            spp,
            &mut o.value,
            &mut o.var,
            &mut o.counters,
        );
        o
    }

    /// xorshift64* uniforms and Box–Muller normals.
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    #[test]
    fn median_odd_even() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut [7.0]), 7.0);
    }

    #[test]
    fn nan_is_replaced_by_neighbour_median() {
        // 3x3 image, centre NaN; one neighbour invalid (its huge value must
        // be ignored), one neighbour infinite.
        let value = [1.0, 2.0, 3.0, 4.0, f32::NAN, 1e6, 5.0, f32::INFINITY, 6.0];
        let spp = [4.0, 4.0, 4.0, 4.0, 4.0, 0.0, 4.0, 4.0, 4.0];
        let o = run(&push(3, 3, 0, 0), &value, &[], &spp);
        // centre: finite valid neighbours {1,2,3,4,5,6} → (3+4)/2
        assert_eq!(o.value[4], 3.5);
        // (1,2) is infinite: valid finite neighbours {4, 5, 6} (the NaN centre is skipped)
        assert_eq!(o.value[7], 5.0);
        assert_eq!(o.value[0], 1.0);
        assert_eq!(o.value[5], 1e6, "finite values are kept, valid or not");
        assert_eq!(o.counters, [2, 0, 0, 0]);
        assert!(o.var.iter().all(|&v| v == 0.0), "no variance layer → 0");
    }

    #[test]
    fn repaired_value_takes_largest_neighbour_variance() {
        let value = [1.0, 1.0, 1.0, 1.0, f32::NAN, 1.0, 1.0, 1.0, 1.0];
        let var = [0.1, 0.5, f32::NAN, 0.2, 0.3, 9.0, 0.4, 0.7, -1.0];
        let spp = [4.0, 4.0, 4.0, 4.0, 4.0, 0.0, 4.0, 4.0, 4.0];
        let o = run(&push(3, 3, 0, 1), &value, &var, &spp);
        assert_eq!(o.value[4], 1.0);
        // largest finite variance over valid pixels (9.0 belongs to an invalid one)
        assert_eq!(o.var[4], 0.7);
        assert_eq!(o.var[2], 0.0, "NaN variance → 0");
        assert_eq!(o.var[8], 0.0, "negative variance → 0");
        assert_eq!(o.var[1], 0.5);
        assert_eq!(o.counters, [1, 2, 0, 0]);

        // All neighbours invalid: value 0, variance from the centre alone.
        let spp1 = [0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0];
        let o = run(&push(3, 3, 0, 1), &value, &var, &spp1);
        assert_eq!(o.value[4], 0.0);
        assert_eq!(o.var[4], 0.3);
        // and with a non-finite centre variance too: 0
        let mut var2 = var;
        var2[4] = f32::INFINITY;
        let o = run(&push(3, 3, 0, 1), &value, &var2, &spp1);
        assert_eq!((o.value[4], o.var[4]), (0.0, 0.0));
    }

    #[test]
    fn low_spp_gets_neighbours_per_sample_variance() {
        // 5x5, all spp 4 with variance of the mean 0.5 (per-sample variance 2),
        // except centre spp 1 (variance undefined) and (0,0) spp 1.5.
        let (w, h) = (5, 5);
        let value = vec![0.0f32; w * h];
        let mut var = vec![0.5f32; w * h];
        let mut spp = vec![4.0f32; w * h];
        spp[12] = 1.0;
        var[12] = 0.0;
        spp[0] = 1.5;
        var[0] = 0.0;
        spp[24] = 0.0; // invalid: untouched
        var[24] = 0.25;
        let o = run(&push(w, h, 1, 1), &value, &var, &spp);
        assert_eq!(o.var[12], 2.0);
        assert!((o.var[0] - (2.0 / 1.5) as f32).abs() < 1e-7);
        assert_eq!(o.var[24], 0.25);
        assert_eq!(o.var[6], 0.5);
        assert_eq!(o.value, value);
        assert_eq!(o.counters, [0, 0, 2, 0]);

        // The median is over v_q n_q, not v_q: mixed counts.
        let mut spp2 = vec![1.0f32; w * h];
        let mut var2 = vec![0.0f32; w * h];
        for (q, n) in [(0usize, 2.0f32), (1, 4.0), (2, 8.0)] {
            spp2[q] = n;
            var2[q] = 1.0 / n; // per-sample variance 1 everywhere
        }
        spp2[3] = 16.0;
        var2[3] = 10.0 / 16.0;
        let o = run(&push(w, h, 1, 1), &value, &var2, &spp2);
        // centre: {1, 1, 1, 10} → 1
        assert_eq!(o.var[12], 1.0);
    }

    #[test]
    fn low_spp_without_neighbours_falls_back_to_step4() {
        // Everything spp 1: no q with n >= 2, so stage 1 equals stage 2.
        let (w, h) = (9, 8);
        let mut rng = Rng(17);
        let value: Vec<f32> = (0..w * h).map(|_| rng.normal() as f32).collect();
        let spp = vec![1.0f32; w * h];
        let var = vec![0.0f32; w * h];
        let s1 = run(&push(w, h, 1, 1), &value, &var, &spp);
        let s2 = run(&push(w, h, 2, 0), &value, &var, &spp);
        assert_eq!(s1.var, s2.var);
        assert_eq!(s1.counters, [0, 0, (w * h) as u32, (w * h) as u32]);
        assert_eq!(s2.counters, [0, 0, 0, (w * h) as u32]);
        assert!(s2.var.iter().all(|&v| v > 0.0));
    }

    #[test]
    fn missing_variance_recovers_gaussian_noise_level() {
        let (w, h) = (64, 64);
        let sigma = 0.3f64;
        let mut rng = Rng(0x1234_5678_9ABC_DEF0);
        let value: Vec<f32> = (0..w * h)
            .map(|_| (0.5 + sigma * rng.normal()) as f32)
            .collect();
        let spp = vec![16.0f32; w * h];
        let o = run(&push(w, h, 2, 0), &value, &[], &spp);
        let mean: f64 = o.var.iter().map(|&v| v as f64).sum::<f64>() / (w * h) as f64;
        let want = sigma * sigma;
        assert!(
            (mean - want).abs() < 0.1 * want,
            "estimated {mean}, want {want}"
        );
        let mut sorted: Vec<f64> = o.var.iter().map(|&v| v as f64).collect();
        let med = median(&mut sorted);
        assert!(
            (med - want).abs() < 0.1 * want,
            "median estimate {med}, want {want}"
        );
        assert_eq!(o.value, value);
    }

    #[test]
    fn step4_invalid_and_isolated_pixels_get_zero() {
        // 5x5 with a single valid pixel: it has no valid neighbour → no e → 0.
        let (w, h) = (5, 5);
        let value = vec![3.0f32; w * h];
        let mut spp = vec![0.0f32; w * h];
        spp[12] = 4.0;
        let o = run(&push(w, h, 2, 0), &value, &[], &spp);
        assert!(o.var.iter().all(|&v| v == 0.0));
        assert_eq!(o.counters, [0, 0, 0, 1]);
        // a constant image estimates 0 everywhere
        let spp = vec![4.0f32; w * h];
        let o = run(&push(w, h, 2, 0), &value, &[], &spp);
        assert!(o.var.iter().all(|&v| v == 0.0));
    }
}
