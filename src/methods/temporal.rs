//! Temporal reconstruction of sequences (spec §10): a stage after the
//! method that filters its output over the frames, keeping its state on
//! the GPU from call to call.
//!
//! §10.1, the LP temporal filter ([`Temporal::Lp`]): per pixel a recursive
//! least-squares fit over time of the method's output (with TEMPORAL-PRIOR's
//! reset, of a constant: a mean with forgetting), reprojected from the
//! previous frame by the world position (`kernels::lp_temporal`) in a
//! window centred where a coarse-to-fine search on the positions found the
//! pixel's surface (TEMPORAL-MOTION, `kernels::temporal_motion`). The paper
//! applies it to LP; here it follows any method.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuContext, KernelTiming, PlaneSet, Precision};
use crate::image::{Layer, RgbImage};
use crate::kernels::lp_smooth::{self, Direction};
use crate::kernels::lp_temporal::{self, TemporalIn, TemporalOut, INPUT_PLANES};
use crate::kernels::lp_temporal_gain;
use crate::kernels::pyramid_pool;
use crate::kernels::temporal_motion::{self, LevelPlanes};
use crate::shared::{
    full_information, MotionPush, PyramidPush, TemporalPush, TwoWayPush, PYRAMID_COUNT,
    PYRAMID_MEAN, TEMPORAL_LAMBDA, TEMPORAL_MOTION, TEMPORAL_MOTION_LEVELS, TEMPORAL_MOTION_RADIUS,
    TEMPORAL_P00, TEMPORAL_RESET, TEMPORAL_RESET_P00, TEMPORAL_RESET_P11, TEMPORAL_STATE,
    TEMPORAL_VALID,
};

/// A temporal stage after the method (spec §10).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Temporal {
    /// Every call stands alone (the default).
    #[default]
    Off,
    /// §10.1, the LP temporal filter, on every call's output: needs the
    /// `position` and `depth` layers (`position_variance` is estimated
    /// when missing, §0.4).
    Lp,
    /// §10.2, APR's temporal window: each frame's blocks fit the frames
    /// `t−2..t+2` (offline; [`crate::SequenceDenoiser`], with
    /// [`Method::Apr`](super::Method::Apr)). A [`crate::Denoiser`] refuses it.
    Apr,
    /// §10.1's filter run over an offline sequence in frame order and in
    /// reverse order, the two combined per pixel (TEMPORAL-SMOOTH): every
    /// frame sees the whole sequence ([`crate::SequenceDenoiser`], any
    /// method; a [`crate::Denoiser`] refuses it). Needs what
    /// [`Temporal::Lp`] needs.
    LpSmooth,
}

impl Temporal {
    /// An error for [`Temporal::Apr`] and [`Temporal::LpSmooth`], which
    /// only a [`crate::SequenceDenoiser`] runs; `Ok` otherwise.
    pub fn refuse_window(self) -> Result<()> {
        let what = match self {
            Temporal::Apr => "APR's temporal window (§10.2) reconstructs a sequence from the frames around each one",
            Temporal::LpSmooth => "the two-way temporal filter reconstructs a sequence from all its frames",
            Temporal::Off | Temporal::Lp => return Ok(()),
        };
        Err(Error::InvalidArgument(format!(
            "{what}: use a SequenceDenoiser"
        )))
    }

    /// The layers the stage reads, besides the method's output and `spp`.
    pub fn needs(self) -> &'static [Layer] {
        match self {
            Temporal::Off | Temporal::Apr => &[],
            Temporal::Lp | Temporal::LpSmooth => &[Layer::Position, Layer::Depth],
        }
    }
}

/// A handle on a chain's temporal state ([`crate::Denoiser::temporal_state`]):
/// given to the configuration of an adaptive pass's denoiser
/// ([`crate::Config::temporal_state`]), its sample map reads what the
/// filter will make of the frame (TEMPORAL-MAP).
#[derive(Clone)]
pub struct TemporalState(pub(crate) Arc<TemporalStage>);

impl std::fmt::Debug for TemporalState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = self.0.size();
        write!(f, "TemporalState({w}x{h})")
    }
}

/// The factors the filter reads the method's error estimate by.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct TemporalScales {
    /// TEMPORAL-MISREG: the factor the estimate is low by on average
    /// (`MethodInfo::error_scale`, or its `pyramid_error_scale`).
    pub error: f32,
    /// TEMPORAL-TEST-SCALE: the factor in TEMPORAL-INFLATE's colour test, the
    /// method's output noise over its estimate relative to WLR's
    /// (`MethodInfo::inflate_scale`, `--opt temporal.inflate`).
    pub inflate: f32,
}

