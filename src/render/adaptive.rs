//! The adaptive loop of the papers (spec §9.3) on the built-in renderer,
//! through the public facade only: pass 0 renders `s_0` uniform samples per
//! pixel; each adaptive pass reconstructs (intermediate windows), turns the
//! error into a sample map for its budget and renders that many samples where
//! the map says; the final pass reconstructs with the final windows. The
//! statistics, error maps and sample maps stay on the GPU between passes
//! (one submission sequence per pass, so a stop request is honoured between
//! passes); only the final image comes back.
//!
//! With [`StopRules`] the number of passes is open: after each pass the final
//! reconstruction's *estimated* rMSE ([`StopEstimates`]: after pass 0 the
//! method's own estimate, after the others how far the reconstruction moved
//! since an earlier one) is compared with a target, the next pass's budget
//! is predicted from how the estimate fell so far, and a time limit stops
//! the render at the last pass that fits. `--max-spp` bounds the samples in
//! every case.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use super::{FeatureSamples, Renderer, Samples};
use crate::gpu::GpuBuffer;
use crate::schedule::INITIAL_SPP;
use crate::{
    Batch, Config, Denoiser, Error, Frame, GpuContext, InputBlend, KernelTiming, Method, Options,
    Outliers, Pass, Precision, Prefilter, Pyramid, Result, RgbImage, Schedule, Source,
};

/// What to render and how.
#[derive(Clone, Debug)]
pub struct LoopConfig {
    /// Average samples per pixel of the whole render (≥ 4 when adaptive).
    pub spp: u32,
    /// Adaptive passes (§9.3) or `spp` uniform samples in one pass.
    pub adaptive: bool,
    /// Reconstruction of the final image. `none`: the plain Monte Carlo
    /// mean.
    pub method: Method,
    /// The method whose reconstruction and error estimate make the
    /// adaptive passes' sample maps, with its schedule and sampling
    /// parameters ([`mapper`](Self::mapper); `None`: the final method's
    /// [`crate::MethodInfo::map_method`], MAP-WLR). `none` samples where
    /// the input variance is. [`with_map_method`](Self::with_map_method)
    /// also sets [`pass_cap`](Self::pass_cap) to that method's.
    pub map_method: Option<Method>,
    /// The G-buffer prefilter (§6).
    pub prefilter: Prefilter,
    /// The outlier stage (§4.4).
    pub outliers: Outliers,
    /// Kernel arithmetic.
    pub precision: Precision,
    /// Method options.
    pub options: Options,
    /// Most samples one pixel may receive in one adaptive pass, as a
    /// multiple of the pass's mean (`None`: no cap). The excess goes to the
    /// other pixels in proportion to their counts, so the pass still spends
    /// exactly its budget. A safeguard against an error estimate that keeps
    /// pointing at the same few pixels (LP's at emitter edges: 20,067 samples
    /// in one pixel of a 64-spp render).
    pub pass_cap: Option<f64>,
    /// Open-ended rendering ([`StopRules`]): passes continue until a target
    /// error, a time limit or a sample bound stops them. `None`: the fixed
    /// schedule of `spp` (§9.3).
    pub stop: Option<StopRules>,
    /// Adaptive passes of the fixed schedule after pass 0 (`None`: the
    /// map method's [`crate::MethodInfo::passes`], §9.3). Each pass costs
    /// one reconstruction for its map, so fewer passes leave more of a time
    /// budget to samples (EQUAL-TIME). At most [`MAX_PASSES`], and no more
    /// than the samples left after pass 0. Uniform and open-ended renders
    /// ignore it (the latter size their passes themselves).
    pub passes: Option<u32>,
    /// With a temporal final denoiser ([`render_with_final`]): the adaptive
    /// passes' sample maps weigh each pixel's error by what the temporal
    /// filter will make of the frame (TEMPORAL-MAP). `true` by default;
    /// `false` gives the maps of a render without the filter.
    pub temporal_maps: bool,
    /// The pyramid's low band ([`Config::pyramid`]) in the final
    /// reconstruction (and the open-ended renders' judging of it); the
    /// adaptive passes' reconstructions run without it.
    pub pyramid: Pyramid,
    /// The input blend ([`Config::input_blend`]) in the final
    /// reconstruction; the adaptive passes' reconstructions run without
    /// it.
    pub input_blend: InputBlend,
    /// The adaptive passes' sample maps from a half-resolution
    /// reconstruction ([`Config::coarse_map`], MAP-COARSE): the map method
    /// runs on the statistics pooled over 2×2 blocks, about a quarter of
    /// its work per pass. `false` by default. Not with the temporal maps
    /// of a temporal final denoiser, nor on images below 16×16 pixels.
    pub coarse_maps: bool,
    /// Before each adaptive pass whose map another method makes
    /// ([`mapper`](Self::mapper) is not [`method`](Self::method)), the
    /// final method's own error estimate decides how much of the pass
    /// follows that map and how much is spread evenly ([`map_weight`],
    /// MAP-CHECK). A fixed schedule pays one final reconstruction per
    /// adaptive pass for it; an open-ended render reuses the one it judges
    /// its stop by. Not with a temporal final denoiser
    /// ([`render_with_final`]), whose maps weigh what the filter knows and
    /// the frame alone does not. Default: the final method's
    /// [`crate::MethodInfo::map_check`].
    pub map_check: bool,
    /// The features of the renderers the loop makes itself (a sequence's
    /// frames, [`super::sequence::render_frames`]); a caller that makes its
    /// own [`Renderer`] chooses with [`Renderer::with_feature_samples`].
    /// Default: [`FeatureSamples::Shared`].
    pub feature_samples: FeatureSamples,
}

