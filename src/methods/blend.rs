//! The input blend (INPUT-BLEND): the last spatial stage of the chain. The
//! method's reconstruction `f` and the input `y` it was made from are two
//! estimates of each pixel with their own errors — the method's estimate
//! `E` and the input's variance of the mean `v` — and the output weighs
//! them by inverse error, per pixel and channel:
//! `f' = (V f + k E y) / (V + k E)` with `V = max(v, trim(v))`, the mean
//! of `v` over a `(2r + 1)²` window without its tenth of largest values
//! flooring the pixel's own (a pixel whose few samples happen to agree has
//! no variance of its own to speak for it; a small lamp's few pixels beside
//! it do not speak for it either, BLEND-TRIM). Where the method smooths
//! across what it cannot see in its features it reports a large error, and
//! the output returns towards the input: it keeps a reconstruction from
//! ending worse than its input.
//!
//! Where the method does not see its own bias either, the residual does
//! (BLEND-RESIDUAL): over a `(2s + 1)²` window `(f − y)²` exceeds the
//! input's variance by about the reconstruction's squared error, so the
//! stage reads that error as at least
//! `B = mean (f − y)² − mean v − z √(2 mean v² / n)` (the excess less `z`
//! of its standard deviation were `f` exact): the weight of the input is
//! `W = max(k E, B)` in place of `k E`, and the error `max(E, B)` in the
//! blend's estimate.
//!
//! It runs on the method's colour before the outlier stage gives back the
//! energy it removed, on the same cleaned statistics the method read: the
//! energy the outlier stage moves is kept whatever the blend does.

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::kernels::input_blend::{self, Channel};
use crate::options::Options;
use crate::reference::input_blend as twin;
use crate::shared::BlendPush;

use super::stats::GpuStats;
use super::{Method, Pass};

/// A method's defaults for the stage ([`super::MethodInfo::blend`]).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct BlendDefaults {
    /// Whether [`InputBlend::Auto`] runs it after the method.
    pub auto: bool,
    /// The radius `r` of the variance's window (`blend.radius`; its mean
    /// leaves out the largest values, BLEND-TRIM).
    pub radius: u32,
    /// The weight `k` of the error estimate (`blend.k`).
    pub k: f32,
    /// The radius `s` of the residual's window (BLEND-RESIDUAL,
    /// `blend.residual_radius`).
    pub residual_radius: u32,
    /// The `z` of the residual's test (`blend.z`).
    pub z: f32,
}

impl BlendDefaults {
    /// Off, `r` = 3, `k` = 1, and BLEND-RESIDUAL's residual window and `z`:
    /// the registry's entries spread it and name what they change.
    pub const BASE: BlendDefaults = BlendDefaults {
        auto: false,
        radius: 3,
        k: 1.0,
        residual_radius: crate::shared::BLEND_RESIDUAL_RADIUS,
        z: crate::shared::BLEND_Z,
    };
}

/// Whether the input blend runs (`Config::input_blend`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InputBlend {
    /// The method's default ([`BlendDefaults::auto`]: WLR, LP, APR, AOS) in a
    /// final reconstruction ([`Pass::Final`]; an adaptive pass's map reads
    /// the method's estimate).
    #[default]
    Auto,
    /// Always (an error for `none`).
    On,
    /// Never.
    Off,
}

impl InputBlend {
    /// Whether the stage runs for `method` in a `pass`.
    pub fn resolve(self, method: Method, pass: Pass) -> bool {
        match self {
            InputBlend::Auto => method.info().blend.auto && pass == Pass::Final,
            InputBlend::On => true,
            InputBlend::Off => false,
        }
    }
}

/// `Err` unless the stage can run after `method`.
pub fn check(method: Method) -> Result<()> {
    if method == Method::None {
        return Err(Error::InvalidArgument(
            "the input blend weighs a reconstruction against its input: method none has none"
                .into(),
        ));
    }
    Ok(())
}

/// The stage's parameters ([`params`]).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct BlendParams {
    /// The radius `r` of the variance's window (`blend.radius`; its mean
    /// leaves out the largest values, BLEND-TRIM).
    pub radius: u32,
    /// The weight `k` of the error estimate (`blend.k`).
    pub k: f32,
    /// The radius `s` of the residual's window (BLEND-RESIDUAL,
    /// `blend.residual_radius`; 0: the residual is not read).
    pub residual_radius: u32,
    /// The `z` of the residual's test (`blend.z`).
    pub z: f32,
}

