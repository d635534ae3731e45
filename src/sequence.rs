//! The facade for offline sequences: [`SequenceDenoiser`] runs APR's
//! temporal window (spec §10.2, [`Temporal::Apr`]) over a sequence's
//! frames given in order, and hands each reconstruction back once the
//! frames after it that its window reads are in.

use std::collections::VecDeque;
use std::sync::Arc;

use crate::denoiser::{Config, Frame, Source};
use crate::error::{Error, Result};
use crate::gpu::{Batch, GpuContext, KernelTiming};
use crate::image::{RgbImage, StatsImage};
use crate::methods::apr::AprParams;
use crate::methods::apr_window::{AprWindow, WindowConfig};
use crate::methods::prepare::{base_report, PrepareReport};
use crate::methods::{InputBlend, Method, Pass, Pyramid, Temporal};

/// APR's temporal window on a sequence (spec §10.2): every frame's
/// reconstruction fits the frames `t−2..t+2` with polynomials in space and
/// time. Frames go in with [`push`](Self::push), in order; frame `t` comes
/// out of the push of frame `t + lag` ([`lag`](Self::lag): `2·apr.stages`,
/// 4 by default), and the last ones out of [`finish`](Self::finish), which
/// also ends the sequence (a cut: the next push is frame 0 of a new one).
/// Each frame is sanitised, cleaned of outliers and prefiltered alone, as
/// [`crate::Denoiser`] would; the outlier stage gives each frame back its
/// own removed energy. The GPU keeps `2·stages + 3` frames of statistics.
///
/// ```no_run
/// # use std::sync::Arc;
/// # use mcdenoise::{Config, GpuContext, Method, SequenceDenoiser, Source, StatsImage, Temporal};
/// # fn demo(ctx: Arc<GpuContext>, frames: Vec<StatsImage>) -> mcdenoise::Result<()> {
/// let mut config = Config::new(Method::Apr);
/// config.temporal = Temporal::Apr;
/// let mut seq = SequenceDenoiser::new(&ctx, Source::of_image(&frames[0]), config)?;
/// for f in &frames {
///     for (t, out) in seq.push(f)? {
///         // out.color is frame t's reconstruction
///     }
/// }
/// for (t, out) in seq.finish()? { /* the last frames */ }
/// # Ok(()) }
/// ```
pub struct SequenceDenoiser {
    ctx: Arc<GpuContext>,
    config: Config,
    /// The statistics every frame must match (`Source::Stats`).
    source: Source,
    window: AprWindow,
    /// The reports of the frames pushed and not yet out, oldest first.
    reports: VecDeque<PrepareReport>,
    /// A push failed part-way: the window's state no longer matches its
    /// frames until [`finish`](SequenceDenoiser::finish) ends the sequence.
    broken: bool,
}

impl std::fmt::Debug for SequenceDenoiser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SequenceDenoiser")
            .field("source", &self.source)
            .field("pushed", &self.window.pushed())
            .finish()
    }
}

impl SequenceDenoiser {
    /// A sequence denoiser for frames of `source` (statistics of one size
    /// and set of layers). `config` must have [`Method::Apr`] and
    /// [`Temporal::Apr`], a final pass, no pyramid and no input blend
    /// (their `Auto` is off for APR); its precision, prefilter, outlier
    /// stage, options (`apr.*`) and `low_spp` apply. GPU only, one chain:
    /// a frame whose window does not fit the device is an
    /// [`Error::Limit`]. Every pipeline is built here, so a kernel the
    /// device cannot run is an error of `new`, never of a push.
    pub fn new(ctx: &Arc<GpuContext>, source: Source, config: Config) -> Result<SequenceDenoiser> {
        let Source::Stats {
            width,
            height,
            layers,
        } = &source
        else {
            return Err(Error::InvalidArgument(
                "the APR temporal window reads statistics (Source::Stats), not a renderer's accumulation planes".into(),
            ));
        };
        if config.method != Method::Apr || config.temporal != Temporal::Apr {
            return Err(Error::InvalidArgument(format!(
                "a SequenceDenoiser runs APR's temporal window (method apr, temporal apr), not method {} with temporal {:?}",
                config.method.name(),
                config.temporal
            )));
        }
        if config.pass != Pass::Final
            || config.pyramid == Pyramid::On
            || config.input_blend == InputBlend::On
        {
            return Err(Error::InvalidArgument(
                "the APR temporal window is a final reconstruction without the pyramid or the input blend".into(),
            ));
        }
        let wc = WindowConfig {
            precision: config.precision,
            prefilter: config.prefilter,
            outliers: config.outliers.resolve(Method::Apr),
            outlier_detection: crate::methods::outliers::Detection::of(&config.options)?,
            outlier_wide: crate::methods::outliers::wide_fraction(&config.options)?,
            gbf: crate::methods::gbf::GbfSettings::new(
                &config.options,
                config.method,
                config.pass,
            )?,
            low_spp: config.low_spp,
            params: AprParams::new(&config.options)?,
        };
        let mut window = AprWindow::new(ctx, (*width, *height), layers, &wc)?;
        window.build_pipelines(ctx)?;
        Ok(SequenceDenoiser {
            ctx: ctx.clone(),
            source: source.clone(),
            config,
            window,
            reports: VecDeque::new(),
            broken: false,
        })
    }

