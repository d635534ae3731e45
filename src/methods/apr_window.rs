//! §10.2, APR's temporal window, for offline sequences: every frame's
//! blocks fit the frames `t−2..t+2` (APR-TEMPORAL-COLUMNS in place of
//! 3D-POLY; 3D-KERNEL; SLICE), on the GPU, streaming.
//!
//! Frames go in one at a time ([`AprWindow::record_push`]); each is
//! sanitised, cleaned of outliers and prefiltered alone, in 2-D (§10.2),
//! and its statistics are kept in a ring of [`slots`] frames. Stage `s` of
//! frame `t` needs frames `t−2..t+2` and, for `s ≥ 2`, their stage-`s−1`
//! planes, so it runs once frame `t + 2s` is in: the final reconstruction
//! of frame `t` comes out `2T` frames after it went in (T = `apr.stages`),
//! and the last `2T` come out at the end ([`AprWindow::record_end`]).
//! Every intermediate stage writes its planes into a ring of its own with
//! the same slots. Twin: `reference::apr_gather::run_sequence`.

use std::sync::Arc;

use super::apr::{
    apr_flags, record_pack, record_stage, AprParams, AprPlanes, StageBindings, VisFeature,
};
use super::chain::{front_arena_bytes, prefilter_runs};
use super::gbf::{self, GbfPlanes};
use super::outliers::{self, OutlierPlanes};
use super::prepare::{self, PrepareScratch};
use super::stats::GpuStats;
use super::{Method, Prefilter};
use crate::error::{Error, Result};
use crate::gpu::{plane_stride, Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, StatsImage};
use crate::kernels::apr_block::AprChannel;
use crate::kernels::spp_total;
use crate::shared::{apr_window, AprPush, APR_SPPT_SLOT, APR_STAGE_OUTPUTS, APR_TEMPORAL};

/// Frames on either side of the centre.
const HALF: usize = crate::reference::apr_block::HALF;

/// Ring slots of the statistics for `stages` stages: stage T of frame
/// `f − 2T` reads frames from `f − 2T − 2` while frame `f` goes in.
pub fn slots(stages: usize) -> usize {
    2 * stages.max(1) + 2 * HALF - 1
}

/// The rings of the window: every frame's statistics (colour, variance,
/// counts, packed features, sample total) in slot `t mod slots`, every
/// intermediate stage's `ŷ`, `σ̂²` in the same slot of its own ring (one
/// window of slots serves both in the kernel), and
/// APR's planes for one frame at a time (block states, extra blocks,
/// outputs).
pub struct AprRing {
    width: usize,
    height: usize,
    params: AprParams,
    slots: usize,
    /// Colour R, G, B: plane `ch · slots + slot`.
    y: PlaneSet,
    /// Colour variance, as `y`.
    v: PlaneSet,
    /// Sample counts: plane `slot`.
    spp: PlaneSet,
    /// Packed features (APR-PACKED), `slots` vec4 planes each, one
    /// [`plane_stride`] of vec4s apart.
    fa: GpuBuffer,
    fb: GpuBuffer,
    /// `spp_total`'s words, [`APR_SPPT_SLOT`] per slot.
    sppt: GpuBuffer,
    /// Whether every frame had visibility.
    vis: bool,
    /// Per intermediate stage: `ŷ` R G B, `σ̂²` R G B, plane
    /// `k · slots + slot`.
    stages: Vec<PlaneSet>,
    apr: AprPlanes,
}

impl AprRing {
    /// The rings for `width × height` frames.
    pub fn new(
        ctx: &Arc<GpuContext>,
        width: usize,
        height: usize,
        params: AprParams,
    ) -> Result<AprRing> {
        let n = width * height;
        let s = slots(params.stages);
        if s > 16 {
            return Err(Error::InvalidArgument(format!(
                "APR's temporal window with {} stages keeps {s} frames; AprPush::window holds 16 slots (at most 6 stages)",
                params.stages
            )));
        }
        let ps = plane_stride(n);
        let limit = ctx.info.max_storage_buffer_range as u64;
        let vec4_bytes = 4 * ps * s as u64;
        if vec4_bytes > limit {
            return Err(Error::Limit(format!(
                "APR's temporal window keeps {s} frames of packed features for {width}x{height} ({vec4_bytes} bytes, one binding), more than maxStorageBufferRange ({limit} bytes)"
            )));
        }
        Ok(AprRing {
            width,
            height,
            params,
            slots: s,
            y: PlaneSet::new(ctx, "apr_window.y", n, 3 * s)?,
            v: PlaneSet::new(ctx, "apr_window.v", n, 3 * s)?,
            spp: PlaneSet::new(ctx, "apr_window.spp", n, s)?,
            fa: GpuBuffer::new(ctx, "apr_window.fa", vec4_bytes)?,
            fb: GpuBuffer::new(ctx, "apr_window.fb", vec4_bytes)?,
            sppt: GpuBuffer::new(ctx, "apr_window.sppt", (4 * APR_SPPT_SLOT * s) as u64)?,
            vis: true,
            stages: (1..params.stages.max(1))
                .map(|_| PlaneSet::new(ctx, "apr_window.stage", n, APR_STAGE_OUTPUTS * s))
                .collect::<Result<_>>()?,
            apr: AprPlanes::new(ctx, width, height)?,
        })
    }

