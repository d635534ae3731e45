//! The facade for offline sequences: [`SequenceDenoiser`] runs APR's
//! temporal window (spec §10.2, [`Temporal::Apr`]) or the two-way temporal
//! filter (TEMPORAL-SMOOTH, [`Temporal::LpSmooth`]) over a sequence's
//! frames given in order, and hands each reconstruction back once the
//! frames after it that it reads are in. [`Smoother`] is the two-way
//! filter on the frames of a caller's own temporal [`Denoiser`] (an
//! adaptive loop's final one).

use std::collections::VecDeque;
use std::sync::Arc;

use crate::denoiser::{Config, Denoiser, Frame, Source};
use crate::error::{Error, Result};
use crate::gpu::{Batch, GpuContext, KernelTiming};
use crate::image::{RgbImage, StatsImage};
use crate::kernels::lp_temporal::INPUT_PLANES;
use crate::methods::apr::AprParams;
use crate::methods::apr_window::{AprWindow, WindowConfig};
use crate::methods::prepare::{base_report, PrepareReport};
use crate::methods::temporal::{FilterRecord, SmoothStage, TemporalScales};
use crate::methods::{InputBlend, Method, Pass, Pyramid, Temporal};
use crate::spill::PlaneSpill;

/// A sequence's frames reconstructed from the frames around each one,
/// given in order with [`push`](Self::push); [`finish`](Self::finish)
/// returns the last ones and ends the sequence (a cut: the next push is
/// frame 0 of a new one). Two temporal stages:
///
/// - [`Temporal::Apr`], APR's temporal window (spec §10.2): every frame's
///   reconstruction fits the frames `t−2..t+2` with polynomials in space
///   and time; frame `t` comes out of the push of frame `t + lag`
///   ([`lag`](Self::lag): `2·apr.stages`, 4 by default). Each frame is
///   sanitised, cleaned of outliers and prefiltered alone, as
///   [`crate::Denoiser`] would; the outlier stage gives each frame back its
///   own removed energy. The GPU keeps `2·stages + 3` frames of statistics.
/// - [`Temporal::LpSmooth`], the two-way temporal filter (TEMPORAL-SMOOTH)
///   after any method: each push runs the method and §10.1's filter in
///   frame order; `finish` runs the filter in reverse order and combines
///   the two, so every frame comes out of `finish`. Until then the host
///   keeps each frame's error estimate and report, and a [`Smoother`]
///   its colour and the filter's planes in a temporary file.
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
    stage: Stage,
    /// A push failed part-way: the stage's state no longer matches its
    /// frames until [`finish`](SequenceDenoiser::finish) ends the sequence.
    broken: bool,
}

/// A [`SequenceDenoiser`]'s temporal stage.
enum Stage {
    Window {
        window: Box<AprWindow>,
        /// The reports of the frames pushed and not yet out, oldest first.
        reports: VecDeque<PrepareReport>,
    },
    Smooth {
        /// The method and the filter in frame order.
        forward: Box<Denoiser>,
        smoother: Box<Smoother>,
        /// The frames pushed, as the forward pass made them.
        frames: Vec<Frame>,
    },
}

impl std::fmt::Debug for SequenceDenoiser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SequenceDenoiser")
            .field("source", &self.source)
            .field("temporal", &self.config.temporal)
            .field("pushed", &self.pushed())
            .finish()
    }
}

