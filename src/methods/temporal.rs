//! Temporal reconstruction of sequences (spec §10): a stage after the
//! method that filters its output over the frames, keeping its state on
//! the GPU from call to call.
//!
//! §10.1, the LP temporal filter ([`Temporal::Lp`]): per pixel a recursive
//! least-squares fit over time of the method's output (with TEMPORAL-PRIOR's
//! reset, of a constant: a mean with forgetting), reprojected from the
//! previous frame by the world position (`kernels::lp_temporal`). The paper
//! applies it to LP; here it follows any method.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuContext, PlaneSet, Precision};
use crate::image::Layer;
use crate::kernels::lp_temporal::{self, TemporalIn, TemporalOut};
use crate::kernels::lp_temporal_gain;
use crate::shared::{
    TemporalPush, TEMPORAL_LAMBDA, TEMPORAL_P00, TEMPORAL_RESET, TEMPORAL_RESET_P00,
    TEMPORAL_RESET_P11, TEMPORAL_STATE,
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
}

impl Temporal {
    /// An error for [`Temporal::Apr`], which only a
    /// [`crate::SequenceDenoiser`] runs; `Ok` otherwise.
    pub fn refuse_window(self) -> Result<()> {
        if self == Temporal::Apr {
            return Err(Error::InvalidArgument(
                "APR's temporal window (§10.2) reconstructs a sequence from the frames around each one: use a SequenceDenoiser".into(),
            ));
        }
        Ok(())
    }

    /// The layers the stage reads, besides the method's output and `spp`.
    pub fn needs(self) -> &'static [Layer] {
        match self {
            Temporal::Off | Temporal::Apr => &[],
            Temporal::Lp => &[Layer::Position, Layer::Depth],
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
    /// Whether the next recorded frame forgets the history: set at
    /// creation and by [`reset`](Self::reset).
    reset: AtomicBool,
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
            reset: AtomicBool::new(true),
        })
    }

    /// Forgets the history: the next frame reinitialises every pixel (a
    /// cut).
    pub fn reset(&self) {
        self.reset.store(true, Ordering::SeqCst);
    }

    /// The push constants of a frame: with a reset pending, every pixel
    /// restarts.
    fn push(&self, reset: bool) -> TemporalPush {
        TemporalPush {
            width: self.width as u32,
            height: self.height as u32,
            flags: if reset { TEMPORAL_RESET } else { 0 },
            lambda: TEMPORAL_LAMBDA,
            p00: TEMPORAL_RESET_P00,
            p11: TEMPORAL_RESET_P11,
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
            self.reset.swap(false, Ordering::SeqCst)
        };
        let out = TemporalOut {
            next: self.next.all(),
            color: self.color(),
            source: self.source(),
        };
        let push = self.push(reset);
        lp_temporal::record(batch, precision, &push, inp, self.prev.all(), &out)?;
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
        let push = self.push(self.reset.load(Ordering::SeqCst));
        lp_temporal_gain::record(batch, precision, &push, inp, self.prev.all(), error, scaled)
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

    /// The debug maps of the last frame, given its `source` plane (as
    /// downloaded): `temporal_source` (the reprojection's offset
    /// `(dy + 3)·7 + dx + 3`, −1 where the pixel was reset, −2 where it was
    /// passed through) and `temporal_p00` (`P00` after the update: the
    /// intercept's variance per unit noise).
    pub fn debug_layers(&self, source: Vec<f32>) -> Result<Vec<(String, Vec<f32>)>> {
        let p00 = self.prev.download_plane::<f32>(TEMPORAL_P00)?;
        Ok(vec![
            ("temporal_source".into(), source),
            ("temporal_p00".into(), p00),
        ])
    }
}