impl LoopConfig {
    /// A render of `spp` on average with `method` and its defaults: the
    /// prefilter and the outlier stage `Auto`, the maps of its
    /// [`crate::MethodInfo::map_method`] with that method's per-pass cap
    /// ([`default_pass_cap`]) and its [`crate::MethodInfo::map_check`],
    /// f32 kernels, no options, the fixed schedule.
    pub fn new(method: Method, spp: u32, adaptive: bool) -> Self {
        Self {
            spp,
            adaptive,
            method,
            map_method: None,
            prefilter: Prefilter::Auto,
            outliers: Outliers::Auto,
            precision: Precision::F32,
            options: Options::default(),
            pass_cap: None,
            stop: None,
            passes: None,
            temporal_maps: true,
            pyramid: Pyramid::Auto,
            input_blend: InputBlend::Auto,
            coarse_maps: false,
            map_check: method.info().map_check,
            feature_samples: FeatureSamples::Shared,
        }
        .with_map_method(None)
    }

    /// The same render with the adaptive passes' maps from `map` (`None`:
    /// the final method's [`crate::MethodInfo::map_method`]) and the
    /// per-pass cap of a render whose maps that method makes
    /// ([`default_pass_cap`]).
    pub fn with_map_method(mut self, map: Option<Method>) -> Self {
        self.map_method = map;
        self.pass_cap = default_pass_cap(self.mapper());
        self
    }

    /// The same render with the per-pass cap `k` as the command line gives
    /// it ([`parse_pass_cap`]): `None` keeps the cap, 0 removes it.
    pub fn with_pass_cap(mut self, k: Option<f64>) -> Self {
        if let Some(k) = k {
            self.pass_cap = (k > 0.0).then_some(k);
        }
        self
    }

    /// The method of the adaptive passes' maps.
    pub fn mapper(&self) -> Method {
        self.map_method
            .unwrap_or_else(|| self.method.info().map_method)
    }
}

/// When an open-ended render stops: at the first pass after which the
/// final reconstruction's estimated rMSE is at most `target_error`, at the
/// last pass that fits in `time_limit`, or when the average reaches
/// `max_spp`, whichever comes first.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct StopRules {
    /// Estimated rMSE of the final reconstruction to reach, as
    /// [`StopEstimates`] estimates it.
    pub target_error: Option<f64>,
    /// Wall time the render may take, reconstructions included.
    pub time_limit: Option<std::time::Duration>,
    /// Samples per pixel on average that the render never exceeds (at
    /// least 1).
    pub max_spp: u32,
}

/// The denoiser configuration of the loop's `pass` after a first pass of
/// `first_spp` samples per pixel: no pixel has `1 <= spp < 2` unless
/// `first_spp` is 1 (§0.4 step 3), as later passes only add.
fn loop_config(cfg: &LoopConfig, pass: Pass, first_spp: u32) -> Config {
    let mut c = Config::new(match pass {
        Pass::Intermediate => cfg.mapper(),
        Pass::Final => cfg.method,
    });
    c.pass = pass;
    c.prefilter = cfg.prefilter;
    c.outliers = cfg.outliers;
    c.precision = cfg.precision;
    c.options = cfg.options.clone();
    c.low_spp = first_spp < 2;
    c.coarse_map = pass == Pass::Intermediate && cfg.coarse_maps;
    (c.pyramid, c.input_blend) = if pass == Pass::Final {
        (cfg.pyramid, cfg.input_blend)
    } else {
        (Pyramid::Off, InputBlend::Off)
    };
    c
}

/// The slowest and fastest decay of the estimated error with the samples,
/// `e ∝ S^-α`, that the budget prediction assumes: regression errors fall
/// at `n^{-4/(d+4)}` (α ≥ 1/3 for d ≤ 8), Monte Carlo noise at `n^-1`;
/// adaptive passes can do a little better while they remove the worst
/// pixels' error.
const DECAY: (f64, f64) = (0.3, 1.5);

/// Most adaptive passes [`LoopConfig::passes`] may ask for: each costs a
/// reconstruction, and more than this many leave too few samples per pass
/// for a map to place.
pub const MAX_PASSES: u32 = 64;

/// The next open-ended pass's budget in samples: enough to reach `target`
/// if the estimate keeps falling as it did over the last two passes
/// (`history`: total samples and estimate after each pass; α = 1 after the
/// first), at least one sample per pixel, at most doubling the samples so
/// far, and never past `cap` in total.
pub fn next_budget(history: &[(f64, f64)], target: Option<f64>, pixels: usize, cap: u64) -> u64 {
    let &(spent, e) = history.last().expect("pass 0 has run");
    let spent_u = spent as u64;
    if spent_u >= cap {
        return 0;
    }
    let doubling = spent.max(pixels as f64);
    let want = match target {
        Some(t) if t > 0.0 && e > t => {
            let alpha = match history {
                [.., (s0, e0), (s1, e1)] if *s1 > *s0 && *e0 > 0.0 && *e1 > 0.0 => {
                    ((e0 / e1).ln() / (s1 / s0).ln()).clamp(DECAY.0, DECAY.1)
                }
                _ => 1.0,
            };
            let needed = spent * (e / t).powf(1.0 / alpha);
            (needed - spent).clamp(pixels as f64, doubling)
        }
        _ => doubling,
    };
    (want.ceil() as u64).min(cap - spent_u)
}