    fn ps(&self) -> u64 {
        plane_stride(self.width * self.height)
    }

    /// Planes `first..first + count` of a ring as one binding.
    fn run(set: &PlaneSet, ps: u64, first: usize, count: usize) -> BufferSlice {
        set.range(first as u64 * ps, count as u64 * ps)
    }

    fn packed_slot(&self, slot: usize) -> [BufferSlice; 2] {
        let n = (self.width * self.height) as u64;
        let at = 4 * self.ps() * slot as u64;
        [self.fa.range(at, 16 * n), self.fb.range(at, 16 * n)]
    }

    fn sppt_slot(&self, slot: usize) -> BufferSlice {
        self.sppt.range(
            (4 * APR_SPPT_SLOT * slot) as u64,
            4 * spp_total::WORDS as u64,
        )
    }

    /// The ring slot of frame `t`.
    pub fn slot(&self, t: usize) -> usize {
        t % self.slots
    }

    /// The sample counts of frame `t` (while it is in the ring).
    pub fn spp(&self, t: usize) -> BufferSlice {
        self.spp.plane(self.slot(t))
    }

    /// Records frame `t`'s sanitised (and cleaned, prefiltered) statistics
    /// `clean` into its slot: colour, variance, counts, packed features,
    /// sample total.
    pub fn record_insert(
        &mut self,
        batch: &mut Batch,
        precision: Precision,
        clean: &GpuStats,
        t: usize,
    ) -> Result<()> {
        let (w, h) = (self.width, self.height);
        if (clean.width, clean.height) != (w, h) {
            return Err(Error::InvalidArgument(format!(
                "a frame of {}x{} in a {w}x{h} sequence",
                clean.width, clean.height
            )));
        }
        let s = self.slot(t);
        for ch in 0..3 {
            batch.copy(
                clean.plane(Layer::Color, ch),
                self.y.plane(ch * self.slots + s),
            );
            batch.copy(
                clean.plane(Layer::ColorVariance, ch),
                self.v.plane(ch * self.slots + s),
            );
        }
        batch.copy(clean.plane(Layer::Spp, 0), self.spp.plane(s));
        let vis_feature = VisFeature::of(self.params, &self.apr.vis, None);
        self.vis &= record_pack(batch, precision, clean, vis_feature, self.packed_slot(s))?;
        batch.fill(self.sppt_slot(s), 0);
        spp_total::record(
            batch,
            w as u32,
            h as u32,
            self.spp.plane(s),
            self.sppt_slot(s),
        )
    }

    /// Records what frame `step` makes computable, `len` the sequence's
    /// length once known (frames `len..` absent): stage `s` of frame
    /// `step − 2s` for every stage. Returns the frame whose final planes
    /// ([`outputs`](Self::outputs)) the recording writes, if any.
    pub fn record_step(
        &self,
        batch: &mut Batch,
        precision: Precision,
        step: usize,
        len: Option<usize>,
    ) -> Result<Option<usize>> {
        let stages = self.params.stages.max(1);
        let inside = |t: usize| len.map_or(true, |l| t < l) && t <= step;
        let mut done = None;
        for stage in 1..=stages {
            let Some(t) = step.checked_sub(2 * stage).filter(|&t| inside(t)) else {
                continue;
            };
            self.record_frame_stage(batch, precision, stage, t, &inside)?;
            if stage == stages {
                done = Some(t);
            }
        }
        Ok(done)
    }

