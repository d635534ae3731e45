//! Image-quality metrics of a result `x` against a reference `r`.
//!
//! All metrics average over every pixel and the three channels and accumulate
//! in f64. The error metrics use the raw linear values; PSNR and SSIM use
//! tone-mapped values [`tonemap`]`(v) = max(v, 0) / (1 + max(v, 0))`, which
//! lie in [0, 1) so the peak / dynamic range is 1.
//!
//! | metric | per-value term | best |
//! |---|---|---|
//! | [`rmse`] | `(x − r)² / (r² + 0.01)` | 0 |
//! | [`relmse`] | `(x − r)² / (r² + 0.001)` | 0 |
//! | [`psnr`] | `10 log10(1 / mean((t(x) − t(r))²))` | +∞ |
//! | [`ssim`] | SSIM map of `t(x)`, `t(r)` | 1 |
//!
//! **Non-finite results.** A NaN or ±Inf value in `x` is the worst possible
//! error: its rMSE/relMSE term is +∞, so `rmse` and `relmse` are +∞, `psnr`
//! is −∞ and `ssim` is −∞. A broken output can therefore never pass a
//! threshold or look better than a finite one. The reference must be finite:
//! [`compare`] rejects one that is not (the bare functions then return NaN
//! or garbage).
//!
//! The bare functions panic if the two images differ in size (a programming
//! error); [`compare`], [`rmse_heatmap`], [`temporal_heatmap`] and [`check_same_size`] return an
//! error instead and are the entry points for user-supplied images.

use crate::error::{Error, Result};
use crate::image::RgbImage;

/// The `ε` of rMSE: `(x − r)² / (r² + RMSE_EPS)`.
pub const RMSE_EPS: f64 = 0.01;
/// The `ε` of relMSE: `(x − r)² / (r² + RELMSE_EPS)`.
pub const RELMSE_EPS: f64 = 0.001;

/// SSIM window: 11 x 11 Gaussian, σ = 1.5 (Wang et al. 2004).
const SSIM_RADIUS: usize = 5;
const SSIM_SIGMA: f64 = 1.5;
/// SSIM stabilisers for a dynamic range L = 1: C1 = (0.01 L)², C2 = (0.03 L)².
const SSIM_C1: f64 = 0.01 * 0.01;
const SSIM_C2: f64 = 0.03 * 0.03;

/// All metrics of one comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Mean of `(x − r)² / (r² + 0.01)`; lower is better.
    pub rmse: f64,
    /// Mean of `(x − r)² / (r² + 0.001)`; lower is better.
    pub relmse: f64,
    /// PSNR in dB of the tone-mapped images, peak 1; +∞ if identical.
    pub psnr: f64,
    /// Mean SSIM of the tone-mapped images, in [−1, 1]; 1 if identical.
    pub ssim: f64,
}

/// The preview tone curve the PSNR and SSIM work on: `max(v, 0) / (1 + max(v, 0))`
/// (negative and NaN → 0; +∞ → 1). The metrics themselves never pass a
/// non-finite `x` through this (see the module docs).
pub fn tonemap(v: f32) -> f64 {
    let v = v as f64;
    if v.is_nan() || v <= 0.0 {
        0.0
    } else if v.is_infinite() {
        1.0
    } else {
        v / (1.0 + v)
    }
}

/// `Ok` if `x` and `r` have the same size, else [`Error::InvalidArgument`]
/// saying both sizes.
pub fn check_same_size(x: &RgbImage, r: &RgbImage) -> Result<()> {
    if (x.width, x.height) != (r.width, r.height) {
        return Err(Error::InvalidArgument(format!(
            "the image is {}x{} but the reference is {}x{}",
            x.width, x.height, r.width, r.height
        )));
    }
    Ok(())
}

