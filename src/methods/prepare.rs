//! Input sanitation of a whole frame (spec §0.4), on the GPU or the CPU.
//!
//! Per scalar channel of every mean layer: stage 0 (non-finite values, variance
//! clamp), then stage 1 (variance of spp < 2 pixels) when the variance layer
//! exists, or stage 2 (variance estimated from the image, step 4) when it does
//! not. `position_covariance` gets stage 0 only. The sample count is
//! normalised by `spp_of` (non-finite or < 1 → 0, an invalid pixel).

use std::path::Path;
use std::sync::Arc;

use super::stats::GpuStats;
use super::Backend;
use crate::error::{Error, Result};
use crate::gpu::{Batch, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::kernels::{sanitize, sanitize_quads};
use crate::reference::{sanitize::sanitize as sanitize_twin, spp_of};
use crate::shared::SanitizePush;

/// What sanitation repaired. Printed on stderr by the CLI (spec §0.4).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PrepareReport {
    /// Sums over all channels of the four counters of
    /// [`sanitize::COUNTERS`].
    pub counters: [u64; 4],
    /// Mean layers whose variance layer was missing and has been estimated.
    pub estimated: Vec<Layer>,
    /// Pixels with no valid sample count (n < 1, NaN or negative).
    pub invalid_pixels: usize,
    /// GPU time per dispatch of the sanitation (empty on the CPU).
    pub timings: Vec<crate::gpu::KernelTiming>,
}

impl PrepareReport {
    /// Lines for stderr: one per kind of repair that happened.
    pub fn messages(&self, input: &Path) -> Vec<String> {
        let mut out = Vec::new();
        for l in &self.estimated {
            out.push(format!(
                "{}: variance estimated from the image (no {} layer)",
                input.display(),
                l.variance().unwrap().name()
            ));
        }
        for (i, what) in sanitize::COUNTERS.iter().enumerate().take(3) {
            if self.counters[i] > 0 {
                out.push(format!("{}: {} {what}", input.display(), self.counters[i]));
            }
        }
        if self.invalid_pixels > 0 {
            out.push(format!(
                "{}: {} pixels without samples (spp < 1): filled from their neighbours",
                input.display(),
                self.invalid_pixels
            ));
        }
        out
    }
}

/// The layers sanitation produces from an input with `layers`: every mean
/// layer with its variance (estimated if absent), the covariance if present,
/// and the count.
pub fn output_layers(layers: &[Layer]) -> Vec<Layer> {
    let mut out = Vec::new();
    for &l in &Layer::WITH_VARIANCE {
        if layers.contains(&l) {
            out.push(l);
            out.push(l.variance().unwrap());
        }
    }
    if layers.contains(&Layer::PositionCovariance) {
        out.push(Layer::PositionCovariance);
    }
    out.push(Layer::Spp);
    out
}

fn check_input(img: &StatsImage) -> Result<()> {
    for l in [Layer::Color, Layer::Spp] {
        if !img.has(l) {
            return Err(Error::BadData(format!(
                "sanitation needs the {} layer",
                l.name()
            )));
        }
    }
    Ok(())
}

/// Sanitises `img` with the chosen backend. The GPU backend needs `ctx`.
pub fn prepare(
    ctx: Option<&Arc<GpuContext>>,
    backend: Backend,
    precision: Precision,
    img: &StatsImage,
) -> Result<(StatsImage, PrepareReport)> {
    check_input(img)?;
    match backend {
        Backend::Cpu => Ok(prepare_cpu(img)),
        Backend::Gpu => {
            let ctx = ctx
                .ok_or_else(|| Error::InvalidArgument("the GPU backend needs a context".into()))?;
            prepare_gpu(ctx, precision, img)
        }
    }
}

/// The report's parts known before running: estimated layers, invalid pixels.
pub fn base_report(img: &StatsImage) -> PrepareReport {
    let layers: Vec<Layer> = img.layers().map(|(l, _)| l).collect();
    PrepareReport {
        counters: [0; 4],
        estimated: Layer::WITH_VARIANCE
            .into_iter()
            .filter(|l| layers.contains(l) && !layers.contains(&l.variance().unwrap()))
            .collect(),
        invalid_pixels: img.get(Layer::Spp).unwrap()[0]
            .iter()
            .filter(|&&s| spp_of(s) < 1.0)
            .count(),
        timings: Vec::new(),
    }
}