    fn record_frame_stage(
        &self,
        batch: &mut Batch,
        precision: Precision,
        stage: usize,
        t: usize,
        inside: &dyn Fn(usize) -> bool,
    ) -> Result<()> {
        let (w, h) = (self.width, self.height);
        let (ps, s) = (self.ps(), self.slots);
        let last = stage == self.params.stages.max(1);
        let stride = (ps / 4) as u32;
        // The window's frames and their slots (the same in the statistics'
        // ring and the stages' rings).
        let frame = |k: usize| (t + k).checked_sub(HALF).filter(|&f| inside(f));
        let window = apr_window(std::array::from_fn(|k| frame(k).map(|f| (f % s) as u32)));
        let slot = t % s;
        let push = AprPush {
            width: w as u32,
            height: h as u32,
            last: last as u32,
            flags: APR_TEMPORAL | apr_flags(self.vis, self.params.clamped, self.params.count_cap),
            stride,
            window,
            ..Default::default()
        };
        let io = StageBindings {
            chans: std::array::from_fn(|ch| {
                let y = Self::run(&self.y, ps, ch * s, s);
                let v = Self::run(&self.v, ps, ch * s, s);
                match stage {
                    1 => AprChannel {
                        y,
                        v,
                        yprev: y,
                        s2prev: v,
                    },
                    _ => {
                        let p = &self.stages[stage - 2];
                        AprChannel {
                            y,
                            v,
                            yprev: Self::run(p, ps, ch * s, s),
                            s2prev: Self::run(p, ps, (3 + ch) * s, s),
                        }
                    }
                }
            }),
            packed: [self.fa.slice(), self.fb.slice()],
            sppt: (self.spp.all(), self.sppt.slice()),
            color: std::array::from_fn(|ch| self.y.plane(ch * s + slot)),
            var: std::array::from_fn(|ch| self.v.plane(ch * s + slot)),
            gather_packed: self.packed_slot(slot),
            gather_sppt: (self.spp.plane(slot), self.sppt_slot(slot)),
            dst: if last {
                self.apr.out.all()
            } else {
                self.apr.stage[0].all()
            },
        };
        let apr = &self.apr;
        record_stage(batch, precision, apr, push, self.params.pixel_test, &io)?;
        if !last {
            let ring = &self.stages[stage - 1];
            for k in 0..APR_STAGE_OUTPUTS {
                batch.copy(apr.stage[0].plane(k), ring.plane(k * s + slot));
            }
        }
        Ok(())
    }

    /// The last final stage's colour R, G, B (clamped ≥ 0).
    pub fn color(&self) -> [BufferSlice; 3] {
        self.apr.color()
    }

    /// All [`crate::shared::APR_OUTPUTS`] final planes.
    pub fn outputs(&self) -> &PlaneSet {
        &self.apr.out
    }
}

/// The whole of §10.2 on a sequence: every frame's front (sanitation,
/// §0.4; the outlier stage's removal, §4.4, per frame in 2-D; the G-buffer
/// prefilter, §6), the [`AprRing`], and the outlier stage's restoration
/// of each final frame with the energy removed from that frame.
pub struct AprWindow {
    layers: Vec<Layer>,
    precision: Precision,
    low_spp: bool,
    stats: GpuStats,
    scratch: PrepareScratch,
    gbf: Option<GbfPlanes>,
    /// One per ring slot: each frame's removed energy and outlier queue,
    /// alive until its final frame; their scratch shares the arena.
    outliers: Vec<OutlierPlanes>,
    ring: AprRing,
    /// Frames recorded since the start of the sequence.
    pushed: usize,
    _arena: Arc<GpuBuffer>,
}

/// What an [`AprWindow`] runs besides APR.
#[derive(Clone, Debug)]
pub struct WindowConfig {
    /// Kernel arithmetic.
    pub precision: Precision,
    /// The G-buffer prefilter (`Auto`: APR's default, on).
    pub prefilter: Prefilter,
    /// The outlier stage.
    pub outliers: bool,
    /// How the outlier stage detects (OUTLIER-CLIP, OUTLIER-RIM).
    pub outlier_detection: crate::methods::outliers::Detection,
    /// OUTLIER-WIDE's fraction (`outliers.wide`; 0: off).
    pub outlier_wide: f64,
    /// What the G-buffer prefilter runs beyond the spec's one pass
    /// (GBF-SECOND, GBF-NLM).
    pub gbf: crate::methods::gbf::GbfSettings,
    /// See [`crate::Config::low_spp`].
    pub low_spp: bool,
    /// APR's options (`apr.stages` sets the lag, `2T` frames).
    pub params: AprParams,
}