/// The rMSE an open-ended render judges `frame`, the reconstruction of the
/// final pass's `config`, by after pass 0: the method's estimate
/// ([`crate::metrics::estimated_rmse`]) times the configuration's
/// [`Config::error_scale`].
pub fn stop_estimate(config: &Config, frame: &Frame) -> f64 {
    let (w, h) = (frame.color.width, frame.color.height);
    config.error_scale(w, h) * crate::metrics::estimated_rmse(&frame.color, &frame.error)
}

/// The factor on the change estimate ([`StopEstimates`], STOP-CHANGE):
/// the 1/N law's factor is 1, and reconstructions whose error falls more
/// slowly than 1/N move less than it says.
pub const CHANGE_SCALE: f64 = 1.25;

/// An open-ended render's stop estimates, pass by pass (STOP-CHANGE).
///
/// After pass 0, the method's own estimate ([`stop_estimate`]). After a
/// later pass with `N` samples in all, how far the reconstruction `F_N`
/// moved since an earlier one `F_M` (the latest kept with `M ≤ N/2`, else
/// pass 0's): `CHANGE_SCALE · M/(N − M) · mean (F_M − F_N)² / (F_N² +
/// 0.01)`. For an error that falls as `1/N`, `E[(F_M − F_N)²] = E[e_M²] −
/// E[e_N²] = E[e_N²] (N − M)/M` (the newer samples are independent of the
/// older), so the change measures the error of the image the render has,
/// whatever the method's estimate misses or overstates. Reconstructions
/// are kept at least doubling apart, so at most a few are held at once.
#[derive(Default)]
pub struct StopEstimates {
    /// Earlier reconstructions' colour and total samples, oldest first.
    kept: Vec<(f64, RgbImage)>,
}

impl StopEstimates {
    /// The estimate after a pass that left `samples` in all and whose final
    /// reconstruction by `config` is `frame`, and whether it is a change
    /// estimate (the first one of those is no decay to extrapolate from
    /// the method's).
    pub fn estimate(&mut self, config: &Config, frame: &Frame, samples: f64) -> (f64, bool) {
        let base = self
            .kept
            .iter()
            .rposition(|(m, _)| *m <= samples / 2.0)
            .unwrap_or(0);
        self.kept.drain(..base);
        let (e, change) = match self.kept.first() {
            Some((m, older)) if *m < samples => {
                let moved = crate::metrics::rmse(older, &frame.color);
                (CHANGE_SCALE * m / (samples - m) * moved, true)
            }
            _ => (stop_estimate(config, frame), false),
        };
        if self.kept.last().map_or(true, |(m, _)| samples >= 2.0 * m) {
            self.kept.push((samples, frame.color.clone()));
        }
        (e, change)
    }
}

/// The per-pass cap of an adaptive render whose maps `method` makes
/// ([`LoopConfig::pass_cap`], [`crate::MethodInfo::pass_cap`]): 4× the
/// pass's mean for LP's and APR's own maps (LP-CAP, APR-CAP), none
/// otherwise.
pub fn default_pass_cap(method: Method) -> Option<f64> {
    method.info().pass_cap
}

/// A per-pass cap from the command line: 0 (no cap) or a finite number of
/// at least 1.
pub fn parse_pass_cap(s: &str) -> std::result::Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|k| *k == 0.0 || (*k >= 1.0 && k.is_finite()))
        .ok_or_else(|| "0 (no cap) or a number >= 1".to_string())
}

/// Caps `counts` at `cap` each and gives the excess to the pixels below the
/// cap in proportion to their counts (uniformly if those are all 0), with
/// the exact cumulative rounding of spec §9.2, until nothing exceeds the cap.
/// The total is unchanged; `cap · counts.len()` must be at least the total.
pub fn cap_counts(counts: &mut [u32], cap: u32) {
    let total: u64 = counts.iter().map(|&c| c as u64).sum();
    assert!(
        cap as u64 * counts.len() as u64 >= total,
        "a cap of {cap} cannot hold {total} samples in {} pixels",
        counts.len()
    );
    loop {
        let over: u64 = counts.iter().map(|&c| c.saturating_sub(cap) as u64).sum();
        if over == 0 {
            return;
        }
        for c in counts.iter_mut() {
            *c = (*c).min(cap);
        }
        let mut w: Vec<u128> = counts
            .iter()
            .map(|&c| if c < cap { c as u128 } else { 0 })
            .collect();
        if w.iter().all(|&x| x == 0) {
            w = counts.iter().map(|&c| (c < cap) as u128).collect();
        }
        for (c, add) in counts.iter_mut().zip(spread(over as u128, &w)) {
            *c += add;
        }
    }
}

/// `total` split in proportion to `weights` by the exact cumulative
/// rounding of spec §9.2 in raster order: the parts sum to exactly `total`
/// and each is the floor or the ceiling of its share. All parts are 0 when
/// the weights are.
fn spread(total: u128, weights: &[u128]) -> Vec<u32> {
    let sum: u128 = weights.iter().sum();
    if sum == 0 {
        return vec![0; weights.len()];
    }
    let (mut p, mut given) = (0u128, 0u128);
    weights
        .iter()
        .map(|&w| {
            p += w;
            let upto = total * p / sum;
            let part = (upto - given) as u32;
            given = upto;
            part
        })
        .collect()
}

/// Steps of [`map_weight`]'s grid: the share of an adaptive pass that
/// follows the map is a multiple of `1 / MIX_STEPS`.
pub const MIX_STEPS: u32 = 20;

