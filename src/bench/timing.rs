//! The timing benchmark ([`run_timing`]): one input denoised by every
//! method × backend, timed on the host and on the device.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use super::scenes::spp_of_file_name;
use super::synthetic::{synthetic, SYNTHETIC_SPP};
use super::{
    backend_name, case_matches, check_context, dedup_backends, denoiser, gpu_ms, median,
    select_methods, Note,
};
use crate::error::{Error, Result};
use crate::gpu::{timings_per_kernel, GpuContext, KernelTiming};
use crate::image::StatsImage;
use crate::io;
use crate::methods::{Backend, Method};

/// The frame the timing benchmark denoises.
#[derive(Clone, Debug, PartialEq)]
pub enum TimingInput {
    /// [`synthetic`] at [`SYNTHETIC_SPP`] spp, seed 1; `inputs` = `synthetic`.
    Synthetic,
    /// A render-statistics file; `inputs` = its stem (a `sppN` stem is
    /// prefixed with its folder's name: `dof_checker-spp16`), with every
    /// character other than letters, digits, `_` and `-` replaced by `_`.
    File(PathBuf),
}

/// What the timing benchmark runs.
#[derive(Clone, Debug)]
pub struct TimingConfig {
    /// Methods to run; empty = every method built into this version.
    pub methods: Vec<Method>,
    /// Backends; empty = the GPU.
    pub backends: Vec<Backend>,
    /// The frame to denoise.
    pub input: TimingInput,
    /// Synthetic: the frame size (default 256×256). File: a centred crop of
    /// this size (default: the whole file).
    pub size: Option<(usize, usize)>,
    /// Timed calls per case (≥ 1), after one untimed warm-up call.
    pub runs: usize,
    /// Case filter ([`case_matches`]) on `method.inputs.WxH`.
    pub filter: Option<String>,
    /// The optional stages (outliers, prefilter) for every method.
    pub stages: super::Stages,
}

/// GPU time of one kernel in one case.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelRow {
    /// The kernel's name (as in `spirv/<name>.comp`; `_f64` for the f64 variant).
    pub kernel: String,
    /// Median over the runs of the kernel's total GPU time in one call (ms).
    pub ms: f64,
    /// Dispatches (bands) of the kernel in one call.
    pub dispatches: usize,
    /// Median over the runs of the achieved GFLOP/s: the flops the kernel's
    /// cost function counts (its host file, `src/kernels/<name>.rs`) over
    /// its GPU time.
    pub gflops: f64,
    /// Median over the runs of the achieved GB/s: the kernel's compulsory
    /// traffic (every bound range read or written once per dispatch,
    /// [`crate::gpu::KernelTiming::bytes`]) over its GPU time.
    pub gbs: f64,
}

/// One case of the timing benchmark.
#[derive(Clone, Debug, PartialEq)]
pub struct TimingRow {
    /// `method.inputs.WxH`.
    pub case: String,
    /// The method denoising the frame.
    pub method: Method,
    /// The backend it ran on.
    pub backend: Backend,
    /// Width of the denoised frame (pixels).
    pub width: usize,
    /// Height of the denoised frame (pixels).
    pub height: usize,
    /// Wall-clock milliseconds of each timed call.
    pub wall_ms: Vec<f64>,
    /// Median of `wall_ms`.
    pub median_wall_ms: f64,
    /// `median_wall_ms` per million pixels.
    pub ms_per_megapixel: f64,
    /// Median over the runs of the summed kernel times (ms); `None` if the
    /// call reported no timings (CPU backend, or a method without them).
    pub gpu_ms: Option<f64>,
    /// GPU time per kernel, in the order the last run first dispatched them.
    pub kernels: Vec<KernelRow>,
    /// Peak device allocation of the case in MB (10⁶ bytes): the denoiser's
    /// buffers and the transfers' staging, from its creation to its last
    /// call; `None` on the CPU backend.
    pub device_mb: Option<f64>,
    /// Peak resident memory of the process during the case in MB (Linux;
    /// the input image, already read, included).
    pub rss_mb: Option<f64>,
}

/// The result of [`run_timing`].
#[derive(Clone, Debug, Default)]
pub struct TimingReport {
    /// Name of the Vulkan device, when the GPU backend was used.
    pub device: Option<String>,
    /// The `inputs` part of the case names.
    pub inputs: String,
    /// Where the input came from (a path, or `synthetic ...`).
    pub source: String,
    /// Timed calls per case ([`TimingConfig::runs`]).
    pub runs: usize,
    /// One row per case × backend that ran, methods in order.
    pub rows: Vec<TimingRow>,
    /// Cases whose calls failed (skipped).
    pub warnings: Vec<String>,
    /// The optional stages and `--opt` options of every case
    /// ([`super::Stages::describe`]).
    pub settings: String,
    /// The device's measured limits ([`super::measure_peak`]), when the GPU
    /// backend ran; each kernel's rate is shown as a fraction of them.
    pub peak: Option<super::Peak>,
}

