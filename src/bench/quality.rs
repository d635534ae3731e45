//! The quality benchmark ([`run_quality`]) and the error-estimate
//! correlations it reports ([`error_correlation`], [`naive_correlation`]).

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use super::scenes::{discover_scenes, Scene};
use super::{
    backend_name, case_matches, check_context, colour_layer, dedup_backends, denoiser, gpu_ms,
    map_budget, select_methods, Note,
};
use crate::error::Result;
use crate::gpu::GpuContext;
use crate::image::{Layer, RgbImage, StatsImage};
use crate::io;
use crate::methods::{Backend, Method};
use crate::metrics::{self, Metrics};
use crate::Frame;

/// Side of the square tiles the error correlations average over (pixels).
pub const CORRELATION_TILE: usize = 8;

/// Means of a per-pixel value over non-overlapping `tile × tile` tiles,
/// row-major by tile. Tiles cut by the right or bottom border are kept and
/// averaged over the pixels they hold.
pub fn tile_means(
    width: usize,
    height: usize,
    tile: usize,
    value: impl Fn(usize) -> f64,
) -> Vec<f64> {
    assert!(tile > 0, "tile_means: tile size 0");
    let (tw, th) = (width.div_ceil(tile), height.div_ceil(tile));
    let mut sum = vec![0.0f64; tw * th];
    let mut count = vec![0usize; tw * th];
    for y in 0..height {
        for x in 0..width {
            let t = (y / tile) * tw + x / tile;
            sum[t] += value(y * width + x);
            count[t] += 1;
        }
    }
    sum.iter().zip(&count).map(|(s, &n)| s / n as f64).collect()
}

/// Budget of the sample map the quality benchmark asks for, per pixel (the
/// share below does not depend on it beyond rounding).
pub const MAP_BUDGET_PER_PIXEL: u32 = 4;

/// Fraction of [`CORRELATION_TILE`]-sized tiles counted as "worst" by
/// [`map_share`].
pub const WORST_TILE_FRACTION: f64 = 0.10;

/// Whether a sample map points at the error: the share of its samples that
/// falls into the 10 % of 8×8 tiles where `out` has the largest true error,
/// measured as rMSE's per-pixel term `mean_ch (x−r)²/(r²+0.01)` against
/// `reference`. Uniform sampling gives about 0.10. NaN for an empty map.
pub fn map_share(samples: &[u32], out: &RgbImage, reference: &RgbImage) -> f64 {
    let (w, h) = (out.width, out.height);
    let heat = match metrics::rmse_heatmap(out, reference) {
        Ok(m) => m,
        Err(_) => return f64::NAN,
    };
    let err = tile_means(w, h, CORRELATION_TILE, |i| heat[i] as f64);
    let got = tile_means(w, h, CORRELATION_TILE, |i| samples[i] as f64);
    let mut order: Vec<usize> = (0..err.len()).collect();
    order.sort_by(|&a, &b| err[b].total_cmp(&err[a]));
    let worst = ((err.len() as f64 * WORST_TILE_FRACTION).round() as usize).max(1);
    // Tile means × tile pixel counts = tile sums.
    let tw = w.div_ceil(CORRELATION_TILE);
    let pixels = |t: usize| {
        let (tx, ty) = (t % tw, t / tw);
        let cw = (w - tx * CORRELATION_TILE).min(CORRELATION_TILE);
        let ch = (h - ty * CORRELATION_TILE).min(CORRELATION_TILE);
        (cw * ch) as f64
    };
    let total: f64 = samples.iter().map(|&s| s as f64).sum();
    let in_worst: f64 = order[..worst].iter().map(|&t| got[t] * pixels(t)).sum();
    in_worst / total
}

/// Pearson correlation of two equally long samples, in f64. NaN if there are
/// fewer than two values, if either sample is constant, or if any value is
/// non-finite (a broken map never scores well).
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "pearson: lengths differ");
    let n = a.len();
    if n < 2 || a.iter().chain(b).any(|v| !v.is_finite()) {
        return f64::NAN;
    }
    let ma = a.iter().sum::<f64>() / n as f64;
    let mb = b.iter().sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (dx, dy) = (x - ma, y - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    if saa == 0.0 || sbb == 0.0 {
        return f64::NAN;
    }
    sab / (saa * sbb).sqrt()
}