/// MAP-CHECK: how many of [`MIX_STEPS`] parts of an adaptive pass follow
/// `map` (its counts, summing to the pass's budget), the rest spread
/// evenly ([`mix_counts`]), so that the final method's predicted error
/// after the pass is least. The prediction is `Σ_i e_i (n_i / (n_i +
/// c_i))^{a_i}`: `error` is the final method's estimated relative MSE of
/// each pixel now, `rate` the exponent `a_i` with which it falls with the
/// pixel's samples (`4/(d_i + 4)`, §9.1), `counts` the samples so far and
/// `c_i` what the mixture gives the pixel. Pixels without samples or with
/// a non-finite or non-positive error count for nothing; ties go to the
/// map.
pub fn map_weight(error: &[f64], rate: &[f64], counts: &[u64], map: &[u32]) -> u32 {
    let total: u64 = map.iter().map(|&m| m as u64).sum();
    let even = total as f64 / map.len().max(1) as f64;
    let used: Vec<usize> = (0..map.len())
        .filter(|&i| counts[i] > 0 && error[i].is_finite() && error[i] > 0.0)
        .collect();
    let predicted = |k: u32| -> f64 {
        let l = k as f64 / MIX_STEPS as f64;
        used.iter()
            .map(|&i| {
                let n = counts[i] as f64;
                let c = l * map[i] as f64 + (1.0 - l) * even;
                error[i] * (n / (n + c)).powf(rate[i])
            })
            .sum()
    };
    let p: Vec<f64> = (0..=MIX_STEPS).map(predicted).collect();
    let best = p.iter().copied().fold(f64::INFINITY, f64::min);
    (0..=MIX_STEPS)
        .rev()
        .find(|&k| p[k as usize] <= best * (1.0 + 1e-12))
        .unwrap_or(MIX_STEPS)
}

/// `k / MIX_STEPS` of `map` and the rest of its total spread evenly, as
/// counts with exactly `map`'s total (the cumulative rounding of §9.2 in
/// raster order: each pixel gets the floor or the ceiling of its share).
pub fn mix_counts(map: &[u32], k: u32) -> Vec<u32> {
    let n = map.len() as u128;
    let total: u128 = map.iter().map(|&m| m as u128).sum();
    let (k, s) = (k.min(MIX_STEPS) as u128, MIX_STEPS as u128);
    // Pixel i's share of the total is (k·m_i·n + (s − k)·total) / (s·n·total).
    let w: Vec<u128> = map
        .iter()
        .map(|&m| k * m as u128 * n + (s - k) * total)
        .collect();
    spread(total, &w)
}

/// The inputs of [`map_weight`] from a reconstruction by `method`: each
/// pixel's estimated relative MSE, `(1/3) Σ_ch max(E, 0) / (f̂² + ε)` with
/// the method's `ε` (§9.1), and the exponent `4/(d + 4)` of its decay.
fn judged(frame: &Frame, method: Method) -> (Vec<f64>, Vec<f64>) {
    let eps = method.info().sampling.eps as f64;
    let (c, e) = (&frame.color, &frame.error);
    let n = c.width * c.height;
    let error = (0..n)
        .map(|i| {
            (0..3)
                .map(|ch| {
                    let f = c.planes[ch][i] as f64;
                    (e.planes[ch][i] as f64).max(0.0) / (f * f + eps)
                })
                .sum::<f64>()
                / 3.0
        })
        .collect();
    let rate = (0..n)
        .map(|i| {
            let d = frame.dim.get(i).map_or(0.0, |&d| (d as f64).max(0.0));
            if d.is_finite() {
                4.0 / (d + 4.0)
            } else {
                1.0
            }
        })
        .collect();
    (error, rate)
}

/// GPU time of a render, split by what it was spent on (timestamp queries).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TimeSplit {
    /// Path tracing (`render_trace`).
    pub render_ms: f64,
    /// Finalisation, sanitation, prefilter and the method, every pass.
    pub reconstruction_ms: f64,
    /// The sample maps (`sample_*` and MAP-SMOOTH).
    pub sampling_ms: f64,
}

/// The result of [`render`].
#[derive(Debug)]
pub struct LoopResult {
    /// The final reconstruction (colour, error, …).
    pub frame: Frame,
    /// The adaptive schedule, when adaptive.
    pub schedule: Option<Schedule>,
    /// GPU time by purpose.
    pub split: TimeSplit,
    /// Every dispatch's GPU time.
    pub timings: Vec<KernelTiming>,
    /// Samples rendered in all.
    pub samples: u64,
    /// An open-ended render's stop estimate after its last pass
    /// ([`StopEstimates`]); `None` for a fixed schedule.
    pub estimate: Option<f64>,
    /// The share of each adaptive pass's samples that followed its map,
    /// the rest spread evenly ([`LoopConfig::map_check`]); empty when the
    /// maps are not checked.
    pub map_weights: Vec<f64>,
}

/// Where a render stands after a pass, for progress displays.
#[derive(Copy, Clone, Debug)]
pub struct PassProgress<'a> {
    /// Passes completed.
    pub done: usize,
    /// Passes in the render (rendering passes plus the final
    /// reconstruction); for an open-ended render, the passes so far plus one.
    pub total: usize,
    /// Samples per pixel so far, on average.
    pub spp: f64,
    /// An open-ended render's estimated rMSE of the final reconstruction
    /// after this pass.
    pub estimate: Option<f64>,
    /// That reconstruction.
    pub frame: Option<&'a Frame>,
}