/// The `inputs` name of a file (see [`TimingInput::File`]).
pub fn inputs_name(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "input".into());
    let name = match (spp_of_file_name(&format!("{stem}.exr")), path.parent()) {
        (Some(_), Some(parent)) => match parent
            .canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        {
            Some(dir) => format!("{dir}-{stem}"),
            None => stem,
        },
        _ => stem,
    };
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Runs the timing benchmark described by `cfg` (module docs). `ctx` is
/// needed when `cfg.backends` holds the GPU.
///
/// # Errors
/// `runs` is 0, the GPU backend is asked for without a context, the input
/// file cannot be read, or the crop is larger than the file. A method call
/// that fails skips its case with a warning.
pub fn run_timing(
    ctx: Option<&Arc<GpuContext>>,
    cfg: &TimingConfig,
    note: &mut dyn FnMut(Note),
) -> Result<TimingReport> {
    if cfg.runs == 0 {
        return Err(Error::InvalidArgument("--runs must be at least 1".into()));
    }
    let backends = dedup_backends(&cfg.backends);
    check_context(ctx, &backends)?;
    let methods = select_methods(&cfg.methods);
    let (img, inputs, source) = match &cfg.input {
        TimingInput::Synthetic => {
            let (w, h) = cfg.size.unwrap_or((256, 256));
            let s = synthetic(w, h, SYNTHETIC_SPP, 1);
            (
                s.stats,
                "synthetic".to_string(),
                format!("synthetic frame, {SYNTHETIC_SPP} spp, seed 1"),
            )
        }
        TimingInput::File(path) => {
            let full = io::read_stats(path)?;
            let img = match cfg.size {
                None => full,
                Some((w, h)) => {
                    if w > full.width || h > full.height {
                        return Err(Error::InvalidArgument(format!(
                            "{}: is {}x{}, smaller than --size {w}x{h}",
                            path.display(),
                            full.width,
                            full.height
                        )));
                    }
                    full.crop((full.width - w) / 2, (full.height - h) / 2, w, h)
                }
            };
            (img, inputs_name(path), path.display().to_string())
        }
    };
    let (w, h) = (img.width, img.height);
    let mut report = TimingReport {
        device: backends
            .contains(&Backend::Gpu)
            .then(|| ctx.map(|c| c.info().name.clone()))
            .flatten(),
        inputs: inputs.clone(),
        source,
        runs: cfg.runs,
        settings: cfg.stages.describe(),
        ..Default::default()
    };
    if let (true, Some(c)) = (backends.contains(&Backend::Gpu), ctx) {
        note(Note::Progress("device limits (peak_fma, peak_copy)"));
        match super::measure_peak(c, cfg.runs) {
            Ok(p) => report.peak = Some(p),
            Err(e) => {
                let msg = format!("device limits not measured: {e}");
                note(Note::Warning(&msg));
                report.warnings.push(msg);
            }
        }
    }
    for &method in &methods {
        let case = format!("{}.{inputs}.{w}x{h}", method.name());
        if !case_matches(&case, cfg.filter.as_deref()) {
            continue;
        }
        for &backend in &backends {
            note(Note::Progress(&format!(
                "{case} ({})",
                backend_name(backend)
            )));
            match time_case(ctx, &img, method, backend, cfg.runs, &cfg.stages) {
                Ok((wall_ms, timings, device_mb, rss_mb)) => {
                    let med = median(&wall_ms);
                    let sums: Vec<f64> = timings.iter().filter_map(|t| gpu_ms(t)).collect();
                    let kernels = timings
                        .last()
                        .map(|t| timings_per_kernel(t))
                        .unwrap_or_default()
                        .into_iter()
                        .map(|(kernel, _, dispatches)| {
                            let per_run: Vec<f64> = timings
                                .iter()
                                .map(|t| {
                                    t.iter()
                                        .filter(|k| k.kernel == kernel)
                                        .map(|k| k.nanoseconds)
                                        .sum::<f64>()
                                        / 1e6
                                })
                                .collect();
                            let rates: Vec<f64> = timings
                                .iter()
                                .map(|t| {
                                    let (f, ns) = t
                                        .iter()
                                        .filter(|k| k.kernel == kernel)
                                        .fold((0.0, 0.0), |(f, ns), k| {
                                            (f + k.flops, ns + k.nanoseconds)
                                        });
                                    f / ns.max(1e-9)
                                })
                                .collect();
                            let bandwidths: Vec<f64> = timings
                                .iter()
                                .map(|t| {
                                    let (b, ns) = t
                                        .iter()
                                        .filter(|k| k.kernel == kernel)
                                        .fold((0.0, 0.0), |(b, ns), k| {
                                            (b + k.bytes, ns + k.nanoseconds)
                                        });
                                    b / ns.max(1e-9)
                                })
                                .collect();
                            KernelRow {
                                ms: median(&per_run),
                                gflops: median(&rates),
                                gbs: median(&bandwidths),
                                kernel,
                                dispatches,
                            }
                        })
                        .collect();
                    report.rows.push(TimingRow {
                        case: case.clone(),
                        method,
                        backend,
                        width: w,
                        height: h,
                        median_wall_ms: med,
                        ms_per_megapixel: med / ((w * h) as f64 / 1e6),
                        wall_ms,
                        gpu_ms: (!sums.is_empty()).then(|| median(&sums)),
                        kernels,
                        device_mb,
                        rss_mb,
                    });
                }
                Err(e) => {
                    let msg = format!(
                        "{case} ({}) skipped: {}: {e}",
                        backend_name(backend),
                        report.source
                    );
                    note(Note::Warning(&msg));
                    report.warnings.push(msg);
                }
            }
        }
    }
    Ok(report)
}