/// All four metrics of `x` against the reference `r`.
///
/// # Errors
/// [`Error::InvalidArgument`] if the sizes differ or the images are empty;
/// [`Error::BadData`] if the reference holds a non-finite value (naming the
/// first such pixel). Non-finite values in `x` are not an error: they make the
/// metrics as bad as possible (module docs).
pub fn compare(x: &RgbImage, r: &RgbImage) -> Result<Metrics> {
    check_same_size(x, r)?;
    if r.width * r.height == 0 {
        return Err(Error::InvalidArgument("cannot compare empty images".into()));
    }
    for (c, plane) in r.planes.iter().enumerate() {
        if let Some(i) = plane.iter().position(|v| !v.is_finite()) {
            return Err(Error::BadData(format!(
                "the reference has a non-finite value ({}) in channel {} at pixel ({}, {})",
                plane[i],
                ["R", "G", "B"][c],
                i % r.width,
                i / r.width
            )));
        }
    }
    Ok(Metrics {
        rmse: rmse(x, r),
        relmse: relmse(x, r),
        psnr: psnr(x, r),
        ssim: ssim(x, r),
    })
}

/// Mean over pixels and channels of `(x − r)² / (r² + eps)`; +∞ if any `x`
/// is non-finite.
fn relative_mse(x: &RgbImage, r: &RgbImage, eps: f64) -> f64 {
    assert_same_size(x, r);
    let mut sum = 0.0f64;
    for (xp, rp) in x.planes.iter().zip(&r.planes) {
        for (&xv, &rv) in xp.iter().zip(rp) {
            if !xv.is_finite() {
                return f64::INFINITY;
            }
            let (xv, rv) = (xv as f64, rv as f64);
            sum += (xv - rv) * (xv - rv) / (rv * rv + eps);
        }
    }
    sum / (3 * x.width * x.height) as f64
}

/// rMSE: mean over pixels and channels of `(x − r)² / (r² + 0.01)`, in f64.
/// +∞ if `x` holds a non-finite value; NaN for empty images.
///
/// # Panics
/// If the sizes differ (use [`compare`] for user input).
pub fn rmse(x: &RgbImage, r: &RgbImage) -> f64 {
    relative_mse(x, r, RMSE_EPS)
}

/// relMSE: mean over pixels and channels of `(x − r)² / (r² + 0.001)`, in f64.
/// +∞ if `x` holds a non-finite value; NaN for empty images.
///
/// # Panics
/// If the sizes differ (use [`compare`] for user input).
pub fn relmse(x: &RgbImage, r: &RgbImage) -> f64 {
    relative_mse(x, r, RELMSE_EPS)
}

/// PSNR (dB) of the tone-mapped images with peak 1: `10 log10(1 / MSE)`.
/// +∞ if the tone-mapped images are identical; −∞ if `x` holds a non-finite
/// value.
///
/// # Panics
/// If the sizes differ (use [`compare`] for user input).
pub fn psnr(x: &RgbImage, r: &RgbImage) -> f64 {
    assert_same_size(x, r);
    let mut sum = 0.0f64;
    for (xp, rp) in x.planes.iter().zip(&r.planes) {
        for (&xv, &rv) in xp.iter().zip(rp) {
            if !xv.is_finite() {
                return f64::NEG_INFINITY;
            }
            let d = tonemap(xv) - tonemap(rv);
            sum += d * d;
        }
    }
    let mse = sum / (3 * x.width * x.height) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    }
}

/// Mean SSIM of the tone-mapped images, averaged over the three channels.
///
/// Standard SSIM (Wang et al. 2004): 11 x 11 Gaussian window with σ = 1.5,
/// K1 = 0.01, K2 = 0.03, L = 1, weighted (biased) local moments, the SSIM map
/// averaged over every pixel. **Border:** the map has a value at every pixel;
/// near the border the window is cut to the part inside the image and its
/// weights are renormalised to sum to 1 (no padding, no cropping of the map).
/// −∞ if `x` holds a non-finite value.
///
/// # Panics
/// If the sizes differ (use [`compare`] for user input).
pub fn ssim(x: &RgbImage, r: &RgbImage) -> f64 {
    assert_same_size(x, r);
    if x.planes.iter().flatten().any(|v| !v.is_finite()) {
        return f64::NEG_INFINITY;
    }
    let (w, h) = (x.width, x.height);
    let total: f64 = x
        .planes
        .iter()
        .zip(&r.planes)
        .map(|(xp, rp)| {
            let a: Vec<f64> = xp.iter().map(|v| tonemap(*v)).collect();
            let b: Vec<f64> = rp.iter().map(|v| tonemap(*v)).collect();
            ssim_plane(w, h, &a, &b)
        })
        .sum();
    total / 3.0
}