fn add_split(split: &mut TimeSplit, timings: &[KernelTiming]) {
    let mut sampling = false;
    for t in timings {
        let ms = t.nanoseconds / 1e6;
        if t.kernel.starts_with("render_") {
            split.render_ms += ms;
        } else if t.kernel.starts_with("sample_") {
            sampling = true;
            split.sampling_ms += ms;
        } else if sampling {
            // MAP-SMOOTH (gauss_smooth) runs between sample_priority and the
            // allocation.
            split.sampling_ms += ms;
        } else {
            split.reconstruction_ms += ms;
        }
    }
}

/// Renders `renderer`'s scene as `cfg` says, into its (cleared)
/// accumulation buffer. `stop` is checked between passes: when set, the
/// render ends with [`Error::Interrupted`]. `progress` is called after each
/// pass.
pub fn render(
    ctx: &Arc<GpuContext>,
    renderer: &Renderer,
    cfg: &LoopConfig,
    stop: &AtomicBool,
    progress: impl FnMut(&PassProgress),
) -> Result<LoopResult> {
    render_with_final(ctx, renderer, cfg, stop, progress, None)
}

/// A denoiser for the final reconstruction of renders of `layout` with
/// `cfg`, and the temporal stage `temporal` ([`Config::temporal`]): what
/// [`render_with_final`] takes to carry a temporal filter's state from one
/// frame's render to the next.
pub fn final_denoiser(
    ctx: &Arc<GpuContext>,
    layout: crate::AccumLayout,
    cfg: &LoopConfig,
    temporal: crate::Temporal,
) -> Result<Denoiser> {
    Denoiser::new(ctx, Source::Accum(layout), final_config(cfg, temporal))
}

/// The configuration of a loop's final reconstruction with the temporal
/// stage `temporal` ([`final_denoiser`]; a [`crate::SequenceDenoiser`]'s
/// with [`crate::Temporal::Apr`]).
pub fn final_config(cfg: &LoopConfig, temporal: crate::Temporal) -> crate::Config {
    // Sanitation's step for 1 <= spp < 2 runs (it changes nothing where
    // every pixel has 0 or at least 2 samples): one denoiser for any
    // schedule.
    let mut c = loop_config(cfg, Pass::Final, 1);
    c.temporal = temporal;
    c
}

/// [`render`], with the final reconstruction by `last` (made by
/// [`final_denoiser`] for the renderer's layout) when given: its temporal
/// stage, if any, then filters this render as the next frame of its
/// sequence, and the adaptive passes' maps read its state
/// ([`LoopConfig::temporal_maps`]). Open-ended renders
/// ([`LoopConfig::stop`]) judge their passes with a denoiser of their own
/// and give `last` the final statistics once.
pub fn render_with_final(
    ctx: &Arc<GpuContext>,
    renderer: &Renderer,
    cfg: &LoopConfig,
    stop: &AtomicBool,
    progress: impl FnMut(&PassProgress),
    last: Option<&Denoiser>,
) -> Result<LoopResult> {
    run(ctx, renderer, cfg, stop, progress, Final::Reconstruct(last))
}

/// [`render`]'s passes without its final reconstruction, for a caller
/// that reconstructs the statistics itself (APR's temporal window): the
/// result's frame is [`Frame::empty`]. Open-ended renders
/// ([`LoopConfig::stop`]) judge every pass by a reconstruction and make
/// the final one as [`render`] does.
pub fn render_passes(
    ctx: &Arc<GpuContext>,
    renderer: &Renderer,
    cfg: &LoopConfig,
    stop: &AtomicBool,
    progress: impl FnMut(&PassProgress),
) -> Result<LoopResult> {
    run(ctx, renderer, cfg, stop, progress, Final::Skip)
}

/// What a render does after its last pass.
#[derive(Copy, Clone)]
enum Final<'a> {
    /// Reconstructs, with the caller's denoiser or one of its own.
    Reconstruct(Option<&'a Denoiser>),
    /// Nothing ([`render_passes`]).
    Skip,
}

impl<'a> Final<'a> {
    /// The caller's final denoiser, if it gave one.
    fn denoiser(self) -> Option<&'a Denoiser> {
        match self {
            Final::Reconstruct(d) => d,
            Final::Skip => None,
        }
    }
}

fn run(
    ctx: &Arc<GpuContext>,
    renderer: &Renderer,
    cfg: &LoopConfig,
    stop: &AtomicBool,
    progress: impl FnMut(&PassProgress),
    last: Final,
) -> Result<LoopResult> {
    check_coarse_maps(renderer, cfg, last)?;
    let run = Runner {
        ctx,
        renderer,
        cfg,
        stop,
        last,
        timings: Vec::new(),
        split: TimeSplit::default(),
        samples: 0,
        counts: Vec::new(),
        map_weights: Vec::new(),
    };
    match cfg.stop {
        None => run.fixed(progress),
        Some(rules) => run.open(rules, progress),
    }
}

/// Refuses, before anything renders, a render whose adaptive passes'
/// coarse maps ([`LoopConfig::coarse_maps`]) could not run: the adaptive
/// passes' configuration, checked as their denoiser would check it (too
/// small an image; the caller's temporal state, [`LoopConfig::temporal_maps`],
/// which a coarse map does not read).
fn check_coarse_maps(renderer: &Renderer, cfg: &LoopConfig, last: Final) -> Result<()> {
    let layout = renderer.layout();
    pass_config(cfg, last, Pass::Intermediate, 1).check_coarse_map(layout.width, layout.height)
}

