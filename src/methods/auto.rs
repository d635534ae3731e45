//! `auto`: several methods on the same statistics, blended per pixel by
//! their own error estimates (AUTO-BLEND, ours; issue #41). The methods fail
//! in different places, and each one's `E_i` says where.
//!
//! The members ([`members`]: WLR, LP, APR and, with `auto.aos=on`, AOS) run
//! on the sanitised, prefiltered statistics; in a final reconstruction of
//! statistics with the visibility layer the WLR member reads it as a tenth
//! feature (WLR-VIS, [`member_options`], AUTO-VIS). A member that does not
//! prefilter by default (AOS) reads them from before the prefilter
//! ([`GpuStage::record_unfiltered`], AUTO-AOS), even with `--prefilter on`.
//! `auto_score` writes each member's relative error estimate `s_m = Σ_c
//! E_m,c / (f_m,c² + 0.01)` and `auto_dis` each pair's disagreement `dis_ab
//! = Σ_c (f_a,c − f_b,c)² / (f̄_c² + 0.01)`; `gauss_rows` and
//! `gauss_smooth` smooth these maps (the Gaussian of §0.5, σ = [`SIGMA`],
//! over valid pixels). `auto_blend` weighs member `m` by `1 / max(s_m,
//! t_m)`, `t_m` its error as the n-cornered hat of the disagreements gives
//! it (for three members `t_0 = (dis01 + dis02 − dis12) / 2`, …), and
//! exports the blend with the error estimate `E_c = (Σ w_m √(k_m E_m,c) /
//! Σ w_m)²`, `k_m` the factor by which the hat raised the member's score.
//! The local dimension `d_i` and the sampling parameters of §9 are the
//! first member's (WLR's); the G-buffer prefilter and the outlier stage run
//! once, around the whole blend.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use super::chain::{ChainConfig, ChainOutput};
use super::registry::{
    self, CpuArgs, CpuResult, GpuStage, MethodInfo, StageArgs, StageRun, REGRESSION_LAYERS,
};
use super::stats::GpuStats;
use super::tiles::Rect;
use super::{Method, Pass, Tally};
use crate::error::Result;
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::kernels::{auto_blend, auto_dis, auto_score, gauss_rows, gauss_smooth};
use crate::options::Options;
use crate::reference;
use crate::shared::{auto_pairs, AutoPush, SmoothPush, AUTO_SUMS};

/// The methods `auto` runs with `options` in a `pass`, in the order they
/// are blended: WLR, LP, APR, and AOS with `auto.aos=on` in a final
/// reconstruction (an adaptive render's intermediate passes with
/// `--map-method auto`, whose reconstructions only make sample maps, do
/// without its cost). The first
/// one gives `d_i` and the sampling parameters (AUTO-BLEND, AUTO-AOS).
pub fn members(options: &Options, pass: Pass) -> Vec<Method> {
    let mut m = vec![Method::Wlr, Method::Lp, Method::Apr];
    if options.get("auto.aos") == "on" && pass == Pass::Final {
        m.push(Method::Aos);
    }
    m
}

/// σ (pixels) of the Gaussian that smooths each member's score before it
/// becomes a weight (AUTO-BLEND).
pub const SIGMA: f32 = 1.5;

/// Whether a member with `options` in `pass` reads the features from
/// before the G-buffer prefilter (a method that does not prefilter by
/// default: AOS, AUTO-AOS), so that the CPU path must keep them.
pub fn reads_unfiltered(options: &Options, pass: Pass) -> bool {
    members(options, pass).into_iter().any(unfiltered)
}

/// Whether member `m` reads the features from before the G-buffer
/// prefilter: a method that does not prefilter by default (AOS).
fn unfiltered(m: Method) -> bool {
    !m.info().prefilter_auto
}

/// The maps of `members` members: their scores and their pairs'
/// disagreements.
fn map_count(members: usize) -> usize {
    members + auto_pairs(members).len()
}

/// The planes after the maps: the smoothing's row sums and weights, then
/// the blend's sums in the same planes, as many as the larger needs.
fn scratch_count(members: usize) -> usize {
    (map_count(members) + 1).max(AUTO_SUMS)
}

/// A member's options in `pass` (AUTO-VIS): `auto`'s, and the WLR member of
/// a final reconstruction reads the visibility as a tenth feature
/// (WLR-VIS) unless `wlr.extra_features` was given ([`for_layers`] gives
/// `none` to statistics without the layer).
pub fn member_options(options: &Options, m: Method, pass: Pass) -> Options {
    let mut o = options.clone();
    if m == Method::Wlr && pass == Pass::Final && !o.is_set(WLR_FEATURES) {
        o.set(WLR_FEATURES, "visibility")
            .expect("a value of the registry");
    }
    o
}

