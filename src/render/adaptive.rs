//! The adaptive loop of the papers (spec §9.3) on the built-in renderer,
//! through the public facade only: pass 0 renders `s_0` uniform samples per
//! pixel; each adaptive pass reconstructs (intermediate windows), turns the
//! error into a sample map for its budget and renders that many samples where
//! the map says; the final pass reconstructs with the final windows. The
//! statistics, error maps and sample maps stay on the GPU between passes
//! (one submission sequence per pass, so a stop request is honoured between
//! passes); only the final image comes back.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use super::{Renderer, Samples};
use crate::{
    Batch, Config, Denoiser, Error, Frame, GpuContext, KernelTiming, Method, Options, Outliers,
    Pass, Precision, Prefilter, Result, Schedule, Source,
};

/// What to render and how.
#[derive(Clone, Debug)]
pub struct LoopConfig {
    /// Average samples per pixel of the whole render (≥ 4 when adaptive).
    pub spp: u32,
    /// Adaptive passes (§9.3) or `spp` uniform samples in one pass.
    pub adaptive: bool,
    /// Reconstruction of the final image (and, when adaptive, of the
    /// intermediate passes). `none`: the plain Monte Carlo mean (adaptive
    /// `none` samples where the input variance is).
    pub method: Method,
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
}

/// The per-pass cap a method's adaptive render uses by default
/// ([`LoopConfig::pass_cap`], [`crate::MethodInfo::pass_cap`]): 4× the
/// pass's mean for LP (LP-CAP), none otherwise.
pub fn default_pass_cap(method: Method) -> Option<f64> {
    method.info().pass_cap
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
        let mut w: Vec<u64> = counts
            .iter()
            .map(|&c| if c < cap { c as u64 } else { 0 })
            .collect();
        if w.iter().all(|&x| x == 0) {
            w = counts.iter().map(|&c| (c < cap) as u64).collect();
        }
        let sum: u64 = w.iter().sum();
        let (mut p, mut given) = (0u64, 0u64);
        for (c, &wi) in counts.iter_mut().zip(&w) {
            p += wi;
            let upto = (over as u128 * p as u128 / sum as u128) as u64;
            *c += (upto - given) as u32;
            given = upto;
        }
    }
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
}

/// Where a pass stands, for progress displays.
#[derive(Copy, Clone, Debug)]
pub struct PassProgress {
    /// Passes completed.
    pub done: usize,
    /// Passes in the render (rendering passes plus the final reconstruction).
    pub total: usize,
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
    mut progress: impl FnMut(PassProgress),
) -> Result<LoopResult> {
    let layout = renderer.layout();
    let pixels = layout.pixels();
    let schedule = if cfg.adaptive {
        Some(Schedule::for_method(cfg.method, cfg.spp, pixels)?)
    } else {
        None
    };
    let first_spp = schedule.as_ref().map_or(cfg.spp, |s| s.initial_spp);
    let config = |pass: Pass| {
        let mut c = Config::new(cfg.method);
        c.pass = pass;
        c.prefilter = cfg.prefilter;
        c.outliers = cfg.outliers;
        c.precision = cfg.precision;
        c.options = cfg.options.clone();
        // Pass 0 gives every pixel `first_spp` samples and later passes only
        // add: no pixel has 1 <= spp < 2 unless `first_spp` is 1 (§0.4 step 3).
        c.low_spp = first_spp < 2;
        c
    };
    let total = 2 + schedule.as_ref().map_or(0, |s| s.budgets.len());
    let mut timings = Vec::new();
    let mut split = TimeSplit::default();
    let mut run = |record: &mut dyn FnMut(&mut Batch) -> Result<()>| -> Result<()> {
        if stop.load(Ordering::SeqCst) {
            return Err(Error::Interrupted);
        }
        let mut batch = Batch::new(ctx)?;
        record(&mut batch)?;
        let t = batch.finish()?;
        add_split(&mut split, &t);
        timings.extend(t);
        Ok(())
    };
    let mut done = 0;
    // Pass 0: uniform.
    run(&mut |b| {
        renderer.record_clear(b);
        renderer.record_pass(b, Samples::Uniform(first_spp))
    })?;
    done += 1;
    progress(PassProgress { done, total });
    if let Some(s) = &schedule {
        let intermediate = Denoiser::new(ctx, Source::Accum(layout), config(Pass::Intermediate))?;
        let map = intermediate
            .outputs()?
            .samples
            .ok_or_else(|| Error::Limit("this device cannot compute sample maps".into()))?;
        let capped = match cfg.pass_cap {
            Some(_) => Some(crate::gpu::GpuBuffer::new(
                ctx,
                "loop.capped_map",
                (pixels * 4) as u64,
            )?),
            None => None,
        };
        for &budget in &s.budgets {
            run(&mut |b| intermediate.record(b, Some(renderer.accum()), Some(budget)))?;
            // The largest count sets how many chunk dispatches the pass takes
            // (render::RENDER_CHUNK): one small readback per pass.
            let mut counts: Vec<u32> = crate::gpu::buffer::read_slice(ctx, map, pixels)?
                .iter()
                .map(|v| v.to_bits())
                .collect();
            let pass_map = match (cfg.pass_cap, &capped) {
                (Some(k), Some(buf)) => {
                    let mean = budget as f64 / pixels as f64;
                    cap_counts(&mut counts, (k * mean).ceil().max(1.0) as u32);
                    buf.upload(0, bytemuck::cast_slice(&counts))?;
                    buf.slice()
                }
                _ => map,
            };
            let max = counts.iter().copied().max().unwrap_or(0);
            run(&mut |b| renderer.record_pass(b, Samples::Map(pass_map, max)))?;
            done += 1;
            progress(PassProgress { done, total });
        }
    }
    let last = Denoiser::new(ctx, Source::Accum(layout), config(Pass::Final))?;
    run(&mut |b| last.record(b, Some(renderer.accum()), None))?;
    progress(PassProgress { done: total, total });
    Ok(LoopResult {
        frame: last.read()?,
        schedule,
        split,
        timings,
    })
}

#[cfg(test)]
mod tests {
    use super::cap_counts;

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