/// How well an estimated per-pixel MSE map predicts the actual error.
///
/// Per pixel: the estimate is the mean over the three channels of `est`
/// (estimated MSE of `out`), the truth is the mean over the channels of
/// `(out − reference)²`. Both maps are averaged over non-overlapping
/// [`CORRELATION_TILE`]` × `[`CORRELATION_TILE`] tiles (8×8; border tiles
/// partly outside the image are averaged over their pixels inside it), which
/// takes out most of the single-pixel noise of the squared error, and the
/// result is the Pearson correlation ([`pearson`]) of the two tile maps, in
/// [−1, 1]: 1 means the estimate is a perfect linear predictor of where the
/// error is. NaN if the image has fewer than two tiles, either tile map is
/// constant, or any value is non-finite.
///
/// # Panics
/// If the three images differ in size (a programming error; check with
/// [`metrics::check_same_size`] first for user input).
pub fn error_correlation(est: &RgbImage, out: &RgbImage, reference: &RgbImage) -> f64 {
    for (what, img) in [("estimate", est), ("reference", reference)] {
        assert!(
            (img.width, img.height) == (out.width, out.height),
            "error_correlation: {what} is {}x{}, the output {}x{}",
            img.width,
            img.height,
            out.width,
            out.height
        );
    }
    let (w, h) = (out.width, out.height);
    let estimated = tile_means(w, h, CORRELATION_TILE, |i| {
        est.planes.iter().map(|p| p[i] as f64).sum::<f64>() / 3.0
    });
    let actual = tile_means(w, h, CORRELATION_TILE, |i| {
        (0..3)
            .map(|c| {
                let d = out.planes[c][i] as f64 - reference.planes[c][i] as f64;
                d * d
            })
            .sum::<f64>()
            / 3.0
    });
    pearson(&estimated, &actual)
}

/// The baseline for [`error_correlation`]: the same correlation with the
/// input's own variance of the mean (`color_variance`, channel mean) in place
/// of the method's estimate, against the same output's actual error. A method's
/// estimate is worth something where it beats this. `None` if `input` has no
/// `color_variance` layer.
///
/// # Panics
/// If `input`, `out` and `reference` differ in size.
pub fn naive_correlation(input: &StatsImage, out: &RgbImage, reference: &RgbImage) -> Option<f64> {
    let v = input.get(Layer::ColorVariance)?;
    let var = RgbImage::from_planes(
        input.width,
        input.height,
        [v[0].clone(), v[1].clone(), v[2].clone()],
    );
    Some(error_correlation(&var, out, reference))
}

/// What the quality benchmark runs.
#[derive(Clone, Debug)]
pub struct QualityConfig {
    /// The scenes folder ([`discover_scenes`]).
    pub dir: PathBuf,
    /// Methods to run; empty = every method built into this version.
    /// Requested methods that are not built are reported once and skipped.
    pub methods: Vec<Method>,
    /// Backends to run each method on; empty = the GPU.
    pub backends: Vec<Backend>,
    /// Case filter ([`case_matches`]) on `method.scene.sppN`. The `input` row
    /// of a scene × spp is kept when its own name or any of that scene × spp's
    /// method cases matches.
    pub filter: Option<String>,
    /// The optional stages (outliers, prefilter) for every method.
    pub stages: super::Stages,
}

/// One row of the quality table.
#[derive(Clone, Debug, PartialEq)]
pub struct QualityRow {
    /// `method.scene.sppN`.
    pub case: String,
    /// The scene folder's name.
    pub scene: String,
    /// The samples per pixel of the input (the N of `sppN.exr`).
    pub spp: u32,
    /// A [`Method::name`], or `"input"` for the noisy input's own colour.
    pub method: String,
    /// `None` for the input row.
    pub backend: Option<Backend>,
    /// Of the method's colour (the raw input colour for `input`) against the reference.
    pub metrics: Metrics,
    /// Wall-clock seconds of making the case's [`Denoiser`](crate::Denoiser)
    /// and its [`denoise`](crate::Denoiser::denoise) call (not the file
    /// reading or the metrics).
    pub wall_s: Option<f64>,
    /// Sum of the call's kernel timings (ms); `None` if none were reported.
    pub gpu_ms: Option<f64>,
    /// [`error_correlation`] of the method's error estimate, if it returned one.
    pub err_corr: Option<f64>,
    /// [`naive_correlation`] for the same output (only alongside `err_corr`).
    pub naive_corr: Option<f64>,
    /// [`map_share`] of the sample map that comes with the output.
    pub map_share: Option<f64>,
    /// `gpu_ms` per megapixel of the input.
    pub gpu_ms_per_mp: Option<f64>,
    /// Fraction of the pixels that became centres (LP).
    pub centres: Option<f64>,
}

