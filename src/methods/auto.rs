//! `auto`: several methods on the same statistics, blended per pixel by
//! their own error estimates (AUTO-BLEND, ours; issue #41). The methods fail
//! in different places, and each one's `E_i` says where.
//!
//! The members ([`MEMBERS`]) run on the sanitised, prefiltered statistics.
//! `auto_score` writes six maps: each member's relative error estimate
//! `s_m = Σ_c E_m,c / (f_m,c² + 0.01)` and each pair's disagreement
//! `dis_ab = Σ_c (f_a,c − f_b,c)² / (f̄_c² + 0.01)`; `gauss_rows` and
//! `gauss_smooth` smooth them (the Gaussian of §0.5, σ = [`SIGMA`], over
//! valid pixels). `auto_blend` weighs member `m` by `1 / max(s_m, t_m)`,
//! `t_m` its error as the three-cornered hat of the disagreements gives it
//! (`t_0 = (dis01 + dis02 − dis12) / 2`, …), and exports the blend with the
//! error estimate `E_c = (Σ w_m √(k_m E_m,c) / Σ w_m)²`, `k_m` the factor
//! by which the hat raised the member's score. The local dimension `d_i` and
//! the sampling parameters of §9 are the first member's (WLR's); the
//! G-buffer prefilter and the outlier stage run once, around the whole
//! blend.

use std::sync::Arc;

use super::chain::{ChainConfig, ChainOutput};
use super::registry::{
    self, CpuArgs, CpuResult, GpuStage, MethodInfo, StageArgs, StageRun, REGRESSION_LAYERS,
};
use super::stats::GpuStats;
use super::tiles::Rect;
use super::Method;
use crate::error::Result;
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::kernels::{auto_blend, auto_score, gauss_rows, gauss_smooth};
use crate::reference;
use crate::shared::{AutoPush, SmoothPush, AUTO_MAPS, AUTO_MEMBERS};

/// The methods `auto` runs, in the order they are blended; the first one
/// gives `d_i` and the sampling parameters (AUTO-BLEND: the set that gained
/// most for its cost on the tuning scenes).
pub const MEMBERS: [Method; AUTO_MEMBERS] = [Method::Wlr, Method::Lp, Method::Apr];

/// σ (pixels) of the Gaussian that smooths each member's score before it
/// becomes a weight (AUTO-BLEND).
pub const SIGMA: f32 = 1.5;

/// A member's configuration: `auto`'s, with the member's method and its
/// error estimate on (the blend reads it).
fn member_config(c: &ChainConfig, m: Method) -> ChainConfig {
    ChainConfig {
        method: m,
        error: true,
        temporal: super::Temporal::Off,
        temporal_state: None,
        ..c.clone()
    }
}

/// `auto`'s entry in the method registry.
pub static INFO: MethodInfo = MethodInfo {
    method: Method::Auto,
    name: "auto",
    about: "WLR, LP and APR blended per pixel by their own error estimates (ours; LP's and APR's patents apply)",
    needs: &REGRESSION_LAYERS,
    prefilter_auto: true,
    outliers_auto: true,
    pyramid_auto: true,
    blend: super::blend::BlendDefaults {
        auto: false,
        radius: 3,
        k: 1.0,
    },
    map_method: Method::Auto,
    passes: super::wlr::INFO.passes,
    pass_cap: None,
    sampling: super::wlr::INFO.sampling,
    // ERROR-SCALE on the blend's estimate: uniform inputs of the eleven
    // tuning scenes at 4, 16 and 64 spp (AUTO-BLEND).
    error_scale: 2.5,
    // The least common multiple of the members' (APR's block grid).
    align: super::apr::INFO.align,
    halo: |c| {
        let mut h = 0;
        for m in MEMBERS {
            h = h.max((m.info().halo)(&member_config(c, m))?);
        }
        Ok(h + crate::shared::gaussian_radius(SIGMA as f64))
    },
    arena_bytes: registry::no_bytes,
    arena_kept: registry::nothing_kept,
    ring_bytes: |c, size| {
        MEMBERS
            .iter()
            .map(|&m| (m.info().ring_bytes)(&member_config(c, m), size))
            .sum()
    },
    gpu: |a| Ok(Box::new(AutoStage::new(a)?)),
    cpu: run_cpu,
};

