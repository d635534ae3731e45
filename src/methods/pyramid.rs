//! The pyramid's low band (PYRAMID-LOWBAND): a stage of the chain for
//! every reconstruction. The sanitised statistics are pooled over 2×2
//! blocks into a half-resolution image, the same method reconstructs it in
//! a second chain (its windows reach twice as far in the image), and the
//! fine output takes its low band from the coarse one — as a ratio, in
//! proportion to the two error estimates (`pyramid_merge`). It removes
//! low-frequency residual noise larger than the method's windows, where
//! light arrives only indirectly; the error estimate and the features
//! decide where it acts.

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::kernels::pyramid_merge::{self, Level};
use crate::kernels::pyramid_pool;
use crate::reference::pyramid_merge as merge_twin;
use crate::reference::pyramid_pool::{self as pool_twin, coarse_size};
use crate::shared::{PyramidPush, PYRAMID_COUNT, PYRAMID_EPS, PYRAMID_MEAN, PYRAMID_VARIANCE};

use super::chain::{ChainConfig, ChainInput, GpuChain};
use super::stats::GpuStats;
use super::temporal::Temporal;
use super::{prepare, DenoiseRequest, Method, Pass, Prefilter};

/// The smallest image side the pyramid runs on (its coarse level is half
/// of it: every method's smallest window still fits).
pub const MIN_SIDE: usize = 16;

/// The push constants of `pyramid_pool` for one plane of `kind` of a
/// `size` (fine) image.
pub fn pool_push(size: (usize, usize), kind: u32) -> PyramidPush {
    let (cw, ch) = coarse_size(size.0, size.1);
    PyramidPush {
        width: cw as u32,
        height: ch as u32,
        kind,
        other_width: size.0 as u32,
        other_height: size.1 as u32,
        ..Default::default()
    }
}

/// The push constants of `pyramid_merge` over a `size` (fine) image.
pub fn merge_push(size: (usize, usize)) -> PyramidPush {
    let (cw, ch) = coarse_size(size.0, size.1);
    PyramidPush {
        width: size.0 as u32,
        height: size.1 as u32,
        other_width: cw as u32,
        other_height: ch as u32,
        eps: PYRAMID_EPS,
        ..Default::default()
    }
}

/// Whether the pyramid's low band runs (`Config::pyramid`); by default
/// after `auto` only (PYRAMID-AUTO).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Pyramid {
    /// The method's default ([`super::MethodInfo::pyramid_auto`]: `auto`
    /// only) in a final reconstruction ([`Pass::Final`]; an adaptive pass's
    /// map reads the method's estimate) of an image of at least
    /// [`MIN_SIDE`] pixels a side.
    #[default]
    Auto,
    /// Always (an error for `none` or a smaller image).
    On,
    /// Never.
    Off,
}

impl Pyramid {
    /// Whether the stage runs for `method` in a `pass` over a `size` image
    /// ([`Pyramid::On`] where it cannot run is refused by [`check`] when
    /// the chain is built).
    pub fn resolve(self, method: Method, pass: Pass, size: (usize, usize)) -> bool {
        match self {
            Pyramid::Auto => {
                method.info().pyramid_auto && pass == Pass::Final && check(method, size).is_ok()
            }
            Pyramid::On => true,
            Pyramid::Off => false,
        }
    }
}

/// `Err` unless the stage can run for `method` on a `size` image.
pub fn check(method: Method, size: (usize, usize)) -> Result<()> {
    check_level("the pyramid", method, size)
}

/// `Err` unless a stage that runs `method` on the 2×2-pooled level
/// (`stage`, named in the message: the pyramid, a coarse sample map) can
/// run for a `size` image: a reconstruction (not `none`) whose smallest
/// window fits the pooled level ([`MIN_SIDE`]).
pub fn check_level(stage: &str, method: Method, (w, h): (usize, usize)) -> Result<()> {
    if method == Method::None {
        return Err(Error::InvalidArgument(format!(
            "{stage} runs a reconstruction on the half-resolution level: method none has none"
        )));
    }
    if w < MIN_SIDE || h < MIN_SIDE {
        return Err(Error::InvalidArgument(format!(
            "{stage} needs an image of at least {MIN_SIDE}x{MIN_SIDE} pixels, not {w}x{h}"
        )));
    }
    Ok(())
}