impl SequenceDenoiser {
    /// A sequence denoiser for frames of `source` (statistics of one size
    /// and set of layers). GPU only; every pipeline is built here, so a
    /// kernel the device cannot run is an error of `new`, never of a push.
    ///
    /// With [`Temporal::Apr`], `config` must have [`Method::Apr`], a final
    /// pass, no pyramid and no input blend (their `Auto` is off for APR);
    /// its precision, prefilter, outlier stage, options (`apr.*`) and
    /// `low_spp` apply; one chain: a frame whose window does not fit the
    /// device is an [`Error::Limit`]. With [`Temporal::LpSmooth`], any
    /// method and what [`Denoiser::new`] accepts with [`Temporal::Lp`]
    /// (one chain, a final pass, the `position` and `depth` layers).
    pub fn new(ctx: &Arc<GpuContext>, source: Source, config: Config) -> Result<SequenceDenoiser> {
        let Source::Stats {
            width,
            height,
            layers,
        } = &source
        else {
            return Err(Error::InvalidArgument(
                "a SequenceDenoiser reads statistics (Source::Stats), not a renderer's accumulation planes".into(),
            ));
        };
        let stage = match config.temporal {
            Temporal::LpSmooth => {
                let mut c = config.clone();
                c.temporal = Temporal::Lp;
                let forward = Denoiser::new(ctx, source.clone(), c)?;
                let smoother = Smoother::new(ctx, &forward)?;
                Stage::Smooth {
                    forward: Box::new(forward),
                    smoother: Box::new(smoother),
                    frames: Vec::new(),
                }
            }
            Temporal::Apr => Stage::Window {
                window: Box::new(Self::window(ctx, (*width, *height), layers, &config)?),
                reports: VecDeque::new(),
            },
            Temporal::Off | Temporal::Lp => {
                return Err(Error::InvalidArgument(format!(
                    "a SequenceDenoiser runs APR's temporal window (method apr, temporal apr) or the two-way filter (temporal lp-smooth), not temporal {:?}",
                    config.temporal
                )))
            }
        };
        Ok(SequenceDenoiser {
            ctx: ctx.clone(),
            source: source.clone(),
            config,
            stage,
            broken: false,
        })
    }