/// Per method × backend × spp: how much the method improves on the input.
#[derive(Clone, Debug, PartialEq)]
pub struct QualitySummary {
    /// A [`Method::name`].
    pub method: String,
    /// The backend the method ran on.
    pub backend: Backend,
    /// The samples per pixel of the inputs.
    pub spp: u32,
    /// Scenes that had both an input row and a method row at this spp.
    pub scenes: usize,
    /// Mean over those scenes of rMSE(input) / rMSE(method): > 1 is better
    /// than the noisy input.
    pub mean_rmse_ratio: f64,
    /// Mean [`error_correlation`] over the scenes that had one.
    pub mean_err_corr: Option<f64>,
}

/// One method against WLR on the same scene, spp and backend.
#[derive(Clone, Debug, PartialEq)]
pub struct VsWlr {
    /// The scene folder's name.
    pub scene: String,
    /// The samples per pixel of the input.
    pub spp: u32,
    /// A [`Method::name`] other than `wlr` and `none`.
    pub method: String,
    /// The backend both methods ran on.
    pub backend: Backend,
    /// rMSE(method) / rMSE(wlr): < 1 is better than WLR.
    pub rmse_ratio: f64,
    /// GPU time of WLR / GPU time of the method (> 1: the method is faster).
    pub speedup: Option<f64>,
}

/// The result of [`run_quality`].
#[derive(Clone, Debug, Default)]
pub struct QualityReport {
    /// The scenes folder the benchmark ran on.
    pub dir: PathBuf,
    /// Name of the Vulkan device, when the GPU backend was used.
    pub device: Option<String>,
    /// Table rows, by scene, spp, then input first and methods in order.
    pub rows: Vec<QualityRow>,
    /// Skipped cases: each message names the case or scene and the file.
    pub warnings: Vec<String>,
    /// The optional stages and `--opt` options of every case
    /// ([`super::Stages::describe`]).
    pub settings: String,
}