/// How a statistics layer pools ([`crate::shared::PyramidPush::kind`]).
pub fn pool_kind(layer: Layer) -> u32 {
    match layer {
        Layer::Spp => PYRAMID_COUNT,
        Layer::ColorVariance
        | Layer::AlbedoVariance
        | Layer::NormalVariance
        | Layer::DepthVariance
        | Layer::PositionVariance
        | Layer::PositionCovariance
        | Layer::VisibilityVariance => PYRAMID_VARIANCE,
        _ => PYRAMID_MEAN,
    }
}

/// The coarse level's chain and the merged planes.
pub struct PyramidStage {
    /// The same method on the pooled statistics.
    coarse: Box<GpuChain>,
    /// The merged colour R, G, B (planes 0–2) and error estimate (3–5).
    merged: PlaneSet,
    /// The fine image's size.
    size: (usize, usize),
}

impl std::fmt::Debug for PyramidStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PyramidStage")
            .field("size", &self.size)
            .finish()
    }
}

impl PyramidStage {
    /// The stage of a `size` chain reading `layers` with `config` (whose
    /// method must reconstruct: not `none`), where the G-buffer prefilter
    /// runs when `prefiltered`.
    pub fn new(
        ctx: &Arc<GpuContext>,
        size: (usize, usize),
        layers: &[Layer],
        config: &ChainConfig,
        prefiltered: bool,
    ) -> Result<PyramidStage> {
        let (w, h) = size;
        check(config.method, size)?;
        let (cw, ch) = coarse_size(w, h);
        // The coarse statistics have every variance layer (sanitation
        // estimates the missing ones): the fine level's choice of the
        // prefilter is made explicit, so both levels make the same one.
        let coarse_config = ChainConfig {
            pyramid: false,
            input_blend: false,
            prefilter: if prefiltered {
                Prefilter::On
            } else {
                Prefilter::Off
            },
            debug: false,
            error: true,
            temporal: Temporal::Off,
            temporal_state: None,
            coarse_map: false,
            ..config.clone()
        };
        let input = ChainInput::Stats {
            width: cw,
            height: ch,
            layers: prepare::output_layers(layers),
        };
        let coarse = Box::new(GpuChain::new(ctx, input, coarse_config)?);
        let merged = PlaneSet::new(ctx, "pyramid.merged", w * h, 6)?;
        Ok(PyramidStage {
            coarse,
            merged,
            size,
        })
    }

    /// Records the coarse level: every plane of the sanitised statistics
    /// `fine` pooled into the coarse chain's, and that chain's method. Runs
    /// after sanitation and before the fine level's outlier stage and
    /// prefilter, which change the statistics in place. `origin`: the
    /// image pixel of the fine level's pixel `(0, 0)` (a tile's; even).
    pub fn record_coarse(
        &self,
        batch: &mut Batch,
        p: Precision,
        fine: &GpuStats,
        origin: (u32, u32),
        total: Option<[u32; 3]>,
    ) -> Result<()> {
        record_pool(batch, p, self.size, fine, self.coarse.clean())?;
        self.coarse
            .record_pooled(batch, (origin.0 / 2, origin.1 / 2), total, false)
    }

    /// Records the merge of the fine level's reconstruction `fine` with the
    /// coarse one's into [`color`](Self::color) and [`error`](Self::error).
    pub fn record_merge(&self, batch: &mut Batch, p: Precision, fine: &Level) -> Result<()> {
        let push = merge_push(self.size);
        let coarse = Level {
            color: self.coarse.color(),
            error: self.coarse.error(),
            spp: self.coarse.clean().plane(Layer::Spp, 0),
        };
        pyramid_merge::record(batch, p, &push, fine, &coarse, self.color(), self.error())
    }