/// The stage's parameters for `method` with `options` (`blend.radius`,
/// `blend.k`, `blend.residual_radius`, `blend.z`; the method's and the
/// stage's defaults otherwise).
pub fn params(method: Method, options: &Options) -> Result<BlendParams> {
    let d = method.info().blend;
    Ok(BlendParams {
        radius: options.number("blend.radius")?.unwrap_or(d.radius),
        k: options.number("blend.k")?.unwrap_or(d.k),
        residual_radius: options
            .number("blend.residual_radius")?
            .unwrap_or(d.residual_radius),
        z: options.number("blend.z")?.unwrap_or(d.z),
    })
}

impl BlendParams {
    /// How far from a pixel the stage reads: the variance's window, and
    /// the residual's, which reads the reconstruction there too.
    pub fn reach(&self) -> usize {
        self.radius.max(self.residual_radius) as usize
    }
}

/// The push constants over a `size` image.
pub fn push((w, h): (usize, usize), p: BlendParams) -> BlendPush {
    BlendPush {
        width: w as u32,
        height: h as u32,
        radius: p.radius,
        k: p.k,
        residual_radius: p.residual_radius,
        z: p.z,
        ..Default::default()
    }
}

/// The stage's planes: the blend's colour R, G, B (planes 0–2) and error
/// estimate (3–5).
pub struct BlendStage {
    planes: PlaneSet,
    push: BlendPush,
}

impl std::fmt::Debug for BlendStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BlendStage")
            .field("push", &self.push)
            .finish()
    }
}

impl BlendStage {
    /// The stage of a `size` chain after `method` with `options`.
    pub fn new(
        ctx: &Arc<GpuContext>,
        size: (usize, usize),
        method: Method,
        options: &Options,
    ) -> Result<BlendStage> {
        check(method)?;
        let push = push(size, params(method, options)?);
        let planes = PlaneSet::new(ctx, "blend.out", size.0 * size.1, 6)?;
        Ok(BlendStage { planes, push })
    }

    /// Records the blend of the reconstruction `color` with error estimate
    /// `error` into [`color`](Self::color) and [`error`](Self::error),
    /// against the statistics `stats` the method
    /// read.
    pub fn record(
        &self,
        batch: &mut Batch,
        p: Precision,
        color: [BufferSlice; 3],
        error: [BufferSlice; 3],
        stats: &GpuStats,
    ) -> Result<()> {
        let spp = stats.plane(Layer::Spp, 0);
        for c in 0..3 {
            let ch = Channel {
                color: color[c],
                error: error[c],
                input: stats.plane(Layer::Color, c),
                variance: stats.plane(Layer::ColorVariance, c),
                out_color: self.planes.plane(c),
                out_error: self.planes.plane(3 + c),
            };
            input_blend::record(batch, p, &self.push, &ch, spp)?;
        }
        Ok(())
    }

    /// The blend's colour R, G, B.
    pub fn color(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|k| self.planes.plane(k))
    }

    /// The blend's error estimate per channel.
    pub fn error(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|k| self.planes.plane(3 + k))
    }
}

/// The CPU path of the stage: the method's `color` and `error` blended
/// with the sanitised statistics `clean` the method read; returns the
/// blend's colour and error estimate.
pub fn run_cpu(
    clean: &StatsImage,
    color: &RgbImage,
    error: &RgbImage,
    params: BlendParams,
) -> Result<(RgbImage, RgbImage)> {
    let (w, h) = (color.width, color.height);
    let layer = |l: Layer| {
        clean
            .get(l)
            .ok_or_else(|| Error::BadData(format!("the input blend needs the {} layer", l.name())))
    };
    let (y, v, spp) = (
        layer(Layer::Color)?,
        layer(Layer::ColorVariance)?,
        &layer(Layer::Spp)?[0],
    );
    let push = push((w, h), params);
    let mut out = RgbImage::new(w, h);
    let mut out_error = RgbImage::new(w, h);
    for c in 0..3 {
        twin::input_blend(
            &push,
            &color.planes[c],
            &error.planes[c],
            &y[c],
            &v[c],
            spp,
            &mut out.planes[c],
            &mut out_error.planes[c],
        );
    }
    Ok((out, out_error))
}