/// One member's GPU stage, with its own arena (the members' scratch lives
/// while the later members run, so they cannot share the chain's).
struct Member {
    method: Method,
    config: ChainConfig,
    stage: Box<dyn GpuStage>,
    _arena: Option<Arc<GpuBuffer>>,
}

/// `auto`'s GPU stage: its members, their maps and the blend.
struct AutoStage {
    members: Vec<Member>,
    /// The [`AUTO_MAPS`] maps (smoothed in place), their row sums, the
    /// weights' row sums, then the blend's colour and error (3 + 3).
    planes: PlaneSet,
    size: (usize, usize),
    ctx: Arc<GpuContext>,
}

impl AutoStage {
    fn new(a: &StageArgs) -> Result<AutoStage> {
        let (w, h) = a.size;
        let mut members = Vec::with_capacity(MEMBERS.len());
        for m in MEMBERS {
            let config = member_config(a.config, m);
            let bytes = (m.info().arena_bytes)(&config, a.size);
            let arena = if bytes > 0 {
                let name = format!("auto.{}.arena", m.name());
                Some(Arc::new(GpuBuffer::new(a.ctx, &name, bytes)?))
            } else {
                None
            };
            let stage = (m.info().gpu)(&StageArgs {
                ctx: a.ctx,
                config: &config,
                size: a.size,
                arena: arena.as_ref(),
            })?;
            members.push(Member {
                method: m,
                config,
                stage,
                _arena: arena,
            });
        }
        Ok(AutoStage {
            members,
            planes: PlaneSet::new(a.ctx, "auto.planes", w * h, 2 * AUTO_MAPS + 1 + 6)?,
            size: a.size,
            ctx: a.ctx.clone(),
        })
    }

    fn maps(&self) -> [BufferSlice; AUTO_MAPS] {
        std::array::from_fn(|k| self.planes.plane(k))
    }

    fn row_sums(&self) -> [BufferSlice; AUTO_MAPS] {
        std::array::from_fn(|k| self.planes.plane(AUTO_MAPS + k))
    }

    fn den(&self) -> BufferSlice {
        self.planes.plane(2 * AUTO_MAPS)
    }

    fn out(&self, k: usize) -> BufferSlice {
        self.planes.plane(2 * AUTO_MAPS + 1 + k)
    }
}

impl GpuStage for AutoStage {
    fn record(&self, batch: &mut Batch, run: &StageRun) -> Result<()> {
        let p = run.precision;
        let (w, h) = (self.size.0 as u32, self.size.1 as u32);
        for m in &self.members {
            m.stage.record(
                batch,
                &StageRun {
                    precision: p,
                    stats: run.stats,
                    // Its configuration asks for the error estimate, which
                    // the blend reads; nothing reads its sampling planes.
                    config: &m.config,
                    maps: false,
                    origin: run.origin,
                    prefiltered: run.prefiltered,
                    spp_total: run.spp_total,
                },
            )?;
        }
        let spp = run.stats.plane(Layer::Spp, 0);
        let colors = std::array::from_fn(|m| self.members[m].stage.color(run.stats));
        let errors = std::array::from_fn(|m| self.members[m].stage.error(run.stats));
        let (maps, sums) = (self.maps(), self.row_sums());
        auto_score::record(batch, p, (w, h), colors, errors, maps)?;
        let radius = gauss_smooth::radius(SIGMA);
        gauss_rows::record(
            batch,
            p,
            (w, h),
            (0, h),
            SIGMA,
            radius,
            &maps,
            spp,
            &sums,
            self.den(),
        )?;
        for k in 0..AUTO_MAPS {
            let scratch = [sums[k], self.den()];
            gauss_smooth::record_columns(batch, p, (w, h), (0, h), SIGMA, scratch, maps[k])?;
        }
        let (color, error) = (self.color(run.stats), self.error(run.stats));
        auto_blend::record(batch, p, (w, h), colors, errors, maps, color, error)
    }