    /// The merged colour R, G, B.
    pub fn color(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|k| self.merged.plane(k))
    }

    /// The merged error estimate per channel.
    pub fn error(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|k| self.merged.plane(3 + k))
    }
}

/// Records the pooling of every plane of the sanitised statistics `fine`
/// (of a `size` image) over 2×2 blocks into `coarse`'s planes (the coarse
/// level's layers; [`pool_cpu`] is the twin).
pub fn record_pool(
    batch: &mut Batch,
    p: Precision,
    size: (usize, usize),
    fine: &GpuStats,
    coarse: &GpuStats,
) -> Result<()> {
    let spp = fine.plane(Layer::Spp, 0);
    for &(layer, _) in &coarse.index {
        let push = pool_push(size, pool_kind(layer));
        for c in 0..layer.channels().len() {
            pyramid_pool::record(
                batch,
                p,
                &push,
                fine.plane(layer, c),
                spp,
                coarse.plane(layer, c),
            )?;
        }
    }
    Ok(())
}

/// The statistics `clean` (sanitised) pooled over 2×2 blocks: the coarse
/// level's input, plane by plane as `pyramid_pool` makes it.
pub fn pool_cpu(clean: &StatsImage) -> StatsImage {
    let (w, h) = (clean.width, clean.height);
    let (cw, ch) = coarse_size(w, h);
    let mut pooled = StatsImage::new(cw, ch);
    let spp = spp_plane(clean);
    for (layer, planes) in clean.layers() {
        let push = pool_push((w, h), pool_kind(layer));
        let out = planes
            .iter()
            .map(|p| {
                let mut d = vec![0.0f32; cw * ch];
                pool_twin::pyramid_pool(&push, p, spp, &mut d);
                d
            })
            .collect();
        pooled.set(layer, out);
    }
    pooled
}

/// The CPU path of the stage: the request's method on the pooled
/// statistics `pooled` (with the prefilter when the fine level's ran,
/// `prefiltered`), and the merge's twin with the fine level's colour,
/// error estimate and sample counts `fine`. Returns the merged colour and
/// error estimate.
pub fn run_cpu(
    pooled: &StatsImage,
    fine: (&RgbImage, &RgbImage, &[f32]),
    req: &DenoiseRequest,
    prefiltered: bool,
) -> Result<(RgbImage, RgbImage)> {
    let (color, error, spp) = fine;
    let coarse_req = DenoiseRequest {
        pyramid: false,
        input_blend: false,
        prefilter: if prefiltered {
            Prefilter::On
        } else {
            Prefilter::Off
        },
        error: true,
        debug: false,
        budget: None,
        ..req.clone()
    };
    let coarse = super::denoise(None, pooled, &coarse_req)?;
    let coarse_error = coarse
        .error
        .ok_or_else(|| Error::InvalidArgument("the coarse level has no error estimate".into()))?;
    Ok(merge_cpu(
        &merge_twin::Level {
            color: color.plane_slices(),
            error: error.plane_slices(),
            spp,
        },
        &merge_twin::Level {
            color: coarse.color.plane_slices(),
            error: coarse_error.plane_slices(),
            spp: spp_plane(pooled),
        },
        (color.width, color.height),
    ))
}

/// The sample counts of statistics that have them (sanitised or pooled).
fn spp_plane(img: &StatsImage) -> &[f32] {
    &img.get(Layer::Spp).expect("the statistics have spp")[0]
}

/// The merge's twin over a `size` image: the merged colour and error
/// estimate of the levels `fine` and `coarse`.
pub fn merge_cpu(
    fine: &merge_twin::Level,
    coarse: &merge_twin::Level,
    size: (usize, usize),
) -> (RgbImage, RgbImage) {
    let mut out = RgbImage::new(size.0, size.1);
    let mut out_error = RgbImage::new(size.0, size.1);
    let [c0, c1, c2] = &mut out.planes;
    let [e0, e1, e2] = &mut out_error.planes;
    merge_twin::pyramid_merge(&merge_push(size), fine, coarse, [c0, c1, c2], [e0, e1, e2]);
    (out, out_error)
}