/// One case's wall ms per run, timings per run, peak device MB, peak
/// resident MB.
type CaseResult = (Vec<f64>, Vec<Vec<KernelTiming>>, Option<f64>, Option<f64>);

/// One warm-up call, then `runs` timed calls on one [`Denoiser`](crate::Denoiser)
/// (its buffers allocated once, as an embedding renderer would keep it):
/// wall ms (upload, chain, download) and timings per run, and the case's
/// peak device allocation and resident memory.
fn time_case(
    ctx: Option<&Arc<GpuContext>>,
    img: &StatsImage,
    method: Method,
    backend: Backend,
    runs: usize,
    stages: &super::Stages,
) -> Result<CaseResult> {
    let device_base = ctx.map(|c| {
        c.reset_peak();
        c.allocated_bytes()
    });
    super::reset_peak_rss();
    let mut d = Timed::new(ctx, img, method, backend, stages)?;
    d.call(img)?;
    let (mut wall, mut timings) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let t0 = Instant::now();
        let out = d.call(img)?;
        wall.push(t0.elapsed().as_secs_f64() * 1e3);
        let mut t = out.timings;
        count_lp(&mut t, &out.stats, img.width * img.height);
        count_by_rank(&mut t, method, &out.dim, (img.width, img.height));
        timings.push(t);
    }
    let mb = |b: u64| b as f64 / 1e6;
    let device_mb = match (backend, ctx, device_base) {
        (Backend::Gpu, Some(c), Some(base)) => {
            Some(mb(c.peak_allocated_bytes().saturating_sub(base)))
        }
        _ => None,
    };
    Ok((wall, timings, device_mb, super::peak_rss_bytes().map(mb)))
}

/// What a timed call runs: a [`crate::Denoiser`] call, or with APR's
/// temporal window ([`crate::Temporal::Apr`]) a push of the same
/// statistics as the next frame of a sequence, timed once the window is
/// full (every push then outputs a frame: one frame's whole work); with
/// the two-way filter ([`crate::Temporal::LpSmooth`]) one frame's whole
/// work too: the method and the filter in frame order, the host copy of
/// the filter's inputs, and the reverse pass's frame (upload, the filter,
/// `lp_smooth`, download), both directions carrying their state from call
/// to call.
enum Timed {
    One(crate::Denoiser),
    Window(Box<crate::SequenceDenoiser>),
    Smooth {
        forward: Box<crate::Denoiser>,
        reverse: Box<crate::methods::temporal::SmoothStage>,
        calls: usize,
    },
}