/// Runs the quality benchmark described by `cfg` (module docs). `ctx` is
/// needed when `cfg.backends` holds the GPU. Progress and warnings go to
/// `note` as they happen; warnings are also kept in the report.
///
/// # Errors
/// Only for what stops the whole benchmark: the folder cannot be listed or
/// holds no scene, or the GPU backend is asked for without a context. A
/// missing or unreadable file, a size mismatch or a failing method call skips
/// the affected cases with a warning.
pub fn run_quality(
    ctx: Option<&Arc<GpuContext>>,
    cfg: &QualityConfig,
    note: &mut dyn FnMut(Note),
) -> Result<QualityReport> {
    let backends = dedup_backends(&cfg.backends);
    check_context(ctx, &backends)?;
    let scenes = discover_scenes(&cfg.dir)?;
    let methods = select_methods(&cfg.methods);
    let mut report = QualityReport {
        dir: cfg.dir.clone(),
        device: backends
            .contains(&Backend::Gpu)
            .then(|| ctx.map(|c| c.info().name.clone()))
            .flatten(),
        settings: cfg.stages.describe(),
        ..Default::default()
    };
    let warn = |report: &mut QualityReport, note: &mut dyn FnMut(Note), msg: String| {
        note(Note::Warning(&msg));
        report.warnings.push(msg);
    };
    let filter = cfg.filter.as_deref();
    // GPU method × backend pairs already warmed up (pipelines built).
    let mut warmed: BTreeSet<(&'static str, &'static str)> = BTreeSet::new();

    for scene in &scenes {
        let case_name = |method: &str, spp: u32| format!("{method}.{}.spp{spp}", scene.name);
        let selected = |spp: u32| -> (bool, Vec<Method>) {
            let ms: Vec<Method> = methods
                .iter()
                .copied()
                .filter(|m| case_matches(&case_name(m.name(), spp), filter))
                .collect();
            let input = case_matches(&case_name("input", spp), filter) || !ms.is_empty();
            (input, ms)
        };
        if !scene.inputs.iter().any(|(spp, _)| selected(*spp).0) {
            continue;
        }
        let reference = match io::read_rgb(&scene.reference) {
            Ok(r) => r,
            Err(e) => {
                warn(
                    &mut report,
                    note,
                    format!(
                        "scene {} skipped: cannot read its reference: {e}",
                        scene.name
                    ),
                );
                continue;
            }
        };
        for (spp, path) in &scene.inputs {
            let (want_input, ms) = selected(*spp);
            if !want_input {
                continue;
            }
            let img = match io::read_stats(path) {
                Ok(img) => img,
                Err(e) => {
                    warn(
                        &mut report,
                        note,
                        format!("{}.spp{spp} skipped: {e}", scene.name),
                    );
                    continue;
                }
            };
            let input_colour = colour_layer(&img).expect("read_stats requires the colour layer");
            let input_metrics = match metrics::compare(&input_colour, &reference) {
                Ok(m) => m,
                Err(e) => {
                    warn(
                        &mut report,
                        note,
                        format!(
                            "{}.spp{spp} skipped: {} vs {}: {e}",
                            scene.name,
                            path.display(),
                            scene.reference.display()
                        ),
                    );
                    continue;
                }
            };
            report.rows.push(QualityRow {
                case: case_name("input", *spp),
                scene: scene.name.clone(),
                spp: *spp,
                method: "input".into(),
                backend: None,
                metrics: input_metrics,
                wall_s: None,
                gpu_ms: None,
                err_corr: None,
                naive_corr: None,
                map_share: None,
                gpu_ms_per_mp: None,
                centres: None,
            });
            for &method in &ms {
                for &backend in &backends {
                    let case = case_name(method.name(), *spp);
                    note(Note::Progress(&format!(
                        "{case} ({})",
                        backend_name(backend)
                    )));
                    let budget = map_budget(img.width * img.height);
                    if backend == Backend::Gpu
                        && warmed.insert((method.name(), backend_name(backend)))
                    {
                        // Untimed warm-up on a corner crop (builds the pipelines
                        // at a fraction of the cost); a failure shows in the timed call.
                        let (cw, ch) = (img.width.min(32), img.height.min(32));
                        let crop = img.crop(0, 0, cw, ch);
                        let _ = denoiser(ctx, &crop, method, backend, &cfg.stages)
                            .and_then(|d| d.denoise(&crop, Some(map_budget(cw * ch))));
                    }
                    let t0 = Instant::now();
                    let result = denoiser(ctx, &img, method, backend, &cfg.stages)
                        .and_then(|d| d.denoise(&img, Some(budget)));
                    let wall = t0.elapsed().as_secs_f64();
                    let out = match result {
                        Ok(out) => out,
                        Err(e) => {
                            warn(
                                &mut report,
                                note,
                                format!(
                                    "{case} ({}) skipped: {}: {e}",
                                    backend_name(backend),
                                    path.display()
                                ),
                            );
                            continue;
                        }
                    };
                    match quality_row(
                        &case, scene, *spp, method, backend, &img, &out, &reference, wall,
                    ) {
                        Ok(row) => report.rows.push(row),
                        Err(msg) => warn(&mut report, note, msg),
                    }
                }
            }
        }
    }
    Ok(report)
}

/// Scores one method's output; `Err` holds the warning if it cannot be scored.
fn quality_row(
    case: &str,
    scene: &Scene,
    spp: u32,
    method: Method,
    backend: Backend,
    img: &StatsImage,
    out: &Frame,
    reference: &RgbImage,
    wall_s: f64,
) -> std::result::Result<QualityRow, String> {
    let skipped = |e: &dyn std::fmt::Display| {
        format!(
            "{case} ({}) skipped: output vs {}: {e}",
            backend_name(backend),
            scene.reference.display()
        )
    };
    let m = metrics::compare(&out.color, reference).map_err(|e| skipped(&e))?;
    // Every method exports an estimate; `none`'s is the variance of the mean
    // (the MSE of the unfiltered input).
    metrics::check_same_size(&out.error, &out.color).map_err(|e| skipped(&e))?;
    let (err_corr, naive_corr) = (
        Some(error_correlation(&out.error, &out.color, reference)),
        naive_correlation(img, &out.color, reference),
    );
    let map_share = out
        .samples
        .as_ref()
        .map(|s| map_share(s, &out.color, reference));
    Ok(QualityRow {
        case: case.to_string(),
        scene: scene.name.clone(),
        spp,
        method: method.name().into(),
        backend: Some(backend),
        metrics: m,
        wall_s: Some(wall_s),
        gpu_ms: gpu_ms(&out.timings),
        err_corr,
        naive_corr,
        map_share,
        gpu_ms_per_mp: gpu_ms(&out.timings).map(|t| t / (img.width * img.height) as f64 * 1e6),
        centres: out
            .stats
            .iter()
            .find(|(k, _)| k == "centre_fraction")
            .map(|(_, v)| *v),
    })
}

