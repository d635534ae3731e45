//! Summaries of a render-statistics image: per-channel statistics
//! ([`inspect`]), warnings about values the denoiser will have to repair or
//! estimate ([`validate`]), and the human-readable report of
//! `mcdenoise inspect` ([`format_report`]).

use std::fmt::Write as _;
use std::path::Path;

use crate::image::{Layer, Requirement, StatsImage};

/// Statistics of one channel (plane).
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelStats {
    /// Full EXR channel name, e.g. `"normal.Z"`.
    pub name: String,
    /// Smallest finite value; NaN if the plane has no finite value.
    pub min: f32,
    /// Largest finite value; NaN if the plane has no finite value.
    pub max: f32,
    /// Mean over the finite values (accumulated in f64); NaN if none.
    pub mean: f64,
    /// Number of NaN values.
    pub nan: usize,
    /// Number of +Inf or -Inf values.
    pub inf: usize,
    /// Number of values `< 0` (including -Inf).
    pub negative: usize,
}

/// Statistics of one layer present in the image, its channels in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerReport {
    /// Which layer the statistics describe.
    pub layer: Layer,
    /// One entry per channel of the layer ([`Layer::channels`] order).
    pub channels: Vec<ChannelStats>,
}

/// Per-channel statistics of every present layer, in [`Layer::ALL`] order.
/// Cost: one pass over every plane.
pub fn inspect(img: &StatsImage) -> Vec<LayerReport> {
    img.layers()
        .map(|(layer, planes)| LayerReport {
            layer,
            channels: layer
                .channels()
                .iter()
                .zip(planes)
                .map(|(c, p)| channel_stats(format!("{}.{c}", layer.name()), p))
                .collect(),
        })
        .collect()
}

fn channel_stats(name: String, plane: &[f32]) -> ChannelStats {
    let (mut min, mut max) = (f32::INFINITY, f32::NEG_INFINITY);
    let (mut sum, mut finite) = (0.0f64, 0usize);
    let (mut nan, mut inf, mut negative) = (0, 0, 0);
    for &v in plane {
        if v.is_nan() {
            nan += 1;
            continue;
        }
        if v < 0.0 {
            negative += 1;
        }
        if v.is_infinite() {
            inf += 1;
            continue;
        }
        min = min.min(v);
        max = max.max(v);
        sum += v as f64;
        finite += 1;
    }
    if finite == 0 {
        (min, max) = (f32::NAN, f32::NAN);
    }
    ChannelStats {
        name,
        min,
        max,
        mean: if finite > 0 {
            sum / finite as f64
        } else {
            f64::NAN
        },
        nan,
        inf,
        negative,
    }
}

/// The smallest and largest finite sample count (`spp.Y`), or `None` if the
/// image has no `spp` layer or no finite value in it.
pub fn spp_range(img: &StatsImage) -> Option<(f32, f32)> {
    let spp = img.get(Layer::Spp)?.first()?;
    let mut range: Option<(f32, f32)> = None;
    for &v in spp.iter().filter(|v| v.is_finite()) {
        range = Some(match range {
            None => (v, v),
            Some((lo, hi)) => (lo.min(v), hi.max(v)),
        });
    }
    range
}

/// The first index in `plane` where `pred` holds, as pixel coordinates.
fn first_pixel(plane: &[f32], width: usize, pred: impl Fn(f32) -> bool) -> Option<(usize, usize)> {
    let i = plane.iter().position(|v| pred(*v))?;
    Some((i % width.max(1), i / width.max(1)))
}