impl Timed {
    fn new(
        ctx: Option<&Arc<GpuContext>>,
        img: &StatsImage,
        method: Method,
        backend: Backend,
        stages: &super::Stages,
    ) -> Result<Timed> {
        if !matches!(
            stages.temporal,
            crate::Temporal::Apr | crate::Temporal::LpSmooth
        ) {
            return Ok(Timed::One(denoiser(ctx, img, method, backend, stages)?));
        }
        let Some(ctx) = ctx.filter(|_| backend == Backend::Gpu) else {
            return Err(crate::Error::InvalidArgument(
                "the offline temporal stages (apr, lp-smooth) run on the GPU backend".into(),
            ));
        };
        if stages.temporal == crate::Temporal::LpSmooth {
            let lp = super::Stages {
                temporal: crate::Temporal::Lp,
                ..stages.clone()
            };
            let forward = super::denoiser(Some(ctx), img, method, backend, &lp)?;
            let precision = forward.config().precision;
            let reverse = crate::methods::temporal::SmoothStage::new(
                ctx,
                (img.width, img.height),
                precision,
            )?;
            reverse.build_pipelines()?;
            return Ok(Timed::Smooth {
                forward: Box::new(forward),
                reverse: Box::new(reverse),
                calls: 0,
            });
        }
        let mut config = super::config(img, method, stages);
        config.temporal = crate::Temporal::Apr;
        let mut w = crate::SequenceDenoiser::new(ctx, crate::Source::of_image(img), config)?;
        for _ in 0..w.lag().unwrap_or(0) {
            w.push(img)?;
        }
        Ok(Timed::Window(Box::new(w)))
    }

    fn call(&mut self, img: &StatsImage) -> Result<crate::Frame> {
        match self {
            Timed::One(d) => d.denoise(img, None),
            Timed::Window(w) => w.push(img)?.pop().map(|(_, f)| f).ok_or_else(|| {
                crate::Error::InvalidArgument("a full window outputs a frame per push".into())
            }),
            Timed::Smooth {
                forward,
                reverse,
                calls,
            } => {
                let mut f = forward.denoise(img, None)?;
                let record = forward.temporal_record()?.ok_or_else(|| {
                    crate::Error::InvalidArgument("the forward pass has no temporal filter".into())
                })?;
                // Both directions have filtered every call so far.
                let n = *calls as u64 + 1;
                let (color, timings) = reverse.run(&record, &f.color, (n, n), false)?;
                *calls += 1;
                f.color = color;
                f.timings.extend(timings);
                Ok(f)
            }
        }
    }
}

/// LP's two data-dependent kernels are dispatched with upper bounds of
/// their work, which size the bands: `lp_centres` charges every candidate
/// cell of every pass the fit of a centre of the largest rank
/// ([`crate::kernels::lp_centres::flops_per_centre`]), `lp_gather` every
/// pixel 30 covering centres. A run's census (LP's statistics
/// `centre_flops` and `covering`, [`crate::methods::lp::Census`]) gives the
/// work the method did: each centre's fit at its rank
/// ([`crate::kernels::lp_centres::flops_of_centre`]) and each pixel's
/// predictions by the centres that cover it
/// ([`crate::kernels::lp_gather::flops_of_pixel`]); the kernels' flops are
/// rescaled to those.
fn count_lp(t: &mut [KernelTiming], stats: &[(String, f64)], pixels: usize) {
    let stat = |name: &str| stats.iter().find(|(k, _)| k == name).map(|&(_, v)| v);
    let n = pixels as f64;
    if let Some(f) = stat("centre_flops") {
        rescale(t, "lp_centres", f * n);
    }
    if let Some(c) = stat("covering") {
        rescale(
            t,
            "lp_gather",
            crate::kernels::lp_gather::flops_of_pixel(c) * n,
        );
    }
}