/// `auto`'s options for statistics with `layers`: without the visibility
/// layer its WLR member regresses on the spec's nine features (AUTO-VIS),
/// unless `wlr.extra_features` was given (then WLR reports the missing
/// layer).
pub fn for_layers(options: &Options, layers: &[Layer]) -> Options {
    let mut o = options.clone();
    if !layers.contains(&Layer::Visibility) && !o.is_set(WLR_FEATURES) {
        o.set(WLR_FEATURES, "none")
            .expect("a value of the registry");
    }
    o
}

/// The option AUTO-VIS sets for the WLR member.
const WLR_FEATURES: &str = "wlr.extra_features";

/// A member's configuration: `auto`'s, with the member's method, its
/// options ([`member_options`]) and its error estimate on (the blend reads
/// it).
fn member_config(c: &ChainConfig, m: Method) -> ChainConfig {
    ChainConfig {
        method: m,
        options: member_options(&c.options, m, c.pass),
        error: true,
        temporal: super::Temporal::Off,
        temporal_state: None,
        coarse_map: false,
        ..c.clone()
    }
}

/// `auto`'s entry in the method registry.
pub static INFO: MethodInfo = MethodInfo {
    method: Method::Auto,
    name: "auto",
    about: "WLR (reading the visibility where the input has it), LP and APR (and AOS with --opt auto.aos=on) blended per pixel by their own error estimates (ours; LP's and APR's patents apply)",
    needs: &REGRESSION_LAYERS,
    prefilter_auto: true,
    outliers_auto: true,
    pyramid_auto: true,
    blend: super::blend::BlendDefaults::BASE,
    // AUTO-MAPS: WLR's maps place samples as well at a third less GPU time.
    map_method: Method::Wlr,
    passes: super::wlr::INFO.passes,
    pass_cap: None,
    map_check: false,
    sampling: super::wlr::INFO.sampling,
    // ERROR-SCALE on the blend's estimate: uniform inputs of the eleven
    // tuning scenes at 4, 16 and 64 spp (AUTO-BLEND).
    error_scale: 2.5,
    // PYRAMID-ERROR-SCALE: error_scale × 2.07.
    pyramid_error_scale: 5.2,
    // TEMPORAL-TEST-SCALE: WLR's factor (the record has the measured ratio).
    inflate_scale: 1.0,
    // The least common multiple of the members' (APR's block grid).
    align: super::apr::INFO.align,
    halo: |c| {
        let mut h = 0;
        for m in members(&c.options, c.pass) {
            h = h.max((m.info().halo)(&member_config(c, m))?);
        }
        Ok(h + crate::shared::gaussian_radius(SIGMA as f64))
    },
    arena_bytes: registry::no_bytes,
    arena_kept: registry::nothing_kept,
    options_for: for_layers,
    ring_bytes: |c, size| {
        members(&c.options, c.pass)
            .into_iter()
            .map(|m| (m.info().ring_bytes)(&member_config(c, m), size))
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
    /// The maps (smoothed in place: the members' scores, then the pairs'
    /// disagreements); their row sums and the weights' row sums, whose
    /// planes (and more, up to [`AUTO_SUMS`]) then carry the blend's sums;
    /// then its colour and error (3 + 3).
    planes: PlaneSet,
    /// The visibility and its variance filtered once for every member
    /// that filters them (WLR-VIS and APR-VIS: `StageRun::visibility`),
    /// when more than one does.
    visibility: Option<PlaneSet>,
    /// Set by `record_unfiltered`, taken by `record` when the members that
    /// read unprefiltered features were recorded there.
    unfiltered_recorded: AtomicBool,
    size: (usize, usize),
    ctx: Arc<GpuContext>,
}

impl AutoStage {
    fn new(a: &StageArgs) -> Result<AutoStage> {
        let (w, h) = a.size;
        let methods = members(&a.config.options, a.config.pass);
        auto_dis::check_members(methods.len(), None)?;
        let mut members = Vec::with_capacity(methods.len());
        for m in methods {
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
        let planes = map_count(members.len()) + scratch_count(members.len()) + 6;
        let mut filtering = 0;
        for m in &members {
            filtering += filters_visibility(m.method, &m.config.options)? as usize;
        }
        let visibility = if filtering > 1 {
            Some(PlaneSet::new(a.ctx, "auto.visibility", w * h, 2)?)
        } else {
            None
        };
        Ok(AutoStage {
            members,
            planes: PlaneSet::new(a.ctx, "auto.planes", w * h, planes)?,
            visibility,
            unfiltered_recorded: AtomicBool::new(false),
            size: a.size,
            ctx: a.ctx.clone(),
        })
    }

    fn map_count(&self) -> usize {
        map_count(self.members.len())
    }

    /// The maps: the members' scores, then the pairs' disagreements.
    fn maps(&self) -> Vec<BufferSlice> {
        (0..self.map_count())
            .map(|k| self.planes.plane(k))
            .collect()
    }

    fn row_sums(&self) -> Vec<BufferSlice> {
        let n = self.map_count();
        (0..n).map(|k| self.planes.plane(n + k)).collect()
    }

    fn den(&self) -> BufferSlice {
        self.planes.plane(2 * self.map_count())
    }

    /// The blend's sums: the smoothing's scratch planes, free by then.
    fn sums(&self) -> [BufferSlice; AUTO_SUMS] {
        std::array::from_fn(|k| self.planes.plane(self.map_count() + k))
    }

    fn out(&self, k: usize) -> BufferSlice {
        let n = self.members.len();
        self.planes.plane(map_count(n) + scratch_count(n) + k)
    }

    /// Records `m` on `run`'s statistics; `visibility`: the filtered
    /// visibility it reads if it filters it.
    fn record_member(
        &self,
        batch: &mut Batch,
        run: &StageRun,
        m: &Member,
        visibility: Option<[BufferSlice; 2]>,
    ) -> Result<()> {
        m.stage.record(
            batch,
            &StageRun {
                precision: run.precision,
                stats: run.stats,
                // Its configuration asks for the error estimate, which
                // the blend reads; nothing reads its sampling planes.
                config: &m.config,
                maps: false,
                origin: run.origin,
                prefiltered: run.prefiltered,
                spp_total: run.spp_total,
                visibility,
            },
        )
    }

    /// Records the visibility's filter once for the members that filter
    /// it, when the statistics have the layer; the planes they read.
    fn record_visibility(
        &self,
        batch: &mut Batch,
        run: &StageRun,
    ) -> Result<Option<[BufferSlice; 2]>> {
        match &self.visibility {
            Some(set) if run.stats.has(Layer::Visibility) => {
                super::wlr::record_visibility(batch, run.precision, run.stats, set, 0)?;
                Ok(Some([set.plane(0), set.plane(1)]))
            }
            _ => Ok(None),
        }
    }
}

/// Whether member `m` with `options` filters the visibility (WLR-VIS,
/// APR-VIS), which the members can then share.
fn filters_visibility(m: Method, options: &Options) -> Result<bool> {
    Ok(match m {
        Method::Wlr => super::wlr::WlrParams::features(options) > 9,
        Method::Apr => super::apr::AprParams::new(options)?.filter_visibility,
        _ => false,
    })
}

impl GpuStage for AutoStage {
    fn record_unfiltered(&self, batch: &mut Batch, run: &StageRun) -> Result<()> {
        for m in self.members.iter().filter(|m| unfiltered(m.method)) {
            self.record_member(batch, run, m, None)?;
        }
        self.unfiltered_recorded.store(true, Ordering::SeqCst);
        Ok(())
    }

    fn record(&self, batch: &mut Batch, run: &StageRun) -> Result<()> {
        let p = run.precision;
        let (w, h) = (self.size.0 as u32, self.size.1 as u32);
        // The members that read unprefiltered features ran before the
        // prefilter (record_unfiltered) when it runs.
        let before = self.unfiltered_recorded.swap(false, Ordering::SeqCst);
        if run.prefiltered && !before && self.members.iter().any(|m| unfiltered(m.method)) {
            return Err(crate::error::Error::InvalidArgument(
                "auto: the prefilter ran, but the members that read unprefiltered features were not recorded before it (GpuStage::record_unfiltered)".into(),
            ));
        }
        let visibility = self.record_visibility(batch, run)?;
        for m in &self.members {
            if !(unfiltered(m.method) && run.prefiltered) {
                self.record_member(batch, run, m, visibility)?;
            }
        }
        let spp = run.stats.plane(Layer::Spp, 0);
        let n = self.members.len();
        let colors: Vec<[BufferSlice; 3]> = self
            .members
            .iter()
            .map(|m| m.stage.color(run.stats))
            .collect();
        let errors: Vec<[BufferSlice; 3]> = self
            .members
            .iter()
            .map(|m| m.stage.error(run.stats))
            .collect();
        let (maps, sums) = (self.maps(), self.row_sums());
        for m in 0..n {
            auto_score::record(batch, p, (w, h), colors[m], errors[m], maps[m])?;
        }
        auto_dis::record(batch, p, (w, h), &colors, &maps[n..])?;
        // gauss_rows takes six maps at once, or one.
        let radius = gauss_smooth::radius(SIGMA);
        let mut k = 0;
        while k < maps.len() {
            let take = if maps.len() - k >= 6 { 6 } else { 1 };
            let (m, s) = (&maps[k..k + take], &sums[k..k + take]);
            gauss_rows::record(
                batch,
                p,
                (w, h),
                (0, h),
                SIGMA,
                radius,
                m,
                spp,
                s,
                self.den(),
            )?;
            for j in k..k + take {
                let scratch = [sums[j], self.den()];
                gauss_smooth::record_columns(batch, p, (w, h), (0, h), SIGMA, scratch, maps[j])?;
            }
            k += take;
        }
        let members: Vec<auto_blend::Member> = (0..n)
            .map(|m| auto_blend::Member {
                color: colors[m],
                error: errors[m],
                score: maps[m],
            })
            .collect();
        let (color, error) = (self.color(run.stats), self.error(run.stats));
        auto_blend::record(
            batch,
            p,
            (w, h),
            &members,
            &maps[n..],
            self.sums(),
            color,
            error,
        )
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
            out.stats.extend(Tally::prefixed(name, o.stats));
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
    let methods = members(&a.options, a.pass);
    auto_dis::check_members(methods.len(), None)?;
    let mut runs = Vec::with_capacity(methods.len());
    for &m in &methods {
        let a = &CpuArgs {
            options: member_options(&a.options, m, a.pass),
            ..a.clone()
        };
        // A member that does not prefilter by default reads the statistics
        // from before the prefilter (AUTO-AOS), as on the GPU.
        let mut r = match &a.unfiltered {
            Some(u) if unfiltered(m) => {
                let args = CpuArgs {
                    prefiltered: false,
                    unfiltered: None,
                    ..a.clone()
                };
                (m.info().cpu)(u, &args)?
            }
            _ => (m.info().cpu)(clean, a)?,
        };
        let name = m.name();
        result
            .stats
            .extend(Tally::prefixed(name, std::mem::take(&mut r.stats)));
        if a.debug {
            result.debug.extend(
                r.debug
                    .iter()
                    .map(|(k, v)| (format!("{name}.{k}"), v.clone())),
            );
        }
        runs.push(r);
    }
    let n = methods.len();
    let push = AutoPush {
        members: n as u32,
        ..push
    };
    let colors: Vec<_> = runs.iter().map(|r| r.color.plane_slices()).collect();
    let errors: Vec<_> = runs.iter().map(|r| r.error.plane_slices()).collect();
    let mut maps: Vec<Vec<f32>> = vec![vec![0.0; w * h]; map_count(n)];
    for m in 0..n {
        reference::auto_score::auto_score(&push, colors[m], errors[m], &mut maps[m]);
    }
    reference::auto_dis::auto_dis(&push, &colors, &mut maps[n..]);
    let smoothed: Vec<Vec<f32>> = maps
        .iter()
        .map(|map| {
            let mut out = vec![0.0f32; w * h];
            reference::gauss_smooth::smooth(&smooth, map, spp, &mut out);
            out
        })
        .collect();
    let members: Vec<reference::auto_blend::Member> = (0..n)
        .map(|m| reference::auto_blend::Member {
            color: colors[m],
            error: errors[m],
            score: &smoothed[m],
        })
        .collect();
    let dis: Vec<&[f32]> = smoothed[n..].iter().map(|v| &v[..]).collect();
    let [cr, cg, cb] = &mut result.color.planes;
    let [er, eg, eb] = &mut result.error.planes;
    reference::auto_blend::auto_blend(&push, &members, &dis, [cr, cg, cb], [er, eg, eb]);
    if a.debug {
        for (m, k) in methods.iter().zip(0..) {
            result
                .debug
                .push((format!("auto.score.{}", m.name()), smoothed[k].clone()));
        }
    }
    result.dim = runs.swap_remove(0).dim;
    Ok(result)
}