impl QualityReport {
    /// Every non-WLR method row (not `input`, not `none`) that has a WLR row
    /// of the same scene, spp and backend, in table order.
    pub fn vs_wlr(&self) -> Vec<VsWlr> {
        let mut v = Vec::new();
        for r in &self.rows {
            let Some(backend) = r.backend else { continue };
            if r.method == "wlr" || r.method == "none" {
                continue;
            }
            let Some(w) = self.rows.iter().find(|w| {
                w.method == "wlr" && w.scene == r.scene && w.spp == r.spp && w.backend == r.backend
            }) else {
                continue;
            };
            v.push(VsWlr {
                scene: r.scene.clone(),
                spp: r.spp,
                method: r.method.clone(),
                backend,
                rmse_ratio: r.metrics.rmse / w.metrics.rmse,
                speedup: match (w.gpu_ms, r.gpu_ms) {
                    (Some(a), Some(b)) if b > 0.0 => Some(a / b),
                    _ => None,
                },
            });
        }
        v
    }

    /// Per method × backend × spp (in table order): the mean over scenes of
    /// rMSE(input) / rMSE(method), and the mean error correlation.
    pub fn summary(&self) -> Vec<QualitySummary> {
        // (method, backend) in order of first appearance, then spp ascending.
        let mut groups: Vec<(String, Backend)> = Vec::new();
        for r in &self.rows {
            if let Some(b) = r.backend {
                if !groups.iter().any(|g| g.0 == r.method && g.1 == b) {
                    groups.push((r.method.clone(), b));
                }
            }
        }
        let spps: BTreeSet<u32> = self.rows.iter().map(|r| r.spp).collect();
        let mut keys = Vec::new();
        for (method, backend) in groups {
            for &spp in &spps {
                if self
                    .rows
                    .iter()
                    .any(|r| r.method == method && r.backend == Some(backend) && r.spp == spp)
                {
                    keys.push((method.clone(), backend, spp));
                }
            }
        }
        keys.into_iter()
            .map(|(method, backend, spp)| {
                let (mut ratios, mut corrs) = (Vec::new(), Vec::new());
                for r in self
                    .rows
                    .iter()
                    .filter(|r| r.method == method && r.backend == Some(backend) && r.spp == spp)
                {
                    let input = self
                        .rows
                        .iter()
                        .find(|i| i.backend.is_none() && i.scene == r.scene && i.spp == spp);
                    if let Some(i) = input {
                        ratios.push(i.metrics.rmse / r.metrics.rmse);
                    }
                    corrs.extend(r.err_corr);
                }
                let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
                QualitySummary {
                    scenes: ratios.len(),
                    mean_rmse_ratio: mean(&ratios),
                    mean_err_corr: (!corrs.is_empty()).then(|| mean(&corrs)),
                    method,
                    backend,
                    spp,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_means_keep_partial_tiles() {
        // 10 x 9: tiles of 8 give 2 x 2, the border ones partial.
        let m = tile_means(10, 9, 8, |i| (i % 10) as f64);
        assert_eq!(m.len(), 4);
        assert!((m[0] - 3.5).abs() < 1e-12); // x = 0..8
        assert!((m[1] - 8.5).abs() < 1e-12); // x = 8, 9
        assert!((m[2] - 3.5).abs() < 1e-12);
        assert!((m[3] - 8.5).abs() < 1e-12);
    }

    #[test]
    fn pearson_edge_cases() {
        assert!((pearson(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.5]) - 0.9986).abs() < 1e-3);
        assert!((pearson(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert!(pearson(&[1.0], &[1.0]).is_nan());
        assert!(pearson(&[1.0, 1.0], &[1.0, 2.0]).is_nan());
        assert!(pearson(&[1.0, f64::NAN], &[1.0, 2.0]).is_nan());
    }
}