/// Mean SSIM of two single-channel planes of `w * h` values in [0, 1]
/// (already tone-mapped), with the window and border handling of [`ssim`].
///
/// # Panics
/// If a plane's length is not `w * h`.
pub fn ssim_plane(w: usize, h: usize, a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), w * h, "ssim_plane: first plane size");
    assert_eq!(b.len(), w * h, "ssim_plane: second plane size");
    if w * h == 0 {
        return f64::NAN;
    }
    let kernel: Vec<f64> = (0..=2 * SSIM_RADIUS)
        .map(|k| {
            let d = k as f64 - SSIM_RADIUS as f64;
            (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()
        })
        .collect();
    // The truncated 2D window is the product of the truncated 1D windows, so
    // two normalised 1D passes give exactly the renormalised 2D weights.
    let blur = |f: &dyn Fn(usize) -> f64| -> Vec<f64> {
        let src: Vec<f64> = (0..w * h).map(f).collect();
        let horizontal = blur_1d(&src, w, h, &kernel, 1, w);
        blur_1d(&horizontal, w, h, &kernel, w, h)
    };
    let mu_a = blur(&|i| a[i]);
    let mu_b = blur(&|i| b[i]);
    let e_aa = blur(&|i| a[i] * a[i]);
    let e_bb = blur(&|i| b[i] * b[i]);
    let e_ab = blur(&|i| a[i] * b[i]);
    let mut sum = 0.0;
    for i in 0..w * h {
        let (ma, mb) = (mu_a[i], mu_b[i]);
        let var_a = e_aa[i] - ma * ma;
        let var_b = e_bb[i] - mb * mb;
        let cov = e_ab[i] - ma * mb;
        sum += ((2.0 * ma * mb + SSIM_C1) * (2.0 * cov + SSIM_C2))
            / ((ma * ma + mb * mb + SSIM_C1) * (var_a + var_b + SSIM_C2));
    }
    sum / (w * h) as f64
}

/// One normalised, border-truncated 1D convolution of a `w x h` plane along
/// the axis whose step is `stride` and whose length is `len`.
fn blur_1d(src: &[f64], w: usize, h: usize, kernel: &[f64], stride: usize, len: usize) -> Vec<f64> {
    let radius = kernel.len() / 2;
    let mut out = vec![0.0; w * h];
    for (i, o) in out.iter_mut().enumerate() {
        // Position along the blurred axis.
        let pos = if stride == 1 { i % w } else { i / w };
        let lo = pos.saturating_sub(radius);
        let hi = (pos + radius).min(len - 1);
        let (mut acc, mut norm) = (0.0, 0.0);
        for q in lo..=hi {
            let k = kernel[q + radius - pos];
            let j = if stride == 1 {
                i - pos + q
            } else {
                q * w + i % w
            };
            acc += k * src[j];
            norm += k;
        }
        *o = acc / norm;
    }
    out
}

