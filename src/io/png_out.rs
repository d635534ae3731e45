//! 8-bit PNG previews: a tone-mapped colour preview and a heat map for
//! per-pixel error. Both are written atomically.

use std::path::Path;

use crate::error::{Error, Result};
use crate::image::RgbImage;

use super::{write_atomic, write_error};

/// The preview tone curve and encoding of one linear value, as an 8-bit sRGB
/// code: `t = v / (1 + v)` (Reinhard; negative and NaN → 0, +Inf → 1), then
/// the sRGB OETF, then rounding to 0..=255.
pub fn srgb_preview_u8(v: f32) -> u8 {
    let v = if v.is_nan() || v <= 0.0 {
        0.0
    } else {
        v as f64
    };
    let t = if v.is_infinite() { 1.0 } else { v / (1.0 + v) };
    let s = if t <= 0.003_130_8 {
        12.92 * t
    } else {
        1.055 * t.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

/// Writes a tone-mapped preview of a linear HDR image as an 8-bit RGB PNG
/// (per channel [`srgb_preview_u8`], sRGB chunk set). Atomic.
///
/// # Errors
/// [`Error::InvalidArgument`] for an empty image or one larger than PNG
/// allows; [`Error::Io`] naming `path` if writing fails.
pub fn write_png_preview(path: &Path, img: &RgbImage) -> Result<()> {
    let n = img.width * img.height;
    if img.planes.iter().any(|p| p.len() != n) {
        return Err(Error::InvalidArgument(format!(
            "{}: image planes do not match its {}x{} size",
            path.display(),
            img.width,
            img.height
        )));
    }
    let mut data = Vec::with_capacity(n * 3);
    for i in 0..n {
        for plane in &img.planes {
            data.push(srgb_preview_u8(plane[i]));
        }
    }
    write_rgb8_png(path, img.width, img.height, &data)
}

/// The heat-map colour of `t` in [0, 1] (clamped; NaN → 1): a ramp through
/// black, blue, magenta, orange, yellow and white, monotone in lightness so
/// that it reads correctly in grey too.
pub fn heat_color(t: f32) -> [u8; 3] {
    const STOPS: [(f32, [f32; 3]); 6] = [
        (0.0, [0.0, 0.0, 0.0]),
        (0.2, [20.0, 20.0, 160.0]),
        (0.45, [170.0, 30.0, 170.0]),
        (0.7, [250.0, 120.0, 30.0]),
        (0.9, [255.0, 230.0, 40.0]),
        (1.0, [255.0, 255.0, 255.0]),
    ];
    let t = if t.is_nan() { 1.0 } else { t.clamp(0.0, 1.0) };
    for pair in STOPS.windows(2) {
        let ((t0, c0), (t1, c1)) = (pair[0], pair[1]);
        if t <= t1 {
            let f = (t - t0) / (t1 - t0);
            return std::array::from_fn(|k| (c0[k] + f * (c1[k] - c0[k]) + 0.5) as u8);
        }
    }
    [255, 255, 255]
}

/// Writes a scalar plane (`width * height` values, row-major) as an 8-bit RGB
/// heat map PNG: value `v` maps to [`heat_color`]`(v / max)`, so 0 is black
/// and `max` and above are white. If `max` is not a positive finite number,
/// the largest finite value of the plane is used instead (all-zero planes are
/// black). Negative values map to black; NaN and +Inf map to white, so broken
/// pixels stand out. Atomic.
///
/// # Errors
/// [`Error::InvalidArgument`] if `values.len() != width * height` or the image
/// is empty; [`Error::Io`] naming `path` if writing fails.
pub fn write_heatmap_png(
    path: &Path,
    width: usize,
    height: usize,
    values: &[f32],
    max: f32,
) -> Result<()> {
    if values.len() != width * height {
        return Err(Error::InvalidArgument(format!(
            "{}: heat map has {} values, expected {width}x{height}",
            path.display(),
            values.len()
        )));
    }
    let scale = if max.is_finite() && max > 0.0 {
        max
    } else {
        values
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0f32, f32::max)
    };
    let mut data = Vec::with_capacity(values.len() * 3);
    for &v in values {
        let t = if v.is_nan() || v == f32::INFINITY {
            1.0
        } else if scale > 0.0 {
            v / scale
        } else {
            0.0
        };
        data.extend_from_slice(&heat_color(t));
    }
    write_rgb8_png(path, width, height, &data)
}

fn write_rgb8_png(path: &Path, width: usize, height: usize, data: &[u8]) -> Result<()> {
    let (w, h) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => (w, h),
        _ => {
            return Err(Error::InvalidArgument(format!(
                "{}: cannot write a {width}x{height} PNG",
                path.display()
            )))
        }
    };
    write_atomic(path, |writer| {
        let mut encoder = png::Encoder::new(writer, w, h);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let png_err = |e: png::EncodingError| match e {
            // The OS's error as it is (a full disk, an I/O error).
            png::EncodingError::IoError(source) => Error::Io {
                path: path.to_path_buf(),
                source,
            },
            e => write_error(path, "PNG encoding failed", e),
        };
        let mut png = encoder.write_header().map_err(png_err)?;
        png.write_image_data(data).map_err(png_err)?;
        png.finish().map_err(png_err)
    })
}