/// Warnings about the input, one sentence each, naming the layer and the
/// first offending pixel `(x, y)`:
///
/// - NaN or Inf values in any channel;
/// - negative values in a variance layer (or on the diagonal of
///   `position_covariance`);
/// - pixels with zero samples, or a negative or non-finite `spp`;
/// - pixels with fewer than 2 samples while a variance layer is present (a
///   sample variance needs 2 samples);
/// - missing variance layers: those the denoiser estimates
///   ([`Requirement::Estimated`]) and, when `position` is present, the
///   `position_variance`/`position_covariance` the G-buffer prefilter needs.
///
/// An empty list means the input is clean. Values are never modified here.
pub fn validate(img: &StatsImage) -> Vec<String> {
    let w = img.width;
    let mut warnings = Vec::new();

    for (layer, planes) in img.layers() {
        for (c, plane) in layer.channels().iter().zip(planes) {
            let name = format!("{}.{c}", layer.name());
            let nan = plane.iter().filter(|v| v.is_nan()).count();
            let inf = plane.iter().filter(|v| v.is_infinite()).count();
            if nan + inf > 0 {
                let (x, y) = first_pixel(plane, w, |v| !v.is_finite()).unwrap_or((0, 0));
                warnings.push(format!(
                    "{name}: {nan} NaN and {inf} Inf values (first at pixel ({x}, {y}))"
                ));
            }
            let variance_like = layer.name().ends_with("_variance")
                || (layer == Layer::PositionCovariance && matches!(*c, "XX" | "YY" | "ZZ"));
            if variance_like {
                let neg = plane.iter().filter(|v| **v < 0.0).count();
                if neg > 0 {
                    let (x, y) = first_pixel(plane, w, |v| v < 0.0).unwrap_or((0, 0));
                    warnings.push(format!(
                        "{name}: {neg} negative variance values (first at pixel ({x}, {y}))"
                    ));
                }
            }
        }
    }

    if let Some(spp) = img.get(Layer::Spp).and_then(|p| p.first()) {
        let zero = spp.iter().filter(|v| **v == 0.0).count();
        if zero > 0 {
            let (x, y) = first_pixel(spp, w, |v| v == 0.0).unwrap_or((0, 0));
            warnings.push(format!(
                "spp.Y: {zero} pixels have zero samples (first at pixel ({x}, {y}))"
            ));
        }
        let invalid = spp.iter().filter(|v| **v < 0.0 || !v.is_finite()).count();
        if invalid > 0 {
            let (x, y) = first_pixel(spp, w, |v| v < 0.0 || !v.is_finite()).unwrap_or((0, 0));
            warnings.push(format!(
                "spp.Y: {invalid} pixels have a negative or non-finite sample count (first at pixel ({x}, {y}))"
            ));
        }
        let has_variance = img.layers().any(|(l, _)| l.name().ends_with("_variance"));
        if has_variance {
            let few = spp.iter().filter(|v| **v > 0.0 && **v < 2.0).count();
            if few > 0 {
                let (x, y) = first_pixel(spp, w, |v| v > 0.0 && v < 2.0).unwrap_or((0, 0));
                warnings.push(format!(
                    "spp.Y: {few} pixels have fewer than 2 samples, so their variances are undefined (first at pixel ({x}, {y}))"
                ));
            }
        }
    }

    for mean in Layer::WITH_VARIANCE {
        let Some(variance) = mean.variance() else {
            continue;
        };
        if img.has(variance) {
            continue;
        }
        if variance.requirement() == Requirement::Estimated {
            warnings.push(format!(
                "{} is missing: it will be estimated from the image",
                variance.name()
            ));
        } else if mean == Layer::Position && img.has(Layer::Position) {
            warnings.push(format!(
                "{} is missing: the G-buffer prefilter needs it with position",
                variance.name()
            ));
        }
    }
    if img.has(Layer::Position) && !img.has(Layer::PositionCovariance) {
        warnings.push(
            "position_covariance is missing: the G-buffer prefilter needs it with position"
                .to_string(),
        );
    }
    warnings
}

/// The report `mcdenoise inspect` prints: size, layers present and missing,
/// spp range, a per-channel table (min, max, mean, NaN/Inf/negative counts)
/// and the [`validate`] warnings.
pub fn format_report(path: &Path, img: &StatsImage) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "{}", path.display());
    let _ = writeln!(
        out,
        "  size: {} x {} ({} pixels)",
        img.width,
        img.height,
        img.pixel_count()
    );
    let present: Vec<&str> = img.layers().map(|(l, _)| l.name()).collect();
    let _ = writeln!(out, "  layers present: {}", present.join(", "));
    let missing: Vec<String> = Layer::ALL
        .iter()
        .filter(|l| !img.has(**l))
        .map(|l| {
            let kind = match l.requirement() {
                Requirement::Required => "required",
                Requirement::Estimated => "will be estimated",
                Requirement::Optional => "optional",
            };
            format!("{} ({kind})", l.name())
        })
        .collect();
    let _ = writeln!(
        out,
        "  layers missing: {}",
        if missing.is_empty() {
            "none".to_string()
        } else {
            missing.join(", ")
        }
    );
    match spp_range(img) {
        Some((lo, hi)) if lo == hi => {
            let _ = writeln!(out, "  spp: {lo} (constant)");
        }
        Some((lo, hi)) => {
            let _ = writeln!(out, "  spp: {lo} .. {hi}");
        }
        None => {
            let _ = writeln!(out, "  spp: n/a");
        }
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "  {:<24} {:>12} {:>12} {:>12} {:>8} {:>8} {:>8}",
        "channel", "min", "max", "mean", "NaN", "Inf", "neg"
    );
    for report in inspect(img) {
        for c in &report.channels {
            let _ = writeln!(
                out,
                "  {:<24} {:>12} {:>12} {:>12} {:>8} {:>8} {:>8}",
                c.name,
                fmt_num(c.min as f64),
                fmt_num(c.max as f64),
                fmt_num(c.mean),
                c.nan,
                c.inf,
                c.negative
            );
        }
    }
    let warnings = validate(img);
    let _ = writeln!(out);
    if warnings.is_empty() {
        let _ = writeln!(out, "  warnings: none");
    } else {
        let _ = writeln!(out, "  warnings:");
        for w in warnings {
            let _ = writeln!(out, "    - {w}");
        }
    }
    out
}

/// Compact number for the table: plain for moderate magnitudes, else exponent.
fn fmt_num(v: f64) -> String {
    if v.is_nan() {
        "-".to_string()
    } else if v == 0.0 || (1e-3..1e5).contains(&v.abs()) {
        format!("{v:.5}")
    } else {
        format!("{v:.4e}")
    }
}