    fn color(&self, _: &GpuStats) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out(c))
    }

    fn error(&self, _: &GpuStats) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out(3 + c))
    }

    fn dim(&self) -> (BufferSlice, bool) {
        self.members[0].stage.dim()
    }

    fn download(
        &self,
        stats: &GpuStats,
        size: (usize, usize),
        rect: Option<Rect>,
        debug: bool,
        out: &mut ChainOutput,
    ) -> Result<()> {
        let n = size.0 * size.1;
        for (k, m) in self.members.iter().enumerate() {
            let mut o = ChainOutput {
                color: RgbImage::new(0, 0),
                error: RgbImage::new(0, 0),
                dim: Vec::new(),
                debug: Vec::new(),
                stats: Vec::new(),
            };
            m.stage.download(stats, size, rect, debug, &mut o)?;
            let name = m.method.name();
            out.stats
                .extend(o.stats.into_iter().map(|(k, v)| (format!("{name}.{k}"), v)));
            if debug {
                out.debug
                    .extend(o.debug.into_iter().map(|(k, v)| (format!("{name}.{k}"), v)));
                let score = crate::gpu::buffer::read_slice(&self.ctx, self.maps()[k], n)?;
                out.debug.push((format!("auto.score.{name}"), score));
            }
        }
        Ok(())
    }
}

/// The CPU path: every member's twin, then the twins of the GPU stage's
/// kernels.
fn run_cpu(clean: &StatsImage, a: &CpuArgs) -> Result<CpuResult> {
    let (w, h) = (clean.width, clean.height);
    let spp = &clean
        .get(Layer::Spp)
        .expect("the statistics have the spp layer")[0];
    let push = AutoPush {
        width: w as u32,
        height: h as u32,
        ..Default::default()
    };
    let smooth = SmoothPush {
        width: w as u32,
        height: h as u32,
        radius: gauss_smooth::radius(SIGMA),
        sigma: SIGMA,
        ..Default::default()
    };
    let mut result = CpuResult {
        color: RgbImage::new(w, h),
        error: RgbImage::new(w, h),
        dim: Vec::new(),
        debug: Vec::new(),
        stats: Vec::new(),
        map_error: None,
    };
    let mut runs = Vec::with_capacity(AUTO_MEMBERS);
    for m in MEMBERS {
        let r = (m.info().cpu)(clean, a)?;
        let name = m.name();
        result
            .stats
            .extend(r.stats.iter().map(|(k, v)| (format!("{name}.{k}"), *v)));
        if a.debug {
            result.debug.extend(
                r.debug
                    .iter()
                    .map(|(k, v)| (format!("{name}.{k}"), v.clone())),
            );
        }
        runs.push(r);
    }
    let colors = std::array::from_fn(|m| runs[m].color.plane_slices());
    let errors = std::array::from_fn(|m| runs[m].error.plane_slices());
    let mut maps: [Vec<f32>; AUTO_MAPS] = std::array::from_fn(|_| vec![0.0; w * h]);
    reference::auto_score::auto_score(&push, colors, errors, &mut maps);
    let smoothed: [Vec<f32>; AUTO_MAPS] = std::array::from_fn(|k| {
        let mut out = vec![0.0f32; w * h];
        reference::gauss_smooth::smooth(&smooth, &maps[k], spp, &mut out);
        out
    });
    let [cr, cg, cb] = &mut result.color.planes;
    let [er, eg, eb] = &mut result.error.planes;
    reference::auto_blend::auto_blend(
        &push,
        colors,
        errors,
        std::array::from_fn(|k| &smoothed[k][..]),
        [cr, cg, cb],
        [er, eg, eb],
    );
    if a.debug {
        for (m, k) in MEMBERS.iter().zip(0..) {
            result
                .debug
                .push((format!("auto.score.{}", m.name()), smoothed[k].clone()));
        }
    }
    result.dim = runs.swap_remove(0).dim;
    Ok(result)
}