    /// The frames' `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        match &self.source {
            Source::Stats { width, height, .. } => (*width, *height),
            _ => unreachable!("new accepts statistics only"),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Frames between a frame going in and its reconstruction coming out
    /// (`2·apr.stages`).
    pub fn lag(&self) -> usize {
        self.window.lag()
    }

    /// Frames pushed since the sequence began.
    pub fn pushed(&self) -> usize {
        self.window.pushed()
    }

    /// Adds the sequence's next frame (statistics of the denoiser's source)
    /// and returns the frames this completes, `(index in the sequence,
    /// result)`: none while the first `lag` frames go in, then one. A
    /// frame of another size or layers is refused and changes nothing;
    /// after any other error the sequence is broken: pushes are refused
    /// until [`finish`](Self::finish), which drops its waiting frames.
    pub fn push(&mut self, img: &StatsImage) -> Result<Vec<(usize, Frame)>> {
        if self.broken {
            return Err(Error::InvalidArgument(
                "an earlier push of this sequence failed: finish() ends it (its waiting frames are lost) and the next push starts a new one".into(),
            ));
        }
        if Source::of_image(img) != self.source {
            return Err(Error::InvalidArgument(format!(
                "frame {} has another size or other layers than the sequence's ({}x{})",
                self.window.pushed(),
                self.size().0,
                self.size().1
            )));
        }
        let report = base_report(img);
        let run = |me: &mut Self| -> Result<Vec<(usize, Frame)>> {
            me.window.upload(img)?;
            let mut batch = Batch::new(&me.ctx)?;
            batch.progress = me.config.progress;
            let done = me.window.record_push(&mut batch)?;
            let timings = batch.finish()?;
            me.reports.push_back(PrepareReport {
                counters: me.window.counters()?,
                ..report
            });
            me.collect(done, timings)
        };
        let out = run(self);
        self.broken = out.is_err();
        out
    }

    /// Ends the sequence: returns its frames still waiting, in order (none
    /// after a failed push). The next [`push`](Self::push) starts a new
    /// sequence (a cut). On an error here the sequence ends as well.
    pub fn finish(&mut self) -> Result<Vec<(usize, Frame)>> {
        let drain = |me: &mut Self| -> Result<Vec<(usize, Frame)>> {
            let mut out = Vec::new();
            if me.window.pushed() == 0 || me.broken {
                return Ok(out);
            }
            for i in 0..me.window.lag() {
                let mut batch = Batch::new(&me.ctx)?;
                batch.progress = me.config.progress;
                let done = me.window.record_end(&mut batch, i)?;
                let timings = batch.finish()?;
                out.extend(me.collect(done, timings)?);
            }
            Ok(out)
        };
        let out = drain(self);
        self.window.restart();
        self.reports.clear();
        self.broken = false;
        out
    }

    /// The host copy of a finished frame's planes.
    fn collect(
        &mut self,
        done: Option<usize>,
        timings: Vec<KernelTiming>,
    ) -> Result<Vec<(usize, Frame)>> {
        let Some(t) = done else {
            return Ok(Vec::new());
        };
        let (w, h) = self.size();
        let planes = self.window.outputs().download_all()?;
        let rgb =
            |k: usize| RgbImage::from_planes(w, h, std::array::from_fn(|c| planes[k + c].clone()));
        let report = self.reports.pop_front().unwrap_or_default();
        let (error, dim) = if self.config.error {
            (rgb(3), planes[6].clone())
        } else {
            (RgbImage::new(0, 0), Vec::new())
        };
        let mut debug = Vec::new();
        if self.config.debug {
            for (c, name) in ["R", "G", "B"].iter().enumerate() {
                debug.push((format!("apr_extra.{name}"), planes[7 + c].clone()));
            }
            debug.push(("apr_trace".into(), planes[6].clone()));
        }
        Ok(vec![(
            t,
            Frame {
                color: rgb(0),
                error,
                dim,
                samples: None,
                debug,
                report,
                timings,
                stats: Vec::new(),
            },
        )])
    }
}