impl Default for TemporalScales {
    /// 1 and 1: the estimate as it is, WLR's test.
    fn default() -> Self {
        TemporalScales {
            error: 1.0,
            inflate: 1.0,
        }
    }
}

/// The filter's state and outputs on the GPU: the state of the last frame
/// (`prev`), the state being written (`next`, copied to `prev` at the end
/// of every frame), the filtered colour and the debug plane `source`.
pub struct TemporalStage {
    width: usize,
    height: usize,
    prev: PlaneSet,
    next: PlaneSet,
    /// R, G, B, then `source`.
    out: PlaneSet,
    motion: MotionSearch,
    /// The factors on the method's error estimate
    /// ([`set_scales`](Self::set_scales)).
    scales: Mutex<TemporalScales>,
    /// Whether the next recorded frame forgets the history: set at
    /// creation and by [`reset`](Self::reset).
    reset: AtomicBool,
    /// Frames recorded, and whether the last one forgot the history
    /// ([`history`](Self::history)).
    frames: AtomicU64,
    last_reset: AtomicBool,
}

impl TemporalStage {
    /// The stage for `width × height` frames, with no history.
    pub fn new(ctx: &Arc<GpuContext>, width: usize, height: usize) -> Result<TemporalStage> {
        let n = width * height;
        Ok(TemporalStage {
            width,
            height,
            prev: PlaneSet::new(ctx, "temporal.prev", n, TEMPORAL_STATE)?,
            next: PlaneSet::new(ctx, "temporal.next", n, TEMPORAL_STATE)?,
            out: PlaneSet::new(ctx, "temporal.out", n, 4)?,
            motion: MotionSearch::new(ctx, (width, height))?,
            scales: Mutex::new(TemporalScales::default()),
            reset: AtomicBool::new(true),
            frames: AtomicU64::new(0),
            last_reset: AtomicBool::new(false),
        })
    }

    /// Frames recorded since the stage was made, and whether the last one
    /// forgot the history (the first frame and every frame after a
    /// [`reset`](Self::reset)).
    pub fn history(&self) -> (u64, bool) {
        (
            self.frames.load(Ordering::SeqCst),
            self.last_reset.load(Ordering::SeqCst),
        )
    }

    /// The factors the filter reads the method's error estimate by, for
    /// the frames recorded from now on (default: 1 and 1).
    pub fn set_scales(&self, scales: TemporalScales) {
        *self.scales.lock().unwrap_or_else(PoisonError::into_inner) = scales;
    }