/// The CPU path: the scalar twin, stage by stage, channel by channel.
pub fn prepare_cpu(img: &StatsImage) -> (StatsImage, PrepareReport) {
    let (w, h) = (img.width, img.height);
    let n = w * h;
    let mut report = base_report(img);
    let spp = &img.get(Layer::Spp).unwrap()[0];
    let mut out = StatsImage::new(w, h);
    let push = |stage: u32, has_var: bool| SanitizePush {
        width: w as u32,
        height: h as u32,
        stage,
        has_var: has_var as u32,
        ..Default::default()
    };
    let mut counters = [0u32; 4];
    for &layer in &Layer::WITH_VARIANCE {
        let Some(values) = img.get(layer) else {
            continue;
        };
        let vars = img.get(layer.variance().unwrap());
        let mut out_v = Vec::new();
        let mut out_var = Vec::new();
        for (c, value) in values.iter().enumerate() {
            let var_in = vars.map(|v| v[c].as_slice()).unwrap_or(value);
            let (mut a_val, mut a_var) = (vec![0.0; n], vec![0.0; n]);
            sanitize_twin(
                &push(0, vars.is_some()),
                value,
                var_in,
                spp,
                &mut a_val,
                &mut a_var,
                &mut counters,
            );
            let (mut b_val, mut b_var) = (vec![0.0; n], vec![0.0; n]);
            let stage = if vars.is_some() { 1 } else { 2 };
            sanitize_twin(
                &push(stage, vars.is_some()),
                &a_val,
                &a_var,
                spp,
                &mut b_val,
                &mut b_var,
                &mut counters,
            );
            out_v.push(b_val);
            out_var.push(b_var);
        }
        out.set(layer, out_v);
        out.set(layer.variance().unwrap(), out_var);
    }
    if let Some(cov) = img.get(Layer::PositionCovariance) {
        let mut planes = Vec::new();
        for p in cov {
            let (mut v, mut dummy) = (vec![0.0; n], vec![0.0; n]);
            sanitize_twin(
                &push(0, false),
                p,
                p,
                spp,
                &mut v,
                &mut dummy,
                &mut counters,
            );
            planes.push(v);
        }
        out.set(Layer::PositionCovariance, planes);
    }
    out.set(
        Layer::Spp,
        vec![spp.iter().map(|&s| spp_of(s) as f32).collect()],
    );
    for k in 0..4 {
        report.counters[k] += counters[k] as u64;
    }
    (out, report)
}

/// Bytes between the counter blocks of two channels (offset alignment).
const COUNTER_STRIDE: u64 = 256;

/// Planes of [`PrepareScratch`]: value and variance of one channel.
pub const PLANES: usize = 2;

/// GPU scratch for [`record_prepare`]: two ping-pong planes and the counters.
#[derive(Debug)]
pub struct PrepareScratch {
    /// Two planes of `width * height` f32, value and variance, that carry a
    /// channel between the sanitation stages.
    pub planes: PlaneSet,
    /// One 256-byte block per channel, each starting with the four u32 counters of
    /// [`sanitize::COUNTERS`].
    pub counters: GpuBuffer,
    /// Number of scalar channels sanitised: those of the layers with a variance
    /// companion, and the six of `position_covariance`.
    pub channels: usize,
}

impl PrepareScratch {
    /// Allocates the scratch for sanitising `input` (its size and layers):
    /// the [`PLANES`] planes at the start of `arena` when given (nothing of
    /// them is read after [`record_prepare`]), else a buffer of their own.
    pub fn new(
        ctx: &Arc<GpuContext>,
        input: &GpuStats,
        arena: Option<&Arc<GpuBuffer>>,
    ) -> Result<PrepareScratch> {
        let n = input.width * input.height;
        let channels: usize = input
            .index
            .iter()
            .filter(|(l, _)| Layer::WITH_VARIANCE.contains(l) || *l == Layer::PositionCovariance)
            .map(|(l, _)| l.channels().len())
            .sum();
        Ok(PrepareScratch {
            planes: match arena {
                Some(a) => PlaneSet::view(a, 0, n, PLANES)?,
                None => PlaneSet::new(ctx, "prepare.scratch", n, PLANES)?,
            },
            counters: GpuBuffer::new(
                ctx,
                "prepare.counters",
                COUNTER_STRIDE * channels.max(1) as u64,
            )?,
            channels,
        })
    }