impl AprWindow {
    /// A window for `width × height` frames with the input layers `layers`.
    pub fn new(
        ctx: &Arc<GpuContext>,
        (width, height): (usize, usize),
        layers: &[Layer],
        config: &WindowConfig,
    ) -> Result<AprWindow> {
        if config.params.prefilter {
            return Err(Error::InvalidArgument(
                "apr.prefilter=on (APR's own 5x5 feature prefilter) runs on the CPU backend only"
                    .into(),
            ));
        }
        super::chain::check_device(ctx, config.precision, (width, height))?;
        super::chain::check_layers(Method::Apr, layers)?;
        let stats = GpuStats::new(
            ctx,
            "apr_window.stats",
            width,
            height,
            &prepare::output_layers(layers),
        )?;
        let n = width * height;
        let with_gbf = prefilter_runs(Method::Apr, config.prefilter, layers)?;
        let arena_bytes = front_arena_bytes(n, with_gbf, config.outliers.then_some(0));
        let arena = Arc::new(GpuBuffer::new(ctx, "apr_window.arena", arena_bytes)?);
        let ring = AprRing::new(ctx, width, height, config.params)?;
        let outliers = if config.outliers {
            (0..ring.slots)
                .map(|_| {
                    OutlierPlanes::new(
                        ctx,
                        width,
                        height,
                        config.outlier_detection,
                        config.outlier_wide,
                        Some((&arena, 0)),
                    )
                })
                .collect::<Result<_>>()?
        } else {
            Vec::new()
        };
        Ok(AprWindow {
            layers: layers.to_vec(),
            precision: config.precision,
            low_spp: config.low_spp,
            scratch: PrepareScratch::new(ctx, &stats, Some(&arena))?,
            gbf: if with_gbf {
                Some(GbfPlanes::new(
                    ctx,
                    width,
                    height,
                    Some(&arena),
                    config.gbf,
                )?)
            } else {
                None
            },
            stats,
            outliers,
            ring,
            pushed: 0,
            _arena: arena,
        })
    }

    /// Uploads the next frame's statistics (of the window's size and
    /// layers) for [`record_push`](Self::record_push).
    pub fn upload(&self, img: &StatsImage) -> Result<()> {
        self.stats.upload_image(img)
    }

    /// Frames recorded since the start of the sequence.
    pub fn pushed(&self) -> usize {
        self.pushed
    }

    /// Frames between a frame going in and its reconstruction coming out.
    pub fn lag(&self) -> usize {
        2 * self.ring.params.stages.max(1)
    }

    /// Records the uploaded frame: its front, its slot, and the step it
    /// makes computable. Returns the frame whose final planes
    /// ([`outputs`](Self::outputs)) the recording writes, if any.
    pub fn record_push(&mut self, batch: &mut Batch) -> Result<Option<usize>> {
        let p = self.precision;
        let f = self.pushed;
        prepare::record_prepare(
            batch,
            p,
            &self.layers,
            &self.stats,
            &self.scratch,
            self.low_spp,
            [0, 0],
        )?;
        if let Some(o) = self.outliers.get(self.ring.slot(f)) {
            outliers::record_remove(batch, p, &self.stats, o)?;
        }
        if let Some(g) = &self.gbf {
            gbf::record_gbf(batch, p, &self.stats, g)?;
        }
        self.ring.record_insert(batch, p, &self.stats, f)?;
        self.pushed += 1;
        self.record_step(batch, f, None)
    }

    /// Builds every pipeline a sequence uses, before any device memory of
    /// a frame is touched (BUILD-FIRST): a counting batch records a frame's
    /// push and the steps that run each stage on it, and changes nothing.
    /// A kernel the device cannot run is an error here, never part-way
    /// through a sequence.
    pub fn build_pipelines(&mut self, ctx: &Arc<GpuContext>) -> Result<()> {
        let (pushed, vis) = (self.pushed, self.ring.vis);
        let mut batch = Batch::counting(ctx);
        let mut run = || -> Result<()> {
            self.record_push(&mut batch)?;
            for step in 1..=self.lag() {
                self.record_step(&mut batch, pushed + step, Some(pushed + 1))?;
            }
            Ok(())
        };
        let built = run();
        self.pushed = pushed;
        self.ring.vis = vis;
        built
    }

    /// Records step `pushed + i` (`i < lag`) after the sequence's last
    /// frame: the frames that wait for no more input.
    pub fn record_end(&mut self, batch: &mut Batch, i: usize) -> Result<Option<usize>> {
        let len = self.pushed;
        self.record_step(batch, len + i, Some(len))
    }

    fn record_step(
        &self,
        batch: &mut Batch,
        step: usize,
        len: Option<usize>,
    ) -> Result<Option<usize>> {
        let done = self.ring.record_step(batch, self.precision, step, len)?;
        if let Some(t) = done {
            if let Some(o) = self.outliers.get(self.ring.slot(t)) {
                outliers::record_restore(
                    batch,
                    self.precision,
                    self.ring.spp(t),
                    self.ring.color(),
                    o,
                )?;
            }
        }
        Ok(done)
    }

    /// Starts a new sequence (a cut): the next frame is frame 0 again.
    /// Frames of the old sequence still waiting are dropped.
    pub fn restart(&mut self) {
        self.pushed = 0;
    }

    /// The sanitation counters of the last pushed frame.
    pub fn counters(&self) -> Result<[u64; 4]> {
        self.scratch.read_counters()
    }

    /// The last recorded final frame's planes: colour R G B (after the
    /// outlier stage's restoration), error R G B, dimension, extra mask
    /// R G B.
    pub fn outputs(&self) -> &PlaneSet {
        self.ring.outputs()
    }
}