    /// The factors of [`set_scales`](Self::set_scales).
    pub fn scales(&self) -> TemporalScales {
        *self.scales.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Forgets the history: the next frame reinitialises every pixel (a
    /// cut).
    pub fn reset(&self) {
        self.reset.store(true, Ordering::SeqCst);
    }

    /// The push constants of a frame: with a reset pending, every pixel
    /// restarts; otherwise the windows follow TEMPORAL-MOTION's search.
    fn push(&self, reset: bool) -> TemporalPush {
        let scales = self.scales();
        TemporalPush {
            width: self.width as u32,
            height: self.height as u32,
            flags: if reset {
                TEMPORAL_RESET
            } else {
                TEMPORAL_MOTION
            },
            lambda: TEMPORAL_LAMBDA,
            p00: TEMPORAL_RESET_P00,
            p11: TEMPORAL_RESET_P11,
            error_scale: scales.error,
            inflate_scale: scales.inflate,
            ..Default::default()
        }
    }

    /// Records one frame: the filter of `inp.color` (the method's output)
    /// with the statistics' planes, then the copy of the new state over
    /// the old. A counting batch leaves a pending reset pending.
    pub fn record(&self, batch: &mut Batch, precision: Precision, inp: &TemporalIn) -> Result<()> {
        let reset = if batch.is_counting() {
            self.reset.load(Ordering::SeqCst)
        } else {
            let reset = self.reset.swap(false, Ordering::SeqCst);
            self.frames.fetch_add(1, Ordering::SeqCst);
            self.last_reset.store(reset, Ordering::SeqCst);
            reset
        };
        let out = TemporalOut {
            next: self.next.all(),
            color: self.color(),
            source: self.source(),
        };
        let push = self.push(reset);
        if !reset {
            self.motion.record(batch, precision, inp, &self.prev)?;
        }
        let motion = self.motion.offsets();
        lp_temporal::record(batch, precision, &push, inp, self.prev.all(), motion, &out)?;
        batch.copy(self.next.all(), self.prev.all());
        Ok(())
    }

    /// Records the filter's factor on `error` into `scaled` for an adaptive
    /// pass of the frame the filter will see next (TEMPORAL-MAP), from its
    /// state without changing it: `inp` is the pass's reconstruction and
    /// statistics.
    pub fn record_gain(
        &self,
        batch: &mut Batch,
        precision: Precision,
        inp: &TemporalIn,
        error: [BufferSlice; 3],
        scaled: [BufferSlice; 3],
    ) -> Result<()> {
        let reset = self.reset.load(Ordering::SeqCst);
        let push = self.push(reset);
        if !reset {
            self.motion.record(batch, precision, inp, &self.prev)?;
        }
        let motion = self.motion.offsets();
        lp_temporal_gain::record(
            batch,
            precision,
            &push,
            inp,
            self.prev.all(),
            motion,
            error,
            scaled,
        )
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The filtered colour planes R, G, B.
    pub fn color(&self) -> [BufferSlice; 3] {
        [self.out.plane(0), self.out.plane(1), self.out.plane(2)]
    }

    /// The debug plane `source` of the last frame (see
    /// [`debug_layers`](Self::debug_layers)).
    pub fn source(&self) -> BufferSlice {
        self.out.plane(3)
    }

    /// `P00` of the last frame after its update, per pixel (0 where the
    /// pixel was passed through).
    pub fn p00(&self) -> BufferSlice {
        self.prev.plane(TEMPORAL_P00)
    }

    /// The debug maps of the last frame, given its `source` plane (as
    /// downloaded): `temporal_source` (the reprojection's offset
    /// `(dy + 3)·7 + dx + 3` from the window's centre, −1 where the pixel
    /// was reset, −2 where it was passed through), `temporal_p00` (`P00`
    /// after the update: the intercept's variance per unit noise) and
    /// `temporal_motion_x`, `temporal_motion_y` (the window's centre less
    /// the pixel, TEMPORAL-MOTION; 0 on a frame that reset every pixel).
    pub fn debug_layers(&self, source: Vec<f32>) -> Result<Vec<(String, Vec<f32>)>> {
        let p00 = self.prev.download_plane::<f32>(TEMPORAL_P00)?;
        let (mx, my) = if self.last_reset.load(Ordering::SeqCst) {
            let n = self.width * self.height;
            (vec![0.0; n], vec![0.0; n])
        } else {
            self.motion.download_centres()?
        };
        Ok(vec![
            ("temporal_source".into(), source),
            ("temporal_p00".into(), p00),
            ("temporal_motion_x".into(), mx),
            ("temporal_motion_y".into(), my),
        ])
    }
}

/// TEMPORAL-MOTION on the GPU: pyramids of a frame's positions and of the
/// previous state's (levels 1 to [`TEMPORAL_MOTION_LEVELS`], pooled by
/// `pyramid_pool`), and each level's offsets, searched from the coarsest
/// level to the full resolution (`temporal_motion`).
struct MotionSearch {
    /// Per level: its size, this frame's planes and the previous one's
    /// (X, Y, Z, count each), and its offsets X, Y.
    levels: Vec<MotionLevel>,
    size: (usize, usize),
    /// Level 0's offsets X, Y: each pixel's.
    offsets: PlaneSet,
}

struct MotionLevel {
    size: (usize, usize),
    cur: PlaneSet,
    prev: PlaneSet,
    offsets: PlaneSet,
}

fn four(set: &PlaneSet) -> LevelPlanes {
    [0, 1, 2, 3].map(|k| set.plane(k))
}

impl MotionSearch {
    fn new(ctx: &Arc<GpuContext>, size: (usize, usize)) -> Result<MotionSearch> {
        let mut levels = Vec::with_capacity(TEMPORAL_MOTION_LEVELS);
        let mut s = size;
        for l in 1..=TEMPORAL_MOTION_LEVELS {
            s = (s.0.div_ceil(2), s.1.div_ceil(2));
            let n = s.0 * s.1;
            levels.push(MotionLevel {
                size: s,
                cur: PlaneSet::new(ctx, &format!("temporal.motion{l}.cur"), n, 4)?,
                prev: PlaneSet::new(ctx, &format!("temporal.motion{l}.prev"), n, 4)?,
                offsets: PlaneSet::new(ctx, &format!("temporal.motion{l}.offsets"), n, 2)?,
            });
        }
        let offsets = PlaneSet::new(ctx, "temporal.motion0.offsets", size.0 * size.1, 2)?;
        Ok(MotionSearch {
            levels,
            size,
            offsets,
        })
    }

    /// Level 0's offsets X, Y (what `lp_temporal` reads).
    fn offsets(&self) -> [BufferSlice; 2] {
        [self.offsets.plane(0), self.offsets.plane(1)]
    }

    /// Records the pyramids of `inp`'s positions and of the state `prev`,
    /// then the search from the coarsest level to the full resolution.
    fn record(
        &self,
        batch: &mut Batch,
        precision: Precision,
        inp: &TemporalIn,
        prev: &PlaneSet,
    ) -> Result<()> {
        let p = inp.position;
        let full_cur: LevelPlanes = [p[0], p[1], p[2], inp.spp];
        let full_prev: LevelPlanes = [9, 10, 11, TEMPORAL_VALID].map(|k| prev.plane(k));
        let (mut fine_size, mut fine_cur, mut fine_prev) = (self.size, full_cur, full_prev);
        for level in &self.levels {
            for (fine, coarse) in [(&fine_cur, &level.cur), (&fine_prev, &level.prev)] {
                for k in 0..4 {
                    let push = PyramidPush {
                        width: level.size.0 as u32,
                        height: level.size.1 as u32,
                        kind: if k == 3 { PYRAMID_COUNT } else { PYRAMID_MEAN },
                        other_width: fine_size.0 as u32,
                        other_height: fine_size.1 as u32,
                        ..Default::default()
                    };
                    pyramid_pool::record(
                        batch,
                        precision,
                        &push,
                        fine[k],
                        fine[3],
                        coarse.plane(k),
                    )?;
                }
            }
            fine_size = level.size;
            fine_cur = four(&level.cur);
            fine_prev = four(&level.prev);
        }
        // From the coarsest level to level 0, which reads the frames' own
        // planes: (size, this frame's, the previous one's, offsets).
        let pooled = self.levels.iter().rev().map(|l| {
            let out = [l.offsets.plane(0), l.offsets.plane(1)];
            (l.size, four(&l.cur), four(&l.prev), out)
        });
        let full = (self.size, full_cur, full_prev, self.offsets());
        let mut coarser: Option<((usize, usize), [BufferSlice; 2])> = None;
        for (size, cur, prv, out) in pooled.chain(std::iter::once(full)) {
            // Not read at the coarsest level.
            let (csize, coarse) = coarser.unwrap_or(((1, 1), [cur[0], cur[1]]));
            let push = MotionPush {
                width: size.0 as u32,
                height: size.1 as u32,
                coarse: coarser.is_some() as u32,
                coarse_width: csize.0 as u32,
                coarse_height: csize.1 as u32,
                radius: TEMPORAL_MOTION_RADIUS,
                ..Default::default()
            };
            temporal_motion::record(batch, precision, &push, &cur, &prv, coarse, out)?;
            coarser = Some((size, out));
        }
        Ok(())
    }

    /// The last search's window centres less the pixel, per pixel (X, Y).
    fn download_centres(&self) -> Result<(Vec<f32>, Vec<f32>)> {
        Ok((
            self.offsets.download_plane::<f32>(0)?,
            self.offsets.download_plane::<f32>(1)?,
        ))
    }
}

/// The host copy of what one frame of the filter read and made, kept for
/// the pass in reverse order of TEMPORAL-SMOOTH ([`SmoothStage`]).
#[derive(Clone, Debug)]
pub struct FilterRecord {
    /// The filter's inputs in the order of [`TemporalIn::planes`]: the
    /// method's colour (3), position (3), position variance (3), depth,
    /// samples, the method's error estimate (3).
    pub inputs: Vec<Vec<f32>>,
    /// `P00` after the update ([`TemporalStage::p00`]).
    pub p00: Vec<f32>,
    /// The frames' `(width, height)`.
    pub size: (usize, usize),
    /// The stage's [`history`](TemporalStage::history) after the frame.
    pub history: (u64, bool),
    /// The stage's factors ([`TemporalStage::set_scales`]).
    pub scales: TemporalScales,
}

impl TemporalStage {
    /// The host copy of the last frame's inputs `inp` and `P00`.
    pub fn download_record(&self, ctx: &Arc<GpuContext>, inp: &TemporalIn) -> Result<FilterRecord> {
        let n = self.width * self.height;
        let read = |s: BufferSlice| crate::gpu::buffer::read_slice(ctx, s, n);
        Ok(FilterRecord {
            inputs: inp.planes().into_iter().map(read).collect::<Result<_>>()?,
            p00: read(self.p00())?,
            size: self.size(),
            history: self.history(),
            scales: self.scales(),
        })
    }
}

/// TEMPORAL-SMOOTH's pass in reverse order: §10.1's filter over the frames
/// kept by the forward pass ([`FilterRecord`]), last frame first, each
/// combined with the forward pass's output by `lp_smooth`.
pub struct SmoothStage {
    ctx: Arc<GpuContext>,
    precision: Precision,
    backward: TemporalStage,
    /// A frame's [`FilterRecord::inputs`].
    inputs: PlaneSet,
    /// The forward pass's colour R, G, B and `P00`.
    forward: PlaneSet,
    out: PlaneSet,
}

impl SmoothStage {
    /// The stage for `width × height` frames.
    pub fn new(
        ctx: &Arc<GpuContext>,
        (width, height): (usize, usize),
        precision: Precision,
    ) -> Result<SmoothStage> {
        let n = width * height;
        Ok(SmoothStage {
            ctx: ctx.clone(),
            precision,
            backward: TemporalStage::new(ctx, width, height)?,
            inputs: PlaneSet::new(ctx, "smooth.inputs", n, INPUT_PLANES)?,
            forward: PlaneSet::new(ctx, "smooth.forward", n, 4)?,
            out: PlaneSet::new(ctx, "smooth.out", n, 3)?,
        })
    }

    /// Builds the pipelines its frames record.
    pub fn build_pipelines(&self) -> Result<()> {
        for decl in [
            &lp_temporal::DECL,
            &lp_smooth::DECL,
            &temporal_motion::DECL,
            &pyramid_pool::DECL,
        ] {
            self.ctx.pipeline(decl, self.precision)?;
        }
        Ok(())
    }

    /// The next frame in reverse order: `record` and `forward` (the
    /// forward pass's output colour) of a frame, after the frames that
    /// follow it in the sequence. `frames`: how many frames each direction
    /// has filtered with this one since the sequence began (in frame order
    /// from the first, in reverse from the last; `(k + 1, n − k)` for frame
    /// `k` of `n`), from which SMOOTH-SHORT knows the information a
    /// direction that met no change holds; a reverse count of 1 starts the
    /// reverse pass. Returns the combined colour and the kernels' timings.
    pub fn run(
        &self,
        record: &FilterRecord,
        forward: &RgbImage,
        frames: (u64, u64),
        progress: bool,
    ) -> Result<(RgbImage, Vec<KernelTiming>)> {
        let (w, h) = self.backward.size();
        if record.inputs.len() != INPUT_PLANES || forward.width != w || forward.height != h {
            return Err(Error::InvalidArgument(format!(
                "a frame of the two-way filter is not of its {w}x{h} frames"
            )));
        }
        for (k, p) in record.inputs.iter().enumerate() {
            self.inputs.upload_plane(k, p)?;
        }
        for (c, p) in forward.planes.iter().enumerate() {
            self.forward.upload_plane(c, p)?;
        }
        self.forward.upload_plane(3, &record.p00)?;
        if frames.1 <= 1 {
            self.backward.reset();
        }
        self.backward.set_scales(record.scales);
        let inp = TemporalIn::from_planes(|k| self.inputs.plane(k));
        let mut batch = Batch::new(&self.ctx)?;
        batch.progress = progress;
        self.backward.record(&mut batch, self.precision, &inp)?;
        let full =
            |n: u64| full_information(n, TEMPORAL_LAMBDA as f64, TEMPORAL_RESET_P00 as f64) as f32;
        let push = TwoWayPush {
            width: w as u32,
            height: h as u32,
            full_forward: full(frames.0),
            full_backward: full(frames.1),
            ..Default::default()
        };
        let fwd = Direction {
            color: [
                self.forward.plane(0),
                self.forward.plane(1),
                self.forward.plane(2),
            ],
            p00: self.forward.plane(3),
        };
        let bwd = Direction {
            color: self.backward.color(),
            p00: self.backward.p00(),
        };
        let out = [self.out.plane(0), self.out.plane(1), self.out.plane(2)];
        lp_smooth::record(
            &mut batch,
            self.precision,
            &push,
            inp.color,
            &fwd,
            &bwd,
            out,
        )?;
        let timings = batch.finish()?;
        let planes = [0, 1, 2].map(|c| self.out.download_plane::<f32>(c));
        let [r, g, b] = planes;
        Ok((RgbImage::from_planes(w, h, [r?, g?, b?]), timings))
    }
}
