//! Sequences of an animated scene ([`Scene::at_frame`]): each frame through
//! the adaptive loop with a seed of its own, so a frame renders the same
//! alone or as part of any range, on one context (one set of pipelines).
//! With a temporal stage ([`Temporal`]) one final denoiser reconstructs
//! every frame, carrying the filter's state from frame to frame; its
//! output then depends on the frames before it in the range. With APR's
//! temporal window ([`Temporal::Apr`]) a [`SequenceDenoiser`] reconstructs
//! each frame from the range's frames around it once they are rendered.
//! With the two-way filter ([`Temporal::LpSmooth`]) the final denoiser
//! filters in frame order, as with [`Temporal::Lp`], and a [`Smoother`]
//! combines it with the filter in reverse order once the range is
//! rendered; until then the frames' statistics wait in a temporary file
//! ([`PlaneSpill`]).

use std::collections::VecDeque;
use std::ops::Range;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use super::adaptive::{self, LoopConfig, LoopResult};
use super::{Renderer, Scene};
use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use crate::image::{Layer, StatsImage};
use crate::spill::PlaneSpill;
use crate::{Denoiser, SequenceDenoiser, Smoother, Source, Temporal};

/// The seed of frame `frame` of a sequence rendered with `seed`.
pub fn frame_seed(seed: u64, frame: u32) -> u64 {
    seed ^ (frame as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

/// One rendered frame of a sequence.
#[derive(Debug)]
pub struct SequenceFrame {
    /// Its frame number.
    pub number: u32,
    /// Its seed ([`frame_seed`]).
    pub seed: u64,
    /// The scene placed at this frame.
    pub scene: Scene,
    /// The loop's result: the reconstruction, its schedule and timings.
    pub result: LoopResult,
    /// The render statistics (the denoiser's input).
    pub stats: StatsImage,
}

/// Renders frames `frames` of `scene`'s sequence at `size` through `cfg`,
/// reconstructing the final images with the temporal stage `temporal`
/// (from the range's first frame on), and hands each to `each` in frame
/// order. A range outside the scene's frames is an error before anything
/// renders.
pub fn render_frames(
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    frames: Range<u32>,
    (width, height): (usize, usize),
    seed: u64,
    cfg: &LoopConfig,
    temporal: Temporal,
    stop: &AtomicBool,
    mut each: impl FnMut(SequenceFrame) -> Result<()>,
) -> Result<()> {
    let n = scene.frames();
    if frames.end > n {
        return Err(Error::InvalidArgument(format!(
            "frames {}..{}: the scene has frames 0..{n}{}",
            frames.start,
            frames.end,
            if scene.animation.is_none() {
                " (it has no [animation])"
            } else {
                ""
            }
        )));
    }
    let mut last: Option<Denoiser> = None;
    // APR's window and the two-way filter: the frames rendered and not yet
    // reconstructed.
    let mut window: Option<SequenceDenoiser> = None;
    let mut smoother: Option<(Smoother, StatsSpill)> = None;
    let mut waiting: VecDeque<SequenceFrame> = VecDeque::new();
    // The lens centre of the scene's frame 0 is every frame's position
    // origin: the final denoiser finalises each frame with the layout it
    // was made for, its temporal stage compares positions across frames,
    // and a frame's statistics do not depend on where the range starts.
    let origin = scene.at_frame(0)?.camera.position;
    for number in frames {
        let at = scene.at_frame(number)?;
        let seed = frame_seed(seed, number);
        let renderer = Renderer::new(ctx, &at, width, height, seed)?
            .with_position_origin(origin)
            .with_feature_samples(cfg.feature_samples);
        if temporal == Temporal::Apr {
            let result = adaptive::render_passes(ctx, &renderer, cfg, stop, |_| {})?;
            let stats = renderer.statistics_at(cfg.precision)?;
            if window.is_none() {
                let config = adaptive::final_config(cfg, temporal);
                window = Some(SequenceDenoiser::new(
                    ctx,
                    Source::of_image(&stats),
                    config,
                )?);
            }
            let done = window.as_mut().expect("just set").push(&stats)?;
            waiting.push_back(SequenceFrame {
                number,
                seed,
                scene: at,
                result,
                stats,
            });
            release(done, &mut waiting, &mut each)?;
            continue;
        }
        if temporal != Temporal::Off && last.is_none() {
            // The two-way filter's forward direction is the filter itself.
            let forward = match temporal {
                Temporal::LpSmooth => Temporal::Lp,
                t => t,
            };
            let d = adaptive::final_denoiser(ctx, renderer.layout(), cfg, forward)?;
            if temporal == Temporal::LpSmooth {
                smoother = Some((Smoother::new(ctx, &d)?, StatsSpill::new()?));
            }
            last = Some(d);
        }
        let result = adaptive::render_with_final(ctx, &renderer, cfg, stop, |_| {}, last.as_ref())?;
        let stats = renderer.statistics_at(cfg.precision)?;
        let mut frame = SequenceFrame {
            number,
            seed,
            scene: at,
            result,
            stats,
        };
        if let (Some((s, spill)), Some(d)) = (&mut smoother, &last) {
            s.keep(d, &frame.result.frame.color)?;
            // The smoother keeps the colour, and the spill the statistics,
            // until the end.
            frame.result.frame.color = crate::image::RgbImage::new(0, 0);
            spill.put(&mut frame.stats)?;
            waiting.push_back(frame);
            continue;
        }
        each(frame)?;
    }
    if let Some(w) = &mut window {
        let done = w.finish()?;
        release(done, &mut waiting, &mut each)?;
    }
    if let Some((s, spill)) = &mut smoother {
        s.finish_each(|t, color, timings| {
            let f = &mut waiting[t].result.frame;
            f.color = color;
            f.timings.extend(timings);
            Ok(())
        })?;
        for (t, mut f) in waiting.drain(..).enumerate() {
            f.stats = spill.take(t)?;
            each(f)?;
        }
    }
    Ok(())
}

/// The statistics of the frames waiting for the two-way filter, in a
/// temporary file ([`PlaneSpill`]) rather than in memory.
struct StatsSpill {
    spill: PlaneSpill,
    /// Each frame's size and layers, with their planes' counts.
    shapes: Vec<((usize, usize), LayerPlanes)>,
}

/// A statistics image's layers and their planes' counts.
type LayerPlanes = Vec<(Layer, usize)>;

impl StatsSpill {
    fn new() -> Result<StatsSpill> {
        Ok(StatsSpill {
            spill: PlaneSpill::new("the rendered statistics awaiting the two-way filter")?,
            shapes: Vec::new(),
        })
    }

    /// Appends `stats`'s planes and leaves it without layers.
    fn put(&mut self, stats: &mut StatsImage) -> Result<()> {
        let layers: LayerPlanes = stats.layers().map(|(l, p)| (l, p.len())).collect();
        self.spill.push(
            stats
                .layers()
                .flat_map(|(_, p)| p.iter().map(|v| v.as_slice())),
        )?;
        self.shapes.push(((stats.width, stats.height), layers));
        *stats = StatsImage::new(stats.width, stats.height);
        Ok(())
    }

    /// Frame `k`'s statistics.
    fn take(&mut self, k: usize) -> Result<StatsImage> {
        let mut planes = self.spill.read(k)?.into_iter();
        let ((w, h), layers) = &self.shapes[k];
        let mut stats = StatsImage::new(*w, *h);
        for &(layer, n) in layers {
            stats.set(layer, planes.by_ref().take(n).collect());
        }
        Ok(stats)
    }
}

/// Hands the frames APR's window finished (`done`, in order) to `each`,
/// each with its rendered frame from `waiting` (the window's colour, error
/// and dimension in place of the loop's).
fn release(
    done: Vec<(usize, crate::Frame)>,
    waiting: &mut VecDeque<SequenceFrame>,
    each: &mut impl FnMut(SequenceFrame) -> Result<()>,
) -> Result<()> {
    for (_, frame) in done {
        let mut f = waiting.pop_front().expect("a frame out is a frame in");
        f.result.frame = crate::Frame {
            samples: f.result.frame.samples.take(),
            ..frame
        };
        each(f)?;
    }
    Ok(())
}