/// The configuration of the loop's denoiser for `pass` ([`loop_config`]),
/// whose adaptive passes read the temporal state of the caller's final
/// denoiser when there is one and [`LoopConfig::temporal_maps`] is on.
fn pass_config(cfg: &LoopConfig, last: Final, pass: Pass, first_spp: u32) -> Config {
    let mut c = loop_config(cfg, pass, first_spp);
    if let (Pass::Intermediate, true, Some(last)) = (pass, cfg.temporal_maps, last.denoiser()) {
        if let Some(state) = last.temporal_state() {
            c.temporal = last.config().temporal;
            c.temporal_state = Some(state);
        }
    }
    c
}

/// One render's state: what it has spent and timed.
struct Runner<'a> {
    ctx: &'a Arc<GpuContext>,
    renderer: &'a Renderer,
    cfg: &'a LoopConfig,
    stop: &'a AtomicBool,
    /// The final reconstruction: the caller's denoiser
    /// ([`render_with_final`]), one of its own, or none after a fixed
    /// schedule ([`render_passes`]).
    last: Final<'a>,
    timings: Vec<KernelTiming>,
    split: TimeSplit,
    /// Samples rendered so far.
    samples: u64,
    /// Each pixel's samples so far, kept when the maps are checked
    /// ([`Runner::checks`]).
    counts: Vec<u64>,
    /// The share of each adaptive pass that followed its map (MAP-CHECK).
    map_weights: Vec<f64>,
}