/// Per-pixel rMSE: the mean over the three channels of
/// `(x − r)² / (r² + 0.01)`, as `width * height` f32 values (+∞ where `x` is
/// non-finite). Its mean is [`rmse`].
///
/// # Errors
/// [`Error::InvalidArgument`] if the sizes differ.
pub fn rmse_heatmap(x: &RgbImage, r: &RgbImage) -> Result<Vec<f32>> {
    check_same_size(x, r)?;
    let n = x.width * x.height;
    let mut out = vec![0.0f32; n];
    for (i, o) in out.iter_mut().enumerate() {
        let mut sum = 0.0f64;
        for c in 0..3 {
            let (xv, rv) = (x.planes[c][i], r.planes[c][i]);
            if !xv.is_finite() {
                sum = f64::INFINITY;
                break;
            }
            let (xv, rv) = (xv as f64, rv as f64);
            sum += (xv - rv) * (xv - rv) / (rv * rv + RMSE_EPS);
        }
        *o = (sum / 3.0) as f32;
    }
    Ok(out)
}

fn assert_same_size(x: &RgbImage, r: &RgbImage) {
    assert!(
        (x.width, x.height) == (r.width, r.height),
        "metrics: image {}x{} vs reference {}x{} (use metrics::compare for user input)",
        x.width,
        x.height,
        r.width,
        r.height
    );
}