    /// Sums the counters after the work has completed.
    pub fn read_counters(&self) -> Result<[u64; 4]> {
        let raw: Vec<u32> = self
            .counters
            .read_vec((COUNTER_STRIDE / 4) as usize * self.channels.max(1))?;
        let mut out = [0u64; 4];
        for c in 0..self.channels {
            for k in 0..4 {
                out[k] += raw[c * (COUNTER_STRIDE / 4) as usize + k] as u64;
            }
        }
        Ok(out)
    }
}

/// Stage 0 of one channel (§0.4 steps 1–2): `sanitize_quads` when the width
/// is a multiple of 4 (the same result, a quarter of the buffer accesses),
/// else `sanitize`.
fn stage0(
    batch: &mut Batch,
    precision: Precision,
    push: SanitizePush,
    planes: [crate::gpu::BufferSlice; 5],
    counters: crate::gpu::BufferSlice,
) -> Result<()> {
    if sanitize_quads::fits(push.width) {
        sanitize_quads::record(batch, precision, push, planes, counters)
    } else {
        sanitize::record(batch, precision, push, planes, counters)
    }
}

/// Records the sanitation of the statistics in `stats`, in place. `stats`
/// holds [`output_layers`] of `layers`, the layers the source provides (the
/// planes of the variances sanitation estimates are written, not read).
/// GPU-resident: nothing is read back.
///
/// In place: a channel's stage 0 reads a pixel's neighbours, so it reads a
/// copy (the scratch planes) and writes the statistics' own planes; with two
/// stages, the first writes the scratch and the second the statistics. The
/// statistics are therefore consumed: running this twice on them is not
/// running it once (the caller uploads or finalises them before every call).
///
/// `low_spp`: whether some pixel may have `1 <= spp < 2` (spec §0.4 step 3).
/// Pass `true` when unknown; `false` skips that stage (a renderer that took at
/// least two samples everywhere knows it), which is exact because the stage
/// only changes such pixels.
///
/// `skip`: margins whose repairs are not counted, `[left | top << 16,
/// right | bottom << 16]` ([`SanitizePush::skip_lo`]; a tile's halo), or
/// `[0, 0]`.
pub fn record_prepare(
    batch: &mut Batch,
    precision: Precision,
    layers: &[Layer],
    stats: &GpuStats,
    scratch: &PrepareScratch,
    low_spp: bool,
    skip: [u32; 2],
) -> Result<()> {
    let (w, h) = (stats.width as u32, stats.height as u32);
    let push = |stage: u32, has_var: bool| SanitizePush {
        width: w,
        height: h,
        stage,
        has_var: has_var as u32,
        skip_lo: skip[0],
        skip_hi: skip[1],
        ..Default::default()
    };
    let spp = stats.plane(Layer::Spp, 0);
    let (tmp_val, tmp_var) = (scratch.planes.plane(0), scratch.planes.plane(1));
    batch.fill(scratch.counters.slice(), 0);
    let mut channel = 0u64;
    let counters = |c: u64| scratch.counters.range(c * COUNTER_STRIDE, 16);
    for &layer in &Layer::WITH_VARIANCE {
        if !layers.contains(&layer) {
            continue;
        }
        let var_layer = layer.variance().unwrap();
        let has_var = layers.contains(&var_layer);
        for c in 0..layer.channels().len() {
            let (value, var) = (stats.plane(layer, c), stats.plane(var_layer, c));
            if has_var && !low_spp {
                // Stage 0 alone is the whole sanitation of this channel.
                batch.copy(value, tmp_val);
                batch.copy(var, tmp_var);
                let planes = [tmp_val, tmp_var, spp, value, var];
                let push = SanitizePush {
                    in_place: 1,
                    ..push(0, true)
                };
                stage0(batch, precision, push, planes, counters(channel))?;
            } else {
                // Without a variance, stage 0 reads the value as a stand-in
                // and stage 2 estimates the variance plane.
                let var_in = if has_var { var } else { value };
                let planes = [value, var_in, spp, tmp_val, tmp_var];
                stage0(
                    batch,
                    precision,
                    push(0, has_var),
                    planes,
                    counters(channel),
                )?;
                let stage = if has_var { 1 } else { 2 };
                let planes = [tmp_val, tmp_var, spp, value, var];
                sanitize::record(
                    batch,
                    precision,
                    push(stage, has_var),
                    planes,
                    counters(channel),
                )?;
            }
            channel += 1;
        }
    }
    if layers.contains(&Layer::PositionCovariance) {
        for c in 0..6 {
            let p = stats.plane(Layer::PositionCovariance, c);
            batch.copy(p, tmp_val);
            // tmp_var, the variance output, is not read: in place too.
            let push = SanitizePush {
                in_place: 1,
                ..push(0, false)
            };
            stage0(
                batch,
                precision,
                push,
                [tmp_val, tmp_val, spp, p, tmp_var],
                counters(channel),
            )?;
            channel += 1;
        }
    }
    // The count itself is not sanitised (every kernel applies spp_of when
    // reading it): a non-finite count is not repaired by a neighbour median.
    Ok(())
}