impl Runner<'_> {
    fn pixels(&self) -> usize {
        self.renderer.layout().pixels()
    }

    fn spp(&self) -> f64 {
        self.samples as f64 / self.pixels() as f64
    }

    /// Whether the final method checks each adaptive pass's map
    /// ([`LoopConfig::map_check`]).
    fn checks(&self) -> bool {
        let temporal = self
            .last
            .denoiser()
            .is_some_and(|d| d.config().temporal != crate::Temporal::Off);
        self.cfg.map_check && self.cfg.adaptive && self.cfg.mapper() != self.cfg.method && !temporal
    }

    /// A denoiser of the loop's configuration for `pass`, on the renderer's
    /// planes. Pass 0 gives every pixel at least `first_spp` samples and
    /// later passes only add: no pixel has `1 <= spp < 2` unless
    /// `first_spp` is 1 (§0.4 step 3).
    fn denoiser(&self, pass: Pass, first_spp: u32) -> Result<Denoiser> {
        let c = pass_config(self.cfg, self.last, pass, first_spp);
        Denoiser::new(self.ctx, Source::Accum(self.renderer.layout()), c)
    }

    /// Records, submits and times one batch.
    fn submit(&mut self, record: &mut dyn FnMut(&mut Batch) -> Result<()>) -> Result<()> {
        if self.stop.load(Ordering::SeqCst) {
            return Err(Error::Interrupted);
        }
        let mut batch = Batch::new(self.ctx)?;
        record(&mut batch)?;
        let t = batch.finish()?;
        add_split(&mut self.split, &t);
        self.timings.extend(t);
        Ok(())
    }

    /// Pass 0: `spp` uniform samples per pixel on cleared planes.
    fn first_pass(&mut self, spp: u32) -> Result<()> {
        let r = self.renderer;
        self.submit(&mut |b| {
            r.record_clear(b);
            r.record_pass(b, Samples::Uniform(spp))
        })?;
        self.samples = spp as u64 * self.pixels() as u64;
        if self.checks() {
            self.counts = vec![spp as u64; self.pixels()];
        }
        Ok(())
    }

    /// One adaptive pass: `intermediate`'s reconstruction and sample map for
    /// `budget`, mixed with an even spread as the final method's
    /// reconstruction `judge` says (MAP-CHECK, when given) and capped as
    /// the configuration says, then the samples. Returns the wall seconds
    /// of the map (reconstruction, check and cap).
    fn adaptive_pass(
        &mut self,
        intermediate: &Denoiser,
        capped: Option<&GpuBuffer>,
        budget: u32,
        judge: Option<&Frame>,
    ) -> Result<f64> {
        let pixels = self.pixels();
        let r = self.renderer;
        let t = Instant::now();
        self.submit(&mut |b| intermediate.record(b, Some(r.accum()), Some(budget)))?;
        let map = intermediate
            .outputs()?
            .samples
            .ok_or_else(|| Error::Limit("this device cannot compute sample maps".into()))?;
        let pass_map = match capped {
            Some(buf) if judge.is_some() || self.cfg.pass_cap.is_some() => {
                // Checking and capping need the counts on the host: one
                // small readback per pass.
                let mut counts: Vec<u32> = crate::gpu::buffer::read_slice(self.ctx, map, pixels)?
                    .iter()
                    .map(|v| v.to_bits())
                    .collect();
                if let Some(frame) = judge {
                    let (error, rate) = judged(frame, self.cfg.method);
                    let k = map_weight(&error, &rate, &self.counts, &counts);
                    self.map_weights.push(k as f64 / MIX_STEPS as f64);
                    counts = mix_counts(&counts, k);
                }
                if let Some(k) = self.cfg.pass_cap {
                    let mean = budget as f64 / pixels as f64;
                    cap_counts(&mut counts, (k * mean).ceil().max(1.0) as u32);
                }
                if !self.counts.is_empty() {
                    for (n, &c) in self.counts.iter_mut().zip(&counts) {
                        *n += c as u64;
                    }
                }
                buf.upload(0, bytemuck::cast_slice(&counts))?;
                buf.slice()
            }
            _ => map,
        };
        let map_secs = t.elapsed().as_secs_f64();
        // The map sums to exactly the budget (§9.2), and capping keeps the
        // total: the pass traces `budget` samples.
        self.submit(&mut |b| {
            r.record_pass(
                b,
                Samples::Map {
                    map: pass_map,
                    total: budget,
                },
            )
        })?;
        self.samples += budget as u64;
        Ok(map_secs)
    }

    /// The buffer of checked or capped counts, when the configuration
    /// checks or caps.
    fn capped_buffer(&self) -> Result<Option<GpuBuffer>> {
        match self.cfg.pass_cap.is_some() || self.checks() {
            true => Ok(Some(GpuBuffer::new(
                self.ctx,
                "loop.capped_map",
                (self.pixels() * 4) as u64,
            )?)),
            false => Ok(None),
        }
    }

    /// `last`'s reconstruction of the planes as they are.
    fn reconstruct(&mut self, last: &Denoiser) -> Result<Frame> {
        let r = self.renderer;
        self.submit(&mut |b| last.record(b, Some(r.accum()), None))?;
        last.read()
    }

    fn result(self, frame: Frame, schedule: Option<Schedule>) -> LoopResult {
        LoopResult {
            frame,
            schedule,
            split: self.split,
            timings: self.timings,
            samples: self.samples,
            estimate: None,
            map_weights: self.map_weights,
        }
    }

    /// The spec's fixed schedule (§9.3), or `spp` uniform samples in one
    /// pass.
    fn fixed(mut self, mut progress: impl FnMut(&PassProgress)) -> Result<LoopResult> {
        let cfg = self.cfg;
        let schedule = if cfg.adaptive {
            Some(match cfg.passes {
                Some(n) => {
                    let rest = cfg.spp.saturating_sub(INITIAL_SPP) as u64 * self.pixels() as u64;
                    if n > MAX_PASSES || n as u64 > rest.max(1) {
                        return Err(Error::InvalidArgument(format!(
                            "{n} adaptive passes: at most {MAX_PASSES}, and no more than the {rest} samples left after pass 0"
                        )));
                    }
                    Schedule::new(cfg.spp, self.pixels(), INITIAL_SPP, n)?
                }
                None => Schedule::for_method(cfg.mapper(), cfg.spp, self.pixels())?,
            })
        } else {
            None
        };
        let first_spp = schedule.as_ref().map_or(cfg.spp, |s| s.initial_spp);
        let total = 2 + schedule.as_ref().map_or(0, |s| s.budgets.len());
        let mut report = |runner: &Runner, done: usize| {
            progress(&PassProgress {
                done,
                total,
                spp: runner.spp(),
                estimate: None,
                frame: None,
            })
        };
        self.first_pass(first_spp)?;
        let mut done = 1;
        report(&self, done);
        // The final method's own denoiser, when it checks the maps (not
        // the caller's: a temporal filter's state must see only the final
        // statistics).
        let judge = match self.checks() {
            true => Some(self.denoiser(Pass::Final, first_spp)?),
            false => None,
        };
        if let Some(s) = &schedule {
            let intermediate = self.denoiser(Pass::Intermediate, first_spp)?;
            let capped = self.capped_buffer()?;
            for &budget in &s.budgets {
                let frame = match &judge {
                    Some(j) => Some(self.reconstruct(j)?),
                    None => None,
                };
                self.adaptive_pass(&intermediate, capped.as_ref(), budget, frame.as_ref())?;
                done += 1;
                report(&self, done);
            }
        }
        let frame = match (self.last, &judge) {
            (Final::Skip, _) => Frame::empty(),
            (Final::Reconstruct(Some(last)), _) => self.reconstruct(last)?,
            (Final::Reconstruct(None), Some(j)) => self.reconstruct(j)?,
            (Final::Reconstruct(None), None) => {
                let last = self.denoiser(Pass::Final, first_spp)?;
                self.reconstruct(&last)?
            }
        };
        report(&self, total);
        Ok(self.result(frame, schedule))
    }

    /// Open-ended: passes until a stop rule holds (see [`StopRules`]).
    fn open(
        mut self,
        rules: StopRules,
        mut progress: impl FnMut(&PassProgress),
    ) -> Result<LoopResult> {
        let started = Instant::now();
        let pixels = self.pixels();
        let cap = rules.max_spp.max(1) as u64 * pixels as u64;
        let first_spp = INITIAL_SPP.min(rules.max_spp.max(1));
        let last = self.denoiser(Pass::Final, first_spp)?;
        let intermediate = match self.cfg.adaptive {
            true => Some(self.denoiser(Pass::Intermediate, first_spp)?),
            false => None,
        };
        let capped = self.capped_buffer()?;
        let t = Instant::now();
        self.first_pass(first_spp)?;
        // Seconds per sample of the last pass's rendering.
        let mut per_sample = t.elapsed().as_secs_f64() / self.samples as f64;
        let mut history: Vec<(f64, f64)> = Vec::new();
        let mut estimates = StopEstimates::default();
        // Wall seconds of the last adaptive pass's sample map.
        let mut map_secs: Option<f64> = None;
        let mut done = 1;
        loop {
            let t = Instant::now();
            let frame = self.reconstruct(&last)?;
            let overhead = t.elapsed().as_secs_f64();
            let (e, change) = estimates.estimate(last.config(), &frame, self.samples as f64);
            if change && history.len() == 1 {
                // Pass 0's estimate is the method's: no decay to fit across.
                history.clear();
            }
            history.push((self.samples as f64, e));
            progress(&PassProgress {
                done,
                total: done + 1,
                spp: self.spp(),
                estimate: Some(e),
                frame: Some(&frame),
            });
            let met = rules.target_error.is_some_and(|t| e <= t);
            let mut budget = next_budget(&history, rules.target_error, pixels, cap);
            if let (Some(limit), false) = (rules.time_limit, met) {
                // The next pass: its map, when adaptive (as long as the
                // last one took; before the first, as long as the check),
                // its samples at the rate so far, and the check.
                let map = match &intermediate {
                    Some(_) => map_secs.unwrap_or(overhead),
                    None => 0.0,
                };
                let left = limit.as_secs_f64() - started.elapsed().as_secs_f64() - overhead - map;
                let fits = (left / per_sample).max(0.0) as u64;
                budget = budget.min(fits / pixels as u64 * pixels as u64);
            }
            if met || budget < pixels as u64 {
                let frame = match self.last.denoiser() {
                    Some(l) => self.reconstruct(l)?,
                    None => frame,
                };
                return Ok(LoopResult {
                    estimate: Some(e),
                    ..self.result(frame, None)
                });
            }
            let before = self.samples;
            let t = Instant::now();
            let mut map = 0.0;
            match &intermediate {
                Some(d) => {
                    let budget = u32::try_from(budget).unwrap_or(u32::MAX);
                    let judge = self.checks().then_some(&frame);
                    map = self.adaptive_pass(d, capped.as_ref(), budget, judge)?;
                    map_secs = Some(map);
                }
                None => {
                    let spp = u32::try_from(budget / pixels as u64).unwrap_or(u32::MAX);
                    let r = self.renderer;
                    self.submit(&mut |b| r.record_pass(b, Samples::Uniform(spp)))?;
                    self.samples += spp as u64 * pixels as u64;
                }
            }
            per_sample = (t.elapsed().as_secs_f64() - map) / (self.samples - before) as f64;
            done += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{cap_counts, map_weight, mix_counts, MIX_STEPS};

    #[test]
    fn a_mixture_keeps_the_total_and_its_ends() {
        let map = [0u32, 7, 0, 30, 1, 0, 0, 2, 9];
        let total: u32 = map.iter().sum();
        for k in 0..=MIX_STEPS {
            let c = mix_counts(&map, k);
            assert_eq!(c.iter().sum::<u32>(), total, "k = {k}");
        }
        assert_eq!(mix_counts(&map, MIX_STEPS), map);
        // 49 samples over 9 pixels: 5 or 6 each.
        let even = mix_counts(&map, 0);
        assert!(even.iter().all(|&c| c == 5 || c == 6), "{even:?}");
        // Half the map, half spread: each pixel within one of its share.
        let half = mix_counts(&map, MIX_STEPS / 2);
        for (h, &m) in half.iter().zip(&map) {
            let share = 0.5 * m as f64 + 0.5 * total as f64 / 9.0;
            assert!((*h as f64 - share).abs() < 1.0, "{h} against {share}");
        }
    }

    #[test]
    fn the_map_is_kept_where_the_final_method_agrees_and_spread_where_not() {
        let n = 64;
        let counts = vec![4u64; n];
        let rate = vec![0.5; n];
        // The map puts everything on the first quarter.
        let map: Vec<u32> = (0..n).map(|i| if i < n / 4 { 16 } else { 0 }).collect();
        // The final method's error is there too: follow the map.
        let agree: Vec<f64> = (0..n).map(|i| if i < n / 4 { 1.0 } else { 0.01 }).collect();
        assert_eq!(map_weight(&agree, &rate, &counts, &map), MIX_STEPS);
        // Its error is flat: spread evenly (the prediction is convex).
        let flat = vec![1.0; n];
        assert_eq!(map_weight(&flat, &rate, &counts, &map), 0);
        // Its error is elsewhere: spread evenly too.
        let other: Vec<f64> = agree.iter().map(|e| 1.01 - e).collect();
        assert_eq!(map_weight(&other, &rate, &counts, &map), 0);
        // Somewhere between: a mixture.
        let some: Vec<f64> = (0..n).map(|i| if i < n / 4 { 2.0 } else { 1.0 }).collect();
        let k = map_weight(&some, &rate, &counts, &map);
        assert!(0 < k && k < MIX_STEPS, "{k}");
        // Pixels without samples or with no usable error count for nothing.
        let mut odd = agree.clone();
        odd[n - 1] = f64::NAN;
        odd[n - 2] = -1.0;
        let mut c = counts.clone();
        c[n - 3] = 0;
        assert_eq!(map_weight(&odd, &rate, &c, &map), MIX_STEPS);
    }

    #[test]
    fn cap_keeps_the_total_and_the_cap() {
        let mut rng = 12345u64;
        for n in [1usize, 7, 100, 1000] {
            for cap in [1u32, 3, 10, 50] {
                let mut c: Vec<u32> = (0..n)
                    .map(|_| {
                        rng = rng
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        let r = (rng >> 33) % 100;
                        if r < 3 {
                            (r * 1000) as u32
                        } else {
                            (r % 5) as u32
                        }
                    })
                    .collect();
                let total: u64 = c.iter().map(|&x| x as u64).sum();
                if cap as u64 * n as u64 >= total {
                    let zeros: Vec<bool> = c.iter().map(|&x| x == 0).collect();
                    cap_counts(&mut c, cap);
                    assert_eq!(c.iter().map(|&x| x as u64).sum::<u64>(), total);
                    assert!(c.iter().all(|&x| x <= cap), "n {n} cap {cap}: {c:?}");
                    // Pixels the map gave nothing keep nothing unless every
                    // pixel below the cap had nothing.
                    if c.iter().zip(&zeros).any(|(&x, &z)| !z && x < cap) {
                        assert!(c.iter().zip(&zeros).all(|(&x, &z)| !z || x == 0));
                    }
                }
            }
        }
    }
}