/// One panel of a [`write_panels`] strip.
#[derive(Clone, Copy, Debug)]
pub enum Panel<'a> {
    /// A linear HDR image, tone-mapped as [`write_png_preview`] does.
    Colour(&'a RgbImage),
    /// A scalar plane as [`write_heatmap_png`] draws it, scaled to `max`.
    Heat(&'a [f32], f32),
}

/// Grey between the panels of a strip.
const GAP_GREY: u8 = 40;

/// Writes `panels` (each `width × height`) side by side, `gap` grey pixels
/// apart, as one 8-bit RGB PNG: a figure of a render's input, sample map,
/// reconstruction, error estimate and reference. Atomic.
///
/// # Errors
/// [`Error::InvalidArgument`] when there are no panels or a panel is not
/// `width × height`; [`Error::Io`] naming `path` if writing fails.
pub fn write_panels(
    path: &Path,
    width: usize,
    height: usize,
    panels: &[Panel],
    gap: usize,
) -> Result<()> {
    let n = width * height;
    let bad = |what: String| Error::InvalidArgument(format!("{}: {what}", path.display()));
    if panels.is_empty() || n == 0 {
        return Err(bad("a figure needs at least one non-empty panel".into()));
    }
    let mut pixels: Vec<Vec<[u8; 3]>> = Vec::with_capacity(panels.len());
    for p in panels {
        let px: Vec<[u8; 3]> = match *p {
            Panel::Colour(img) => {
                if (img.width, img.height) != (width, height) {
                    return Err(bad(format!(
                        "a {}x{} panel in a {width}x{height} figure",
                        img.width, img.height
                    )));
                }
                (0..n)
                    .map(|i| std::array::from_fn(|c| srgb_preview_u8(img.planes[c][i])))
                    .collect()
            }
            Panel::Heat(values, max) => {
                if values.len() != n {
                    return Err(bad(format!(
                        "a heat panel of {} values in a {width}x{height} figure",
                        values.len()
                    )));
                }
                values
                    .iter()
                    .map(|&v| {
                        if v.is_nan() || v == f32::INFINITY {
                            heat_color(1.0)
                        } else if max > 0.0 {
                            heat_color(v / max)
                        } else {
                            heat_color(0.0)
                        }
                    })
                    .collect()
            }
        };
        pixels.push(px);
    }
    let total_w = panels.len() * width + (panels.len() - 1) * gap;
    let mut data = Vec::with_capacity(total_w * height * 3);
    for y in 0..height {
        for (k, px) in pixels.iter().enumerate() {
            if k > 0 {
                data.extend(std::iter::repeat(GAP_GREY).take(gap * 3));
            }
            for x in 0..width {
                data.extend_from_slice(&px[y * width + x]);
            }
        }
    }
    write_rgb8_png(path, total_w, height, &data)
}