    /// APR's window for `config` ([`Temporal::Apr`]), its pipelines built.
    fn window(
        ctx: &Arc<GpuContext>,
        size: (usize, usize),
        layers: &[crate::image::Layer],
        config: &Config,
    ) -> Result<AprWindow> {
        if config.method != Method::Apr {
            return Err(Error::InvalidArgument(format!(
                "APR's temporal window (method apr, temporal apr) does not run method {}",
                config.method.name(),
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
        let mut window = AprWindow::new(ctx, size, layers, &wc)?;
        window.build_pipelines(ctx)?;
        Ok(window)
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

    /// Frames between a frame going in and its reconstruction coming out:
    /// `2·apr.stages` for APR's window; `None` for the two-way filter, whose
    /// frames all come out of [`finish`](Self::finish).
    pub fn lag(&self) -> Option<usize> {
        match &self.stage {
            Stage::Window { window, .. } => Some(window.lag()),
            Stage::Smooth { .. } => None,
        }
    }

    /// Frames pushed since the sequence began.
    pub fn pushed(&self) -> usize {
        match &self.stage {
            Stage::Window { window, .. } => window.pushed(),
            Stage::Smooth { frames, .. } => frames.len(),
        }
    }

    /// Adds the sequence's next frame (statistics of the denoiser's source)
    /// and returns the frames this completes, `(index in the sequence,
    /// result)`: with APR's window none while the first `lag` frames go
    /// in, then one; with the two-way filter none. A frame of another size
    /// or layers is refused and changes nothing; after any other error the
    /// sequence is broken: pushes are refused until
    /// [`finish`](Self::finish), which drops its waiting frames.
    pub fn push(&mut self, img: &StatsImage) -> Result<Vec<(usize, Frame)>> {
        if self.broken {
            return Err(Error::InvalidArgument(
                "an earlier push of this sequence failed: finish() ends it (its waiting frames are lost) and the next push starts a new one".into(),
            ));
        }
        if Source::of_image(img) != self.source {
            return Err(Error::InvalidArgument(format!(
                "frame {} has another size or other layers than the sequence's ({}x{})",
                self.pushed(),
                self.size().0,
                self.size().1
            )));
        }
        let out = match &mut self.stage {
            Stage::Window { window, reports } => {
                let report = base_report(img);
                let run = || -> Result<Option<(usize, Vec<KernelTiming>)>> {
                    window.upload(img)?;
                    let mut batch = Batch::new(&self.ctx)?;
                    batch.progress = self.config.progress;
                    let done = window.record_push(&mut batch)?;
                    let timings = batch.finish()?;
                    reports.push_back(PrepareReport {
                        counters: window.counters()?,
                        ..report
                    });
                    Ok(done.map(|t| (t, timings)))
                };
                run()
            }
            Stage::Smooth {
                forward,
                smoother,
                frames,
            } => {
                let mut run = || -> Result<()> {
                    let mut f = forward.denoise(img, None)?;
                    smoother.keep(forward, &f.color)?;
                    // The smoother keeps the colour; finish replaces it.
                    f.color = RgbImage::new(0, 0);
                    frames.push(f);
                    Ok(())
                };
                run().map(|()| None)
            }
        };
        self.broken = out.is_err();
        match out? {
            Some((t, timings)) => self.collect(t, timings),
            None => Ok(Vec::new()),
        }
    }

    /// Ends the sequence: returns its frames still waiting, in order (none
    /// after a failed push). The next [`push`](Self::push) starts a new
    /// sequence (a cut). On an error here the sequence ends as well.
    pub fn finish(&mut self) -> Result<Vec<(usize, Frame)>> {
        let broken = std::mem::take(&mut self.broken);
        let size = self.size();
        match &mut self.stage {
            Stage::Window { window, reports } => {
                // Each finished frame is read back before the next step
                // overwrites the window's outputs.
                let mut out = Vec::new();
                let mut run = || -> Result<()> {
                    if window.pushed() == 0 || broken {
                        return Ok(());
                    }
                    for i in 0..window.lag() {
                        let mut batch = Batch::new(&self.ctx)?;
                        batch.progress = self.config.progress;
                        let done = window.record_end(&mut batch, i)?;
                        let timings = batch.finish()?;
                        if let Some(t) = done {
                            let report = reports.pop_front().unwrap_or_default();
                            out.push(Self::window_frame(
                                &self.config,
                                size,
                                window,
                                t,
                                report,
                                timings,
                            )?);
                        }
                    }
                    Ok(())
                };
                let done = run();
                window.restart();
                reports.clear();
                done.map(|()| out)
            }
            Stage::Smooth {
                forward,
                smoother,
                frames,
            } => {
                let frames = std::mem::take(frames);
                forward.reset();
                if broken {
                    smoother.clear()?;
                    return Ok(Vec::new());
                }
                let mut frames: Vec<(usize, Frame)> = frames.into_iter().enumerate().collect();
                smoother.finish_each(|t, color, timings| {
                    let f = &mut frames[t].1;
                    f.color = color;
                    f.timings.extend(timings);
                    Ok(())
                })?;
                Ok(frames)
            }
        }
    }

    /// The host copy of APR's window's finished frame `t`.
    fn collect(&mut self, t: usize, timings: Vec<KernelTiming>) -> Result<Vec<(usize, Frame)>> {
        let size = self.size();
        let Stage::Window { window, reports } = &mut self.stage else {
            unreachable!("only APR's window finishes frames in a push");
        };
        let report = reports.pop_front().unwrap_or_default();
        Ok(vec![Self::window_frame(
            &self.config,
            size,
            window,
            t,
            report,
            timings,
        )?])
    }

    /// Frame `t` of APR's window, read back from its outputs.
    fn window_frame(
        config: &Config,
        (w, h): (usize, usize),
        window: &AprWindow,
        t: usize,
        report: PrepareReport,
        timings: Vec<KernelTiming>,
    ) -> Result<(usize, Frame)> {
        let planes = window.outputs().download_all()?;
        let rgb =
            |k: usize| RgbImage::from_planes(w, h, std::array::from_fn(|c| planes[k + c].clone()));
        let (error, dim) = if config.error {
            (rgb(3), planes[6].clone())
        } else {
            (RgbImage::new(0, 0), Vec::new())
        };
        let mut debug = Vec::new();
        if config.debug {
            for (c, name) in ["R", "G", "B"].iter().enumerate() {
                debug.push((format!("apr_extra.{name}"), planes[7 + c].clone()));
            }
            debug.push(("apr_trace".into(), planes[6].clone()));
        }
        Ok((
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
        ))
    }
}

/// The two-way temporal filter (TEMPORAL-SMOOTH) on the frames of a
/// caller's temporal [`Denoiser`] ([`Temporal::Lp`], one chain): after
/// each of its calls, [`keep`](Self::keep) copies what its filter read and
/// made and the call's colour to an unnamed temporary file in
/// [`std::env::temp_dir`] (`TMPDIR` on Unix; 18 planes, 72 bytes per pixel
/// and frame), so the host's memory does not grow with the sequence;
/// [`finish`](Self::finish) runs
/// the filter over them in reverse order and combines the two directions,
/// per pixel and channel, `(w_f F + w_b B − y)/(w_f + w_b − 1)` with `w =
/// 1/P₀₀` of each direction, but at most the other's where that one has
/// met a change (SMOOTH-SHORT), and `y` the method's output. Every frame's
/// reconstruction then sees the whole sequence; the method runs once per
/// frame. For an adaptive loop whose final denoiser carries the filter's
/// state into its sample maps; [`SequenceDenoiser`] with
/// [`Temporal::LpSmooth`] does the rest for statistics in host memory.
pub struct Smoother {
    stage: SmoothStage,
    progress: bool,
    size: (usize, usize),
    /// Every kept frame's record and forward colour ([`KEPT_PLANES`]), in
    /// order.
    kept: PlaneSpill,
    /// Each kept frame's [`FilterRecord::history`].
    histories: Vec<(u64, bool)>,
    /// The kept frames' factors ([`FilterRecord::scales`]).
    scales: TemporalScales,
    /// The denoiser's filter frames at the last keep.
    last: Option<u64>,
}

/// The planes a [`Smoother`] keeps per frame: the filter's inputs, its
/// `P00` and the forward colour.
const KEPT_PLANES: usize = INPUT_PLANES + 1 + 3;

impl std::fmt::Debug for Smoother {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Smoother")
            .field("size", &self.size)
            .field("kept", &self.kept.len())
            .finish()
    }
}

impl Smoother {
    /// The two-way filter for the frames of `denoiser`, which must filter
    /// on one GPU chain ([`Temporal::Lp`], a final pass); its precision and
    /// progress setting apply. Builds its pipelines and creates its temporary
    /// file (an [`Error::Io`] if the temporary directory cannot hold one).
    pub fn new(ctx: &Arc<GpuContext>, denoiser: &Denoiser) -> Result<Smoother> {
        let Some(size) = denoiser.temporal_state().map(|s| s.0.size()) else {
            return Err(Error::InvalidArgument(
                "the two-way filter follows a denoiser with the temporal filter (temporal lp, a final pass, on one GPU chain)".into(),
            ));
        };
        let config = denoiser.config();
        let stage = SmoothStage::new(ctx, size, config.precision)?;
        stage.build_pipelines()?;
        Ok(Smoother {
            stage,
            progress: config.progress,
            size,
            kept: PlaneSpill::new("the two-way filter's kept frames")?,
            histories: Vec::new(),
            scales: TemporalScales::default(),
            last: None,
        })
    }

    /// Keeps the frame `denoiser` (the one given to [`new`](Self::new))
    /// just reconstructed: `color`, the colour its call returned, and what
    /// its filter read. Every frame of the sequence, in order, right after
    /// its call: the first must start the filter's history (a new
    /// denoiser, or one [`Denoiser::reset`] at the cut), and no call may
    /// come between two keeps; otherwise an error, and nothing is kept.
    pub fn keep(&mut self, denoiser: &Denoiser, color: &RgbImage) -> Result<()> {
        let Some(record) = denoiser.temporal_record()? else {
            return Err(Error::InvalidArgument(
                "the two-way filter keeps the frames of a denoiser with the temporal filter".into(),
            ));
        };
        let (size, (frames, reset)) = (record.size, record.history);
        if size != self.size || (color.width, color.height) != size {
            return Err(Error::InvalidArgument(format!(
                "the two-way filter was made for {}x{} frames, not {}x{}",
                self.size.0, self.size.1, color.width, color.height
            )));
        }
        match self.last {
            None if !reset => {
                return Err(Error::InvalidArgument(
                    "the denoiser's temporal filter carries frames from before this sequence: reset it (Denoiser::reset) at the sequence's start".into(),
                ))
            }
            Some(last) if frames != last + 1 || reset => {
                return Err(Error::InvalidArgument(format!(
                    "the two-way filter keeps every frame of a sequence right after its call: the denoiser ran {} frame(s) since the last keep{}",
                    frames.saturating_sub(last),
                    if reset { ", and was reset (a cut: finish the sequence first)" } else { "" }
                )))
            }
            _ => {}
        }
        let planes = record
            .inputs
            .iter()
            .chain([&record.p00])
            .chain(&color.planes);
        self.kept.push(planes.map(|p| p.as_slice()))?;
        self.histories.push(record.history);
        self.scales = record.scales;
        self.last = Some(frames);
        Ok(())
    }

    /// Frames kept since the sequence began.
    pub fn len(&self) -> usize {
        self.kept.len()
    }

    /// Whether no frame is kept.
    pub fn is_empty(&self) -> bool {
        self.kept.is_empty()
    }

    /// Drops the kept frames: the next keep starts a new sequence.
    pub fn clear(&mut self) -> Result<()> {
        self.last = None;
        self.histories.clear();
        self.kept.clear()
    }

    /// Kept frame `k`'s record and forward colour.
    fn kept_frame(&mut self, k: usize) -> Result<(FilterRecord, RgbImage)> {
        let mut planes = self.kept.read(k)?;
        debug_assert_eq!(planes.len(), KEPT_PLANES);
        let (w, h) = self.size;
        let color = planes.split_off(INPUT_PLANES + 1);
        let p00 = planes.pop().expect("KEPT_PLANES planes");
        let color: [Vec<f32>; 3] = color.try_into().expect("three colour planes");
        let record = FilterRecord {
            inputs: planes,
            p00,
            size: self.size,
            history: self.histories[k],
            scales: self.scales,
        };
        Ok((record, RgbImage::from_planes(w, h, color)))
    }

    /// Ends the sequence: every kept frame's two-way reconstruction, in
    /// order, with the timings of its pass in reverse order. The kept
    /// frames are dropped (also on an error); the next keep starts a new
    /// sequence, after a [`Denoiser::reset`] of the denoiser.
    pub fn finish(&mut self) -> Result<Vec<(RgbImage, Vec<KernelTiming>)>> {
        let mut out = Vec::with_capacity(self.len());
        self.finish_each(|_, color, timings| {
            out.push((color, timings));
            Ok(())
        })?;
        out.reverse();
        Ok(out)
    }

    /// [`finish`](Self::finish) one frame at a time, last frame first:
    /// hands `each` the frame's index in the sequence, its reconstruction
    /// and its timings, so the host holds one frame's output at a time. An
    /// error of `each` ends the sequence too.
    pub fn finish_each(
        &mut self,
        mut each: impl FnMut(usize, RgbImage, Vec<KernelTiming>) -> Result<()>,
    ) -> Result<()> {
        let frames = self.kept.len();
        let mut run = || -> Result<()> {
            for k in (0..frames).rev() {
                let (record, color) = self.kept_frame(k)?;
                let (out, timings) = self.stage.run(
                    &record,
                    &color,
                    (k as u64 + 1, (frames - k) as u64),
                    self.progress,
                )?;
                each(k, out, timings)?;
            }
            Ok(())
        };
        let done = run();
        let cleared = self.clear();
        done.and(cleared)
    }
}
