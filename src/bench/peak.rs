//! The device's limits for the roofline of `mcdenoise bench` (issue #13):
//! arithmetic peak from `peak_fma` (f32, and f64 where the device has it)
//! and memory bandwidth from `peak_copy`, each as min / median / max over
//! timed runs after one warm-up, from the kernels' GPU timestamps.

use std::sync::Arc;

use super::median;
use crate::error::{Error, Result};
use crate::gpu::{Batch, GpuBuffer, GpuContext, KernelTiming, Precision};
use crate::kernels::{peak_copy, peak_fma};
use crate::shared::PeakPush;

/// Invocations per row of the FMA grid.
pub const FMA_WIDTH: u32 = 4096;
/// Rows of the FMA grid.
pub const FMA_ROWS: u32 = 64;
/// FMA rounds per invocation: with [`FMA_WIDTH`] × [`FMA_ROWS`] invocations,
/// 4.3 GFLOP a run.
pub const FMA_ITERATIONS: u32 = 256;
/// Words per row of the copy.
pub const COPY_WIDTH: u32 = 4096;
/// Rows of the copy: 8 Mi words, 32 MiB per buffer (well under lavapipe's
/// 128 MiB `maxStorageBufferRange`), 64 MiB across memory a run.
pub const COPY_ROWS: u32 = 2048;

/// Min, median and max of a measure over the runs.
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct Spread {
    /// Smallest run.
    pub min: f64,
    /// Median run.
    pub median: f64,
    /// Largest run.
    pub max: f64,
}

impl Spread {
    /// Of a non-empty list.
    pub fn of(v: &[f64]) -> Spread {
        Spread {
            min: v.iter().copied().fold(f64::INFINITY, f64::min),
            median: median(v),
            max: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// The measured limits.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Peak {
    /// Timed runs per measure.
    pub runs: usize,
    /// f32 FMA rate, GFLOP/s.
    pub fma_f32: Spread,
    /// f64 FMA rate, GFLOP/s (`None` without `shaderFloat64`).
    pub fma_f64: Option<Spread>,
    /// Copy bandwidth, GB/s (10⁹ bytes read + written per second).
    pub copy: Spread,
}

impl Peak {
    /// The median FMA peak of a kernel variant: f64 for a `_f64` kernel.
    pub fn flops_for(&self, kernel: &str) -> Option<f64> {
        if kernel.ends_with("_f64") {
            self.fma_f64.map(|s| s.median)
        } else {
            Some(self.fma_f32.median)
        }
    }

    /// The measures as a Markdown table (GFLOP/s and GB/s).
    pub fn to_markdown(&self) -> String {
        let mut rows: Vec<Vec<String>> = vec![
            ["device limit", "min", "median", "max"]
                .map(String::from)
                .to_vec(),
            ["---", "---:", "---:", "---:"].map(String::from).to_vec(),
        ];
        let mut row = |name: &str, s: &Spread| {
            rows.push(vec![
                name.into(),
                format!("{:.2}", s.min),
                format!("{:.2}", s.median),
                format!("{:.2}", s.max),
            ])
        };
        row("FMA f32 GFLOP/s (`peak_fma`)", &self.fma_f32);
        if let Some(s) = &self.fma_f64 {
            row("FMA f64 GFLOP/s (`peak_fma_f64`)", s);
        }
        row("copy GB/s (`peak_copy`)", &self.copy);
        super::report::markdown_table(&rows)
    }
}

/// GFLOP/s of one call's timings: counted flops over GPU time.
fn rate(t: &[KernelTiming]) -> f64 {
    let ns: f64 = t.iter().map(|k| k.nanoseconds).sum();
    t.iter().map(|k| k.flops).sum::<f64>() / ns.max(1e-9)
}

/// Measures the limits with `runs` timed runs each (after one warm-up).
///
/// # Errors
/// `runs` is 0, the device gives no timestamps, or a dispatch fails.
pub fn measure_peak(ctx: &Arc<GpuContext>, runs: usize) -> Result<Peak> {
    if runs == 0 {
        return Err(Error::InvalidArgument(
            "the peak needs at least one run".into(),
        ));
    }
    if ctx.info.timestamp_period_ns <= 0.0 {
        return Err(Error::InvalidArgument(
            "the device has no compute timestamps: the peak cannot be measured".into(),
        ));
    }
    // One warm-up, then `runs` timed calls; `measure` turns a call's
    // timings into the figure.
    let sample = |record: &dyn Fn(&mut Batch) -> Result<()>,
                  measure: &dyn Fn(&[KernelTiming]) -> f64|
     -> Result<Spread> {
        let mut v = Vec::with_capacity(runs);
        for run in 0..=runs {
            let mut batch = Batch::new(ctx)?;
            record(&mut batch)?;
            let t = batch.finish()?;
            if run > 0 {
                v.push(measure(&t));
            }
        }
        Ok(Spread::of(&v))
    };
    let out = GpuBuffer::new(ctx, "peak.fma", (FMA_WIDTH * FMA_ROWS) as u64 * 4)?;
    let fma_push = PeakPush {
        width: FMA_WIDTH,
        height: FMA_ROWS,
        iterations: FMA_ITERATIONS,
        ..Default::default()
    };
    let fma = |precision: Precision| {
        sample(
            &|b| peak_fma::record(b, precision, &fma_push, out.slice()),
            &rate,
        )
    };
    let fma_f32 = fma(Precision::F32)?;
    let fma_f64 = if ctx.supports_f64() {
        Some(fma(Precision::F64)?)
    } else {
        None
    };
    let words = (COPY_WIDTH * COPY_ROWS) as u64;
    let src = GpuBuffer::new(ctx, "peak.src", words * 4)?;
    let dst = GpuBuffer::new(ctx, "peak.dst", words * 4)?;
    let copy_push = PeakPush {
        width: COPY_WIDTH,
        height: COPY_ROWS,
        ..Default::default()
    };
    let copy = sample(
        &|b| peak_copy::record(b, Precision::F32, &copy_push, src.slice(), dst.slice()),
        &|t| {
            let ns: f64 = t.iter().map(|k| k.nanoseconds).sum();
            words as f64 * peak_copy::BYTES_PER_WORD / ns.max(1e-9)
        },
    )?;
    Ok(Peak {
        runs,
        fma_f32,
        fma_f64,
        copy,
    })
}
