//! `none`: no reconstruction. The output is the sanitised input colour
//! (§0.4), the Monte Carlo mean, with its variance `v_i` as the error
//! estimate and `d_i = 0`, so its sample map follows the input variance
//! (`ΔMSE = v_i / n_i`). It checks inputs, the pipeline and the metrics.

use super::chain::ChainOutput;
use super::registry::{self, CpuResult, GpuStage, MethodInfo, StageRun};
use super::sampling::{self, DimSource, SamplingParams};
use super::stats::GpuStats;
use super::tiles::Rect;
use super::{prepare, Method};
use crate::error::Result;
use crate::gpu::{Batch, BufferSlice, PlaneSet};
use crate::image::{Layer, RgbImage};

/// `none`'s entry in the method registry.
pub static INFO: MethodInfo = MethodInfo {
    method: Method::None,
    name: "none",
    about: "no reconstruction: the sanitised input colour (spec §0.4), for checking inputs, the pipeline and the metrics",
    needs: &[Layer::Color, Layer::Spp],
    prefilter_auto: false,
    // Its output is the Monte Carlo mean by definition.
    outliers_auto: false,
    pyramid_auto: false,
    blend: super::blend::BlendDefaults {
        radius: 0,
        ..super::blend::BlendDefaults::BASE
    },
    map_method: Method::None,
    passes: 5,
    pass_cap: None,
    map_check: false,
    sampling: SamplingParams {
        eps: sampling::EPS_DEFAULT,
        sigma_s: 0.0,
        e_is_dmse: false,
        dim: DimSource::Plain,
        floor: 0.0,
    },
    error_scale: 1.0,
    // The pyramid never runs after `none` (it has no low band to take).
    pyramid_error_scale: 1.0,
    // TEMPORAL-TEST-SCALE: WLR's factor (the record has the measured ratio).
    inflate_scale: 1.0,
    align: 1,
    halo: |_| Ok(0),
    arena_bytes: registry::no_bytes,
    arena_kept: registry::nothing_kept,
    options_for: registry::same_options,
    ring_bytes: registry::no_bytes,
    gpu: |a| {
        let (w, h) = a.size;
        Ok(Box::new(NoneStage {
            zero: PlaneSet::new(a.ctx, "none.dim", w * h, 1)?,
        }))
    },
    cpu: |clean, a| {
        let (w, h) = (clean.width, clean.height);
        let var = clean
            .get(Layer::ColorVariance)
            .expect("sanitation estimates a missing colour variance");
        let mut debug = Vec::new();
        if a.debug {
            for (c, name) in ["R", "G", "B"].iter().enumerate() {
                debug.push((format!("color_variance.{name}"), var[c].clone()));
            }
        }
        Ok(CpuResult {
            color: prepare::colour_of(clean),
            error: RgbImage::from_planes(w, h, [var[0].clone(), var[1].clone(), var[2].clone()]),
            dim: vec![0.0; w * h],
            debug,
            stats: Vec::new(),
            map_error: None,
        })
    },
};

/// `none`'s GPU stage: a zero plane for the local dimension.
struct NoneStage {
    zero: PlaneSet,
}

impl GpuStage for NoneStage {
    fn record(&self, batch: &mut Batch, _: &StageRun) -> Result<()> {
        batch.fill(self.zero.plane(0), 0);
        Ok(())
    }

    /// The sanitised input, not yet clamped.
    fn color(&self, stats: &GpuStats) -> [BufferSlice; 3] {
        std::array::from_fn(|c| stats.plane(Layer::Color, c))
    }

    /// The variance of the mean: the MSE of the unfiltered input.
    fn error(&self, stats: &GpuStats) -> [BufferSlice; 3] {
        std::array::from_fn(|c| stats.plane(Layer::ColorVariance, c))
    }

    fn dim(&self) -> (BufferSlice, bool) {
        (self.zero.plane(0), false)
    }

    fn download(
        &self,
        stats: &GpuStats,
        _: (usize, usize),
        _: Option<Rect>,
        debug: bool,
        out: &mut ChainOutput,
    ) -> Result<()> {
        // The colour and the count only (not every layer), clamped as the
        // methods' outputs are.
        let clean = stats.download_layers(&[Layer::Color, Layer::Spp])?;
        out.color = prepare::colour_of(&clean);
        if debug {
            let var = stats.download_layers(&[Layer::ColorVariance])?;
            let planes = var.get(Layer::ColorVariance).expect("just downloaded");
            for (c, name) in ["R", "G", "B"].iter().enumerate() {
                out.debug
                    .push((format!("color_variance.{name}"), planes[c].clone()));
            }
        }
        Ok(())
    }
}