/// Upload, [`record_prepare`], download.
pub fn prepare_gpu(
    ctx: &Arc<GpuContext>,
    precision: Precision,
    img: &StatsImage,
) -> Result<(StatsImage, PrepareReport)> {
    let layers: Vec<Layer> = img.layers().map(|(l, _)| l).collect();
    let stats = GpuStats::new(
        ctx,
        "prepare.stats",
        img.width,
        img.height,
        &output_layers(&layers),
    )?;
    stats.upload_image(img)?;
    let scratch = PrepareScratch::new(ctx, &stats, None)?;
    let low_spp = has_low_spp(img);
    let mut batch = Batch::new(ctx)?;
    record_prepare(
        &mut batch,
        precision,
        &layers,
        &stats,
        &scratch,
        low_spp,
        [0, 0],
    )?;
    let timings = batch.finish()?;
    let mut report = base_report(img);
    report.timings = timings;
    report.counters = scratch.read_counters()?;
    let mut clean = stats.download()?;
    // Same normalisation of the count as the CPU path.
    let spp: Vec<f32> = clean.get(Layer::Spp).unwrap()[0]
        .iter()
        .map(|&s| spp_of(s) as f32)
        .collect();
    clean.set(Layer::Spp, vec![spp]);
    Ok((clean, report))
}

/// Whether some pixel has `1 <= spp < 2` (spec §0.4 step 3 applies).
pub fn has_low_spp(img: &StatsImage) -> bool {
    img.get(Layer::Spp)
        .is_some_and(|s| s[0].iter().any(|&v| (1.0..2.0).contains(&spp_of(v))))
}

/// Whether any pixel of `img` has a sample (a valid count, `spp` ≥ 1); an
/// image without a `spp` layer has none.
pub fn has_samples(img: &StatsImage) -> bool {
    img.get(Layer::Spp)
        .is_some_and(|s| s[0].iter().any(|&v| spp_of(v) >= 1.0))
}

/// The colour layer as an image, clamped to ≥ 0 (spec §0.4 step 5). Invalid
/// pixels (n < 1) get the mean of the valid pixels of their 3x3
/// neighbourhood, or 0 (spec §0.2).
pub fn colour_of(img: &StatsImage) -> RgbImage {
    let (w, h) = (img.width, img.height);
    let col = img.get(Layer::Color).expect("colour layer");
    let spp = &img.get(Layer::Spp).expect("spp layer")[0];
    let valid = |i: usize| spp_of(spp[i]) >= 1.0;
    let planes = std::array::from_fn(|c| {
        (0..w * h)
            .map(|i| {
                let v = if valid(i) {
                    col[c][i] as f64
                } else {
                    let (x, y) = (i % w, i / w);
                    let (mut s, mut k) = (0.0, 0);
                    for qy in y.saturating_sub(1)..(y + 2).min(h) {
                        for qx in x.saturating_sub(1)..(x + 2).min(w) {
                            let q = qy * w + qx;
                            if valid(q) {
                                s += col[c][q] as f64;
                                k += 1;
                            }
                        }
                    }
                    if k > 0 {
                        s / k as f64
                    } else {
                        0.0
                    }
                };
                v.max(0.0) as f32
            })
            .collect()
    });
    RgbImage::from_planes(w, h, planes)
}