/// WLR's and AOS's fits are dispatched with bounds of their work, which
/// size the bands (`wlr_fit`, `wlr_final`: rank 9 with every neighbour in
/// every kernel's support; `aos_fit`: its block layout at rank 3). The
/// run's rank map (`dim`: WLR's and AOS's TSVD rank per pixel, 0 for an
/// invalid pixel) gives the work the method did: each pixel's fits at its
/// rank over its window clipped to the image
/// ([`crate::kernels::wlr_fit::flops_of_pixel`],
/// [`crate::kernels::wlr_final::flops_of_pixel`],
/// [`crate::kernels::aos_fit::flops_of_pixel`]), in the final pass's
/// window (the bench's); the kernels' flops are rescaled to those. Rank 0
/// is taken for an invalid pixel (no work): a valid one has rank 0 only
/// when it is its window's one valid pixel. A rank map of the wrong size
/// (none downloaded) leaves the flops as dispatched.
fn count_by_rank(t: &mut [KernelTiming], method: Method, dim: &[f32], (w, h): (usize, usize)) {
    use crate::kernels::{aos_fit, wlr_final, wlr_fit};
    type PixelFlops = fn(f64, u32) -> f64;
    let (radius, kernels): (usize, &[(&str, PixelFlops)]) = match method {
        Method::Wlr => (
            crate::methods::wlr::RADIUS_FINAL as usize,
            &[
                ("wlr_fit", wlr_fit::flops_of_pixel),
                ("wlr_final", wlr_final::flops_of_pixel),
                ("wlr_fit_vis", wlr_fit::flops_of_pixel_vis),
                ("wlr_final_vis", wlr_final::flops_of_pixel_vis),
            ],
        ),
        Method::Aos => (
            crate::reference::aos::RADIUS_FINAL,
            &[("aos_fit", aos_fit::flops_of_pixel)],
        ),
        _ => return,
    };
    if dim.len() != w * h || w == 0 {
        return;
    }
    // The window's extent along a row or column, clipped to the image.
    let extent = |n: usize| -> Vec<f64> {
        (0..n)
            .map(|i| crate::kernels::clipped_span(i, radius, n) as f64)
            .collect()
    };
    let (ex, ey) = (extent(w), extent(h));
    for &(name, of_pixel) in kernels {
        let actual: f64 = dim
            .iter()
            .enumerate()
            .filter(|&(_, &k)| k >= 0.5)
            .map(|(i, &k)| of_pixel(ex[i % w] * ey[i / w], k.round() as u32))
            .sum();
        rescale(t, name, actual);
        rescale(t, &format!("{name}_f64"), actual);
    }
}

/// Scales the flops of `kernel`'s timings so that they sum to `actual`.
fn rescale(t: &mut [KernelTiming], kernel: &str, actual: f64) {
    let counted: f64 = t
        .iter()
        .filter(|k| k.kernel == kernel)
        .map(|k| k.flops)
        .sum();
    if counted <= 0.0 {
        return;
    }
    for k in t.iter_mut().filter(|k| k.kernel == kernel) {
        k.flops *= actual / counted;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timing(kernel: &str, flops: f64) -> KernelTiming {
        KernelTiming {
            kernel: kernel.into(),
            rows: (0, 8),
            nanoseconds: 1e6,
            flops,
            bytes: 0.0,
        }
    }

    #[test]
    fn count_by_rank_charges_each_pixel_its_rank_and_window() {
        use crate::kernels::{aos_fit, wlr_final, wlr_fit};
        let (w, h) = (40, 3);
        // Rank 3 everywhere but one invalid pixel (rank 0).
        let mut dim = vec![3.0f32; w * h];
        dim[5] = 0.0;
        let mut t = vec![
            timing("wlr_fit", 1e9),
            timing("wlr_fit", 2e9),
            timing("wlr_final", 1e9),
            timing("gauss_smooth", 7.0),
        ];
        count_by_rank(&mut t, Method::Wlr, &dim, (w, h));
        // R = 9: every window spans the 3 rows; 19 columns away from the
        // sides.
        let (mut fit, mut fin) = (0.0, 0.0);
        for i in (0..w * h).filter(|&i| i != 5) {
            let x = i % w;
            let n = ((x + 9).min(w - 1) + 1 - x.saturating_sub(9)) as f64 * 3.0;
            fit += wlr_fit::flops_of_pixel(n, 3);
            fin += wlr_final::flops_of_pixel(n, 3);
        }
        let sum =
            |name: &str| -> f64 { t.iter().filter(|k| k.kernel == name).map(|k| k.flops).sum() };
        assert!((sum("wlr_fit") - fit).abs() < 1e-6 * fit);
        assert!((sum("wlr_final") - fin).abs() < 1e-6 * fin);
        // In proportion to what the bands were charged.
        assert!((t[1].flops - 2.0 * t[0].flops).abs() < 1e-6 * t[1].flops);
        assert_eq!(t[3].flops, 7.0);
        // AOS's kernel, and none of WLR's, for AOS.
        let mut t = vec![timing("aos_fit", 1e9), timing("wlr_fit", 1e9)];
        count_by_rank(&mut t, Method::Aos, &dim, (w, h));
        assert!(t[0].flops < 1e9 && t[0].flops > 0.0);
        assert!(t[0].flops > 119.0 * aos_fit::flops_of_pixel(30.0, 3));
        assert!(t[0].flops < 119.0 * aos_fit::flops_of_pixel(57.0, 3));
        assert_eq!(t[1].flops, 1e9);
        // No rank map: unchanged.
        count_by_rank(&mut t, Method::Aos, &[], (w, h));
        assert_eq!(t[1].flops, 1e9);
    }
}