/// The rMSE a reconstruction estimates for itself: the mean over pixels and
/// channels of `E_i[ch] / (f̂_i[ch]² + 0.01)`, its per-pixel error estimate
/// relative to its own value (what [`rmse`] measures against a reference,
/// with the output standing in for the reference). Non-finite terms are
/// skipped; NaN when `error` is empty or of another size than `color`.
pub fn estimated_rmse(color: &RgbImage, error: &RgbImage) -> f64 {
    if (error.width, error.height) != (color.width, color.height) || color.width * color.height == 0
    {
        return f64::NAN;
    }
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (f, e) in color.planes.iter().zip(&error.planes) {
        for (&f, &e) in f.iter().zip(e) {
            let t = e.max(0.0) as f64 / ((f as f64) * (f as f64) + RMSE_EPS);
            if t.is_finite() {
                sum += t;
                n += 1;
            }
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}

/// One pixel and channel's term of [`temporal_error`]: the output's change
/// `o1 − o0` between two frames less the reference's `r1 − r0`, squared,
/// over `r1² + 0.01`.
fn temporal_term(o1: f32, o0: f32, r1: f32, r0: f32) -> f64 {
    let d = (o1 as f64 - o0 as f64) - (r1 as f64 - r0 as f64);
    d * d / ((r1 as f64).powi(2) + RMSE_EPS)
}

/// Per pixel, [`temporal_error`]'s term between two consecutive frames
/// (`o0`, `r0` the earlier output and reference), averaged over the
/// channels: where a sequence flickers (+∞ where an output is not finite).
///
/// # Errors
/// [`Error::InvalidArgument`] if the sizes differ.
pub fn temporal_heatmap(
    o1: &RgbImage,
    o0: &RgbImage,
    r1: &RgbImage,
    r0: &RgbImage,
) -> Result<Vec<f32>> {
    for x in [o0, r1, r0] {
        check_same_size(o1, x)?;
    }
    Ok((0..o1.width * o1.height)
        .map(|i| {
            let mut sum = 0.0f64;
            for c in 0..3 {
                let (a, b) = (o1.planes[c][i], o0.planes[c][i]);
                if !a.is_finite() || !b.is_finite() {
                    return f32::INFINITY;
                }
                sum += temporal_term(a, b, r1.planes[c][i], r0.planes[c][i]);
            }
            (sum / 3.0) as f32
        })
        .collect())
}

/// Temporal error of a sequence `out` against its references `refs` (frame
/// by frame, the same sizes): the mean over frames `t ≥ 1`, pixels and
/// channels of `((o_t − o_{t−1}) − (r_t − r_{t−1}))² / (r_t² + 0.01)` —
/// flicker is a change between frames the reference does not have. `None`
/// for fewer than two frames; +∞ if an output holds a non-finite value.
pub fn temporal_error(out: &[&RgbImage], refs: &[&RgbImage]) -> Result<Option<f64>> {
    if out.len() != refs.len() {
        return Err(Error::InvalidArgument(format!(
            "temporal error: {} frames against {} references",
            out.len(),
            refs.len()
        )));
    }
    for (o, r) in out.iter().zip(refs) {
        check_same_size(o, r)?;
        check_same_size(o, out[0])?;
    }
    if out.len() < 2 {
        return Ok(None);
    }
    let (mut sum, mut count) = (0.0f64, 0usize);
    for t in 1..out.len() {
        for c in 0..3 {
            let (o1, o0) = (&out[t].planes[c], &out[t - 1].planes[c]);
            let (r1, r0) = (&refs[t].planes[c], &refs[t - 1].planes[c]);
            for i in 0..o1.len() {
                if !o1[i].is_finite() || !o0[i].is_finite() {
                    return Ok(Some(f64::INFINITY));
                }
                sum += temporal_term(o1[i], o0[i], r1[i], r0[i]);
                count += 1;
            }
        }
    }
    Ok(Some(sum / count.max(1) as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, f: impl Fn(usize, usize) -> f32) -> RgbImage {
        let planes = std::array::from_fn(|c| (0..w * h).map(|i| f(i, c)).collect());
        RgbImage::from_planes(w, h, planes)
    }

    fn textured(w: usize, h: usize) -> RgbImage {
        image(w, h, |i, c| {
            let (x, y) = (i % w, i / w);
            ((x * 7 + y * 13 + c * 5) % 17) as f32 * 0.3
                + if (x / 4 + y / 4) % 2 == 0 { 2.0 } else { 0.1 }
        })
    }

    #[test]
    fn identical_images_are_perfect() {
        let x = textured(23, 17);
        let m = compare(&x, &x).unwrap();
        assert_eq!(m.rmse, 0.0);
        assert_eq!(m.relmse, 0.0);
        assert_eq!(m.psnr, f64::INFINITY);
        assert!((m.ssim - 1.0).abs() < 1e-12, "ssim(x, x) = {}", m.ssim);
    }

    #[test]
    fn rmse_of_a_tiny_case() {
        // One pixel: x = (1, 2, 0), r = (0, 1, 0.1).
        let x = RgbImage::from_planes(1, 1, [vec![1.0], vec![2.0], vec![0.0]]);
        let r = RgbImage::from_planes(1, 1, [vec![0.0], vec![1.0], vec![0.1]]);
        let expected_rmse = (1.0 / 0.01 + 1.0 / 1.01 + 0.01 / 0.02) / 3.0;
        let expected_relmse = (1.0 / 0.001 + 1.0 / 1.001 + 0.01 / 0.011) / 3.0;
        assert!((rmse(&x, &r) - expected_rmse).abs() < 1e-6 * expected_rmse);
        assert!((relmse(&x, &r) - expected_relmse).abs() < 1e-6 * expected_relmse);
        let heat = rmse_heatmap(&x, &r).unwrap();
        assert!((heat[0] as f64 - expected_rmse).abs() < 1e-4 * expected_rmse);
    }

    #[test]
    fn psnr_of_a_known_offset() {
        // Tone-mapped values 0.5 vs 0.25 everywhere: MSE = 1/16, PSNR = 10 log10(16).
        let x = image(4, 3, |_, _| 1.0);
        let r = image(4, 3, |_, _| 1.0 / 3.0);
        assert!((psnr(&x, &r) - 10.0 * 16f64.log10()).abs() < 1e-6);
    }

    #[test]
    fn ssim_drops_with_noise_and_stays_in_range() {
        let r = textured(32, 32);
        let x = image(32, 32, |i, c| {
            r.planes[c][i] * if (i * 31 + c) % 3 == 0 { 1.5 } else { 0.7 }
        });
        let s = ssim(&x, &r);
        assert!(s < 0.99 && s > -1.0, "ssim = {s}");
        // Symmetric in its arguments.
        assert!((s - ssim(&r, &x)).abs() < 1e-12);
    }

    #[test]
    fn ssim_on_tiny_images_uses_the_truncated_window() {
        let x = image(1, 1, |_, _| 0.5);
        assert!((ssim(&x, &x) - 1.0).abs() < 1e-12);
        let y = image(3, 1, |i, _| i as f32);
        assert!((ssim(&y, &y) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn non_finite_output_is_worst() {
        let r = textured(8, 8);
        let mut x = r.clone();
        x.planes[1][10] = f32::NAN;
        let m = compare(&x, &r).unwrap();
        assert_eq!(m.rmse, f64::INFINITY);
        assert_eq!(m.relmse, f64::INFINITY);
        assert_eq!(m.psnr, f64::NEG_INFINITY);
        assert_eq!(m.ssim, f64::NEG_INFINITY);
        assert_eq!(rmse_heatmap(&x, &r).unwrap()[10], f32::INFINITY);
        x.planes[1][10] = f32::INFINITY;
        assert_eq!(rmse(&x, &r), f64::INFINITY);
    }

    #[test]
    fn compare_rejects_bad_inputs() {
        let a = textured(8, 8);
        let b = textured(8, 9);
        let e = compare(&a, &b).unwrap_err().to_string();
        assert!(e.contains("8x8") && e.contains("8x9"), "{e}");
        assert!(rmse_heatmap(&a, &b).is_err());
        let mut r = a.clone();
        r.planes[2][9] = f32::NAN;
        let e = compare(&a, &r).unwrap_err().to_string();
        assert!(e.contains("(1, 1)"), "{e}");
    }

    #[test]
    fn temporal_error_sees_flicker_not_a_steady_bias() {
        let img = |v: f32| RgbImage::from_planes(2, 1, [vec![v; 2], vec![v; 2], vec![v; 2]]);
        let refs = [img(1.0), img(2.0), img(3.0)];
        let r: Vec<&RgbImage> = refs.iter().collect();
        // A steady bias of +0.5 follows the reference's changes: no flicker.
        let biased = [img(1.5), img(2.5), img(3.5)];
        let o: Vec<&RgbImage> = biased.iter().collect();
        assert_eq!(temporal_error(&o, &r).unwrap(), Some(0.0));
        // ±0.1 alternating: differences of 0.2 the reference lacks.
        let flicker = [img(1.1), img(1.9), img(3.1)];
        let o: Vec<&RgbImage> = flicker.iter().collect();
        let want = 0.5 * (0.2f64.powi(2) / 4.01 + 0.2f64.powi(2) / 9.01);
        let got = temporal_error(&o, &r).unwrap().unwrap();
        assert!((got - want).abs() < 1e-6 * want, "{got} {want}");
        assert_eq!(temporal_error(&o[..1], &r[..1]).unwrap(), None);
        assert!(temporal_error(&o[..2], &r).is_err());
    }

    #[test]
    fn temporal_heatmap_is_the_error_per_pixel() {
        let img =
            |a: f32, b: f32| RgbImage::from_planes(2, 1, [vec![a, b], vec![a, b], vec![a, b]]);
        let (r0, r1) = (img(1.0, 1.0), img(2.0, 1.0));
        // The first pixel follows the reference; the second jumps by 0.3.
        let (o0, o1) = (img(1.0, 1.0), img(2.0, 1.3));
        let map = temporal_heatmap(&o1, &o0, &r1, &r0).unwrap();
        assert_eq!(map[0], 0.0);
        assert!((map[1] as f64 - 0.09 / 1.01).abs() < 1e-6, "{map:?}");
        let mean = (map[0] + map[1]) as f64 / 2.0;
        let got = temporal_error(&[&o0, &o1], &[&r0, &r1]).unwrap().unwrap();
        assert!((got - mean).abs() < 1e-6 * got, "{got} {mean}");
        let nan = img(f32::NAN, 1.0);
        assert_eq!(
            temporal_heatmap(&nan, &o0, &r1, &r0).unwrap()[0],
            f32::INFINITY
        );
        assert!(temporal_heatmap(&o1, &RgbImage::new(1, 1), &r1, &r0).is_err());
    }
}
