//! WLR: weighted local regression (spec §2) as a sequence of kernels:
//!
//! ```text
//! channel_mean  color_variance R,G,B → vbar
//! wlr_fit       steps 1–7: TSVD, curvature → b_j, five trial fits, parametric fits, h_opt
//!               (and each centre's local space and b_j, for wlr_final)
//! gauss_smooth  step 8: hbar = G_1(h_opt)
//! wlr_final     steps 9–10: final fit with hbar, MSE
//! ```
//!
//! [`record_wlr`] records them on GPU-resident, sanitised statistics
//! ([`GpuStats`]), 8 rows at a time: `wlr_fit` runs 8 rows ahead of the
//! smoothing's column pass and `wlr_final`, so the centre states live in a
//! ring of 16 rows. [`run_cpu`] runs the scalar twins in the same order,
//! each over the whole image (the twin of `wlr_final` recomputes the local
//! space: the same values).

use std::sync::Arc;

use super::chain::ChainOutput;
use super::registry::{self, CpuResult, GpuStage, MethodInfo, StageRun, REGRESSION_LAYERS};
use super::sampling::{self, DimSource, SamplingParams};
use super::stats::GpuStats;
use super::tiles::Rect;
use super::{Method, Pass};
use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::kernels::{aos_nlm, channel_mean, gauss_smooth, gbf_pack, wlr_final, wlr_fit};
use crate::options::Options;
use crate::reference;
use crate::shared::{
    AosPush, ChannelMeanPush, SmoothPush, WlrPush, WLR_NONNEG, WLR_OUTLIER_CLAMPED, WLR_REJECT,
    WLR_SKIP_DEBUG, WLR_SKIP_MSE,
};

/// Window radius of the final pass (19x19), §2.3.
pub const RADIUS_FINAL: u32 = 9;
/// Window radius of intermediate (adaptive) passes (11x11), §2.3 and §9.3.
pub const RADIUS_INTERMEDIATE: u32 = 5;
/// σ of the h_opt smoothing (§2.3 step 8, H-SMOOTH).
pub const H_SMOOTH_SIGMA: f32 = 1.0;

/// The parameters of one WLR run.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct WlrParams {
    /// Window radius R in pixels: [`RADIUS_FINAL`] or [`RADIUS_INTERMEDIATE`].
    pub radius: u32,
    /// [`WlrPush::options`] bits.
    pub options: u32,
    /// Features regressed on: the spec's 9, or 10 with the prefiltered
    /// visibility (`wlr.extra_features=visibility`, WLR-VIS).
    pub features: usize,
}

impl WlrParams {
    /// From the pass and the `wlr.*` options of the registry.
    pub fn new(pass: Pass, opts: &Options) -> Result<WlrParams> {
        let mut options = 0;
        if opts.get("wlr.reject") == "on" {
            options |= WLR_REJECT;
        }
        if opts.get("wlr.outlier_weight") == "clamped" {
            options |= WLR_OUTLIER_CLAMPED;
        }
        if opts.get("wlr.nonneg") == "on" {
            options |= WLR_NONNEG;
        }
        Ok(WlrParams {
            radius: match pass {
                Pass::Final => RADIUS_FINAL,
                Pass::Intermediate => RADIUS_INTERMEDIATE,
            },
            options,
            features: Self::features(opts),
        })
    }

    /// The feature count `wlr.extra_features` asks for: 9, or 10 with the
    /// visibility.
    pub fn features(opts: &Options) -> usize {
        if opts.get("wlr.extra_features") == "visibility" {
            10
        } else {
            9
        }
    }
}

/// The planes of a WLR run that outlive it (the debug layers, the outputs,
/// the rank the sample map reads), in this order in [`WlrPlanes::set`].
pub const PLANES: [&str; 11] = [
    "h_opt", "kflags", "b1", "b2", "b3", "hbar", "out_r", "out_g", "out_b", "mse", "flags",
];
const H_OPT: usize = 0;
const KFLAGS: usize = 1;
const B1: usize = 2; // b1, b2, b3
const HBAR: usize = 5;
const OUT0: usize = 6; // R, G, B, mse, flags

/// Scratch planes, dead once `wlr_final` has run: vbar, the MSE model `λ1`,
/// `κ0`, `κ1` (`wlr_fit` → `wlr_final`), the row sums of the smoothing;
/// with WLR-VIS the filtered visibility and its variance; after
/// them the features and their variances packed by `gbf_pack` (4 vec4
/// planes: the kernels load a vec4 instead of four scalars).
const SCRATCH: usize = 6;
const VIS: usize = 6; // visibility, its variance (WLR-VIS only)
const PACKED: usize = 4;
const VBAR: usize = 0;
const MODEL: usize = 1; // λ1, κ0, κ1
const SMOOTH: usize = 4; // numerator, weights

/// Rows `wlr_final` lags behind `wlr_fit` in [`record_wlr`]: at least the
/// radius of the `h_opt` smoothing, and a multiple of the kernels' workgroup
/// height.
const LAG_ROWS: u32 = 8;

/// Rows of `wlr_fit` per step of [`record_wlr`]: one workgroup row, the
/// smallest band a dispatch makes (at the final radius a row of 256 pixels
/// already fills a submit). The centre-state ring then holds
/// `CHUNK_ROWS + LAG_ROWS` rows whatever the image, so its size grows with
/// the width only, and the tiler's memory model (a line through two square
/// sizes, `tiles::ChainMemory`) charges it more than it takes above them.
const CHUNK_ROWS: u32 = 8;

/// GPU scratch and output planes of one WLR run.
#[derive(Debug)]
pub struct WlrPlanes {
    /// The [`PLANES`] of a `width × height` image, in that order.
    pub set: PlaneSet,
    /// The [`SCRATCH`] planes (in the chain's arena when it has one).
    scratch: PlaneSet,
    /// The [`PACKED`] vec4 planes, after them.
    packed: PlaneSet,
    /// The ring of centre states `wlr_fit` leaves for `wlr_final`
    /// ([`wlr_fit::state_words`] per pixel, `ring_rows` rows). A buffer of
    /// its own: in the arena, its size (∝ width) would bend the tiler's
    /// linear memory model below the truth.
    state: PlaneSet,
    ring_rows: u32,
}

impl WlrPlanes {
    /// Allocates the [`PLANES`] for a `width × height` image, the centre-state
    /// ring of a run at `precision`, and the `SCRATCH` planes: in `arena`
    /// from its start when given (it must hold [`WlrPlanes::scratch_bytes`];
    /// nothing else may use it while WLR runs), else in a buffer of their own.
    /// Fails with [`Error::Limit`] when the ring, one binding, exceeds
    /// `maxStorageBufferRange` (a width of ~22,000 pixels in f32, half that
    /// in f64; tiling narrows it).
    /// `features`: 9, or 10 for WLR-VIS (its state and two scratch planes
    /// more).
    pub fn new(
        ctx: &Arc<GpuContext>,
        (width, height): (usize, usize),
        precision: Precision,
        arena: Option<&Arc<GpuBuffer>>,
        features: usize,
    ) -> Result<WlrPlanes> {
        let n = width * height;
        let ring_rows = Self::ring_rows(height);
        let ring_bytes = Self::ring_bytes(width, height, precision, features);
        let scratch_planes = Self::scratch_planes(features);
        let limit = ctx.info.max_storage_buffer_range as u64;
        if ring_bytes > limit {
            return Err(Error::Limit(format!(
                "WLR's centre-state ring for a width of {width} pixels ({ring_rows} rows, {ring_bytes} bytes, one binding) exceeds maxStorageBufferRange ({limit} bytes); denoise in tiles (--tile)"
            )));
        }
        let (scratch, packed) = match arena {
            Some(a) => (
                PlaneSet::view(a, 0, n, scratch_planes)?,
                PlaneSet::view(a, PlaneSet::bytes(n, scratch_planes), 4 * n, PACKED)?,
            ),
            None => (
                PlaneSet::new(ctx, "wlr.scratch", n, scratch_planes)?,
                PlaneSet::new(ctx, "wlr.packed", 4 * n, PACKED)?,
            ),
        };
        Ok(WlrPlanes {
            set: PlaneSet::new(ctx, "wlr", n, PLANES.len())?,
            scratch,
            packed,
            state: PlaneSet::new(ctx, "wlr.state", (ring_bytes / 4) as usize, 1)?,
            ring_rows,
        })
    }

    /// Rows of the centre-state ring for an image `height` rows tall.
    fn ring_rows(height: usize) -> u32 {
        (CHUNK_ROWS + LAG_ROWS).min(height.max(1) as u32)
    }

    /// Scratch planes (vbar, the model, the smoothing's sums; the
    /// visibility's two for WLR-VIS).
    fn scratch_planes(features: usize) -> usize {
        if features > 9 {
            SCRATCH + 2
        } else {
            SCRATCH
        }
    }

    /// Bytes of the centre-state ring of a `width × height` image at
    /// `precision` with `features` features: it grows with the width, not
    /// the area.
    pub fn ring_bytes(width: usize, height: usize, precision: Precision, features: usize) -> u64 {
        let ring_rows = Self::ring_rows(height);
        let word = match precision {
            Precision::F32 => 4,
            Precision::F64 => 8,
        };
        ring_rows as u64 * width.max(1) as u64 * (wlr_fit::state_words(features) * word) as u64
    }

    /// Bytes of the scratch an arena must hold for a `width × height` image
    /// with `features` features.
    pub fn scratch_bytes((width, height): (usize, usize), features: usize) -> u64 {
        let n = width * height;
        PlaneSet::bytes(n, Self::scratch_planes(features)) + PlaneSet::bytes(4 * n, PACKED)
    }

    /// The output colour planes R, G, B.
    pub fn color(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.set.plane(OUT0 + c))
    }

    /// The estimated MSE (shared by the channels, §2.3 step 10).
    pub fn mse(&self) -> BufferSlice {
        self.set.plane(OUT0 + 3)
    }

    /// `kflags`: the TSVD rank `k` in `value mod 16`, flags above (§2.5).
    pub fn kflags(&self) -> BufferSlice {
        self.set.plane(KFLAGS)
    }
}

/// The 7 feature planes WLR and LP regress on, and the G-buffer prefilter
/// filters (normal xyz, depth, albedo rgb, §2.1), as (layer, channel).
pub(crate) const FEATURE_PLANES: [(Layer, usize); 7] = [
    (Layer::Normal, 0),
    (Layer::Normal, 1),
    (Layer::Normal, 2),
    (Layer::Depth, 0),
    (Layer::Albedo, 0),
    (Layer::Albedo, 1),
    (Layer::Albedo, 2),
];

/// The planes of [`FEATURE_PLANES`] and their variances, from sanitised
/// statistics, bound as whole vec4s ([`GpuStats::plane_quads`]), as
/// `gbf_pack` reads them.
pub(crate) fn features(s: &GpuStats) -> ([BufferSlice; 7], [BufferSlice; 7]) {
    let order = FEATURE_PLANES;
    (
        std::array::from_fn(|k| s.plane_quads(order[k].0, order[k].1)),
        std::array::from_fn(|k| s.plane_quads(order[k].0.variance().unwrap(), order[k].1)),
    )
}

/// Records WLR on sanitised statistics `clean` (which must hold colour,
/// albedo, normal, depth, their variances and spp). Outputs stay on the GPU
/// in `planes`. With WLR-VIS, `filtered` is the visibility and its variance
/// already filtered by `record_visibility` (`StageRun::visibility`);
/// `None` filters them here.
pub fn record_wlr(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &WlrPlanes,
    params: WlrParams,
    filtered: Option<[BufferSlice; 2]>,
) -> Result<()> {
    let (w, h) = (clean.width as u32, clean.height as u32);
    let p = |i: usize| planes.set.plane(i);
    let q = |i: usize| planes.scratch.plane(i);
    let (feat, var) = features(clean);
    let color: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::Color, c));
    let cvar: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::ColorVariance, c));
    let spp = clean.plane(Layer::Spp, 0);
    channel_mean::record(batch, precision, w, h, cvar, q(VBAR))?;
    let model: [BufferSlice; 3] = std::array::from_fn(|k| q(MODEL + k));
    let fit_out: [BufferSlice; 8] = [
        p(H_OPT),
        model[0],
        model[1],
        model[2],
        p(KFLAGS),
        p(B1),
        p(B1 + 1),
        p(B1 + 2),
    ];
    let fit_in: [BufferSlice; 4] = [model[0], model[1], model[2], p(KFLAGS)];
    let out: [BufferSlice; 5] = std::array::from_fn(|k| p(OUT0 + k));
    let scratch = [q(SMOOTH), q(SMOOTH + 1)];
    let packed: [BufferSlice; 4] = std::array::from_fn(|k| planes.packed.plane(k));
    let spp_quads = clean.plane_quads(Layer::Spp, 0);
    gbf_pack::record(batch, precision, w, h, (0, h), feat, var, spp_quads, packed)?;
    let vis = match (params.features > 9, filtered) {
        (false, _) => None,
        (true, Some(v)) => Some(v),
        (true, None) => {
            record_visibility(batch, precision, clean, &planes.scratch, VIS)?;
            Some([q(VIS), q(VIS + 1)])
        }
    };
    let ring = (planes.state.plane(0), planes.ring_rows);
    let wr = (params.radius, params.options);
    let size = (w, h);
    // wlr_fit runs a band of rows ahead; wlr_final follows LAG_ROWS behind,
    // once the smoothing of h_opt has every row it needs (its radius, 3, is
    // at most LAG_ROWS: the rows [ready, ready + radius) are fitted), and
    // reads the centre states of its rows from the ring before wlr_fit
    // overwrites them (the ring holds CHUNK_ROWS + LAG_ROWS rows).
    debug_assert!(gauss_smooth::radius(H_SMOOTH_SIGMA) <= LAG_ROWS);
    let (mut fitted, mut done) = (0u32, 0u32);
    while done < h {
        let end = (fitted + CHUNK_ROWS).min(h);
        wlr_fit::record(
            batch,
            precision,
            size,
            (fitted, end),
            wr,
            packed,
            color,
            q(VBAR),
            spp,
            fit_out,
            ring,
            vis,
        )?;
        gauss_smooth::record_row_sums(
            batch,
            precision,
            size,
            (fitted, end),
            H_SMOOTH_SIGMA,
            p(H_OPT),
            spp,
            scratch,
        )?;
        fitted = end;
        let ready = if end == h { h } else { end - LAG_ROWS };
        if ready > done {
            gauss_smooth::record_columns(
                batch,
                precision,
                size,
                (done, ready),
                H_SMOOTH_SIGMA,
                scratch,
                p(HBAR),
            )?;
            wlr_final::record(
                batch,
                precision,
                size,
                (done, ready),
                wr,
                [packed[0], packed[1]],
                color,
                q(VBAR),
                spp,
                p(HBAR),
                fit_in,
                ring,
                out,
                vis.map(|v| v[0]),
            )?;
            done = ready;
        }
    }
    Ok(())
}

/// How far [`record_visibility`]'s output reads its input: the 3×3 mean
/// (1), then the NL-means search and patch radii. WLR-VIS and APR-VIS add
/// it to their halos.
pub(super) const VIS_FILTER_REACH: usize =
    1 + reference::aos::NLM_SEARCH + reference::aos::NLM_PATCH;

/// WLR-VIS (and APR-VIS): the visibility and its variance, their 3×3
/// means NL-means filtered as AOS filters them (§5.2, unclamped;
/// `aos_nlm_vis`), into planes `first` and `first + 1` of `scratch`
/// (WLR's [`VIS`]). [`filter_visibility`] is its CPU path.
pub(super) fn record_visibility(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    scratch: &PlaneSet,
    first: usize,
) -> Result<()> {
    let layer = Layer::Visibility;
    if !clean.has(layer) {
        return Err(no_visibility());
    }
    let vlayer = layer.variance().expect("visibility has a variance layer");
    let (w, h) = (clean.width, clean.height);
    let push = AosPush {
        width: w as u32,
        height: h as u32,
        channels: 1,
        stride: (scratch.stride / 4) as u32,
        ..Default::default()
    };
    let dst = scratch.range(
        first as u64 * scratch.stride,
        scratch.stride + (w * h * 4) as u64,
    );
    let planes = [
        clean.plane(layer, 0),
        clean.plane(vlayer, 0),
        clean.plane(Layer::Spp, 0),
    ];
    aos_nlm::record_boxed(batch, precision, &push, planes, dst)
}

/// WLR-VIS (and APR-VIS) on the CPU: the visibility `g` (variances `gv`)
/// as `record_visibility` filters it, the `aos_nlm_vis` kernel's twin
/// ([`reference::aos_nlm::aos_nlm_boxed`]): value and variance.
pub fn filter_visibility(w: usize, h: usize, g: &[f32], gv: &[f32], spp: &[f32]) -> [Vec<f32>; 2] {
    let push = AosPush {
        width: w as u32,
        height: h as u32,
        channels: 1,
        ..Default::default()
    };
    let mut out = reference::aos_nlm::aos_nlm_boxed(&push, &[g], &[gv], spp).into_iter();
    let g = out.next().expect("aos_nlm_boxed gives the value");
    let gv = out.next().expect("aos_nlm_boxed gives the variance");
    [g, gv]
}

/// WLR-VIS on statistics without the visibility layer (GPU and CPU paths).
fn no_visibility() -> Error {
    Error::BadData("wlr.extra_features=visibility needs the visibility layer".into())
}

/// What a WLR run gives back on the host.
#[derive(Clone, Debug)]
pub struct WlrResult {
    /// The reconstruction (§2.3 step 9), clamped to ≥ 0.
    pub color: RgbImage,
    /// Estimated MSE per pixel (shared by R, G, B).
    pub mse: Vec<f32>,
    /// The planes that outlive a run, by name ([`PLANES`]: the outputs, the
    /// rank and the debug maps; not the scratch of `wlr_fit` → `wlr_final`).
    pub planes: Vec<(String, Vec<f32>)>,
}

impl WlrResult {
    fn from_planes(width: usize, height: usize, all: Vec<Vec<f32>>) -> WlrResult {
        let color = RgbImage::from_planes(
            width,
            height,
            [
                all[OUT0].clone(),
                all[OUT0 + 1].clone(),
                all[OUT0 + 2].clone(),
            ],
        );
        let mse = all[OUT0 + 3].clone();
        WlrResult {
            color,
            mse,
            planes: PLANES.iter().map(|s| s.to_string()).zip(all).collect(),
        }
    }

    /// The TSVD rank `k` per pixel: the local dimension `d_i` of §9.1.
    pub fn rank(&self) -> Vec<f32> {
        let kflags = &self.planes.iter().find(|(k, _)| k == "kflags").unwrap().1;
        kflags.iter().map(|v| (*v as u32 % 16) as f32).collect()
    }

    /// The debug layers of issue #3: rank, b1..b3, h_opt, hbar, flags (§2.5).
    pub fn debug_layers(&self) -> Vec<(String, Vec<f32>)> {
        let get = |n: &str| self.planes.iter().find(|(k, _)| k == n).unwrap().1.clone();
        vec![
            ("rank".into(), self.rank()),
            ("b1".into(), get("b1")),
            ("b2".into(), get("b2")),
            ("b3".into(), get("b3")),
            ("h_opt".into(), get("h_opt")),
            ("hbar".into(), get("hbar")),
            ("flags".into(), get("flags")),
        ]
    }
}

/// Downloads the planes of a finished [`record_wlr`].
pub fn download(planes: &WlrPlanes, width: usize, height: usize) -> Result<WlrResult> {
    Ok(WlrResult::from_planes(
        width,
        height,
        planes.set.download_all()?,
    ))
}

/// The CPU path: the scalar twins in the order of [`record_wlr`], on
/// sanitised statistics.
pub fn run_cpu(clean: &StatsImage, params: WlrParams) -> Result<WlrResult> {
    run_cpu_with_progress(clean, params, false)
}

/// [`run_cpu`], printing each stage's time on stderr when `progress` is set
/// and the run has taken more than a second.
pub fn run_cpu_with_progress(
    clean: &StatsImage,
    params: WlrParams,
    progress: bool,
) -> Result<WlrResult> {
    let started = std::time::Instant::now();
    let report = |stage: &str| {
        let t = started.elapsed().as_secs_f64();
        if progress && t > 1.0 {
            log::info!("{stage} (cpu) done ({t:.1} s)");
        }
    };
    let (w, h) = (clean.width, clean.height);
    let n = w * h;
    let need = |l: Layer| {
        clean
            .get(l)
            .ok_or_else(|| Error::BadData(format!("WLR needs the {} layer", l.name())))
    };
    let (col, cvar) = (need(Layer::Color)?, need(Layer::ColorVariance)?);
    let (nrm, nvar) = (need(Layer::Normal)?, need(Layer::NormalVariance)?);
    let (dep, dvar) = (need(Layer::Depth)?, need(Layer::DepthVariance)?);
    let (alb, avar) = (need(Layer::Albedo)?, need(Layer::AlbedoVariance)?);
    let spp = &need(Layer::Spp)?[0];
    let feat: [&[f32]; 7] = [
        &nrm[0], &nrm[1], &nrm[2], &dep[0], &alb[0], &alb[1], &alb[2],
    ];
    let var: [&[f32]; 7] = [
        &nvar[0], &nvar[1], &nvar[2], &dvar[0], &avar[0], &avar[1], &avar[2],
    ];
    let color: [&[f32]; 3] = [&col[0], &col[1], &col[2]];
    // WLR-VIS: the visibility filtered as `record_visibility` filters it.
    let vis_planes = if params.features > 9 {
        let need_vis = |l: Layer| clean.get(l).ok_or_else(no_visibility);
        let (v, vv) = (
            need_vis(Layer::Visibility)?,
            need_vis(Layer::VisibilityVariance)?,
        );
        Some(filter_visibility(w, h, &v[0], &vv[0], spp))
    } else {
        None
    };
    let vis: Option<[&[f32]; 2]> = vis_planes.as_ref().map(|p| [&p[0][..], &p[1][..]]);

    let push_cm = ChannelMeanPush {
        width: w as u32,
        height: h as u32,
        ..Default::default()
    };
    let mut vbar = vec![0.0f32; n];
    reference::channel_mean::channel_mean(&push_cm, &cvar[0], &cvar[1], &cvar[2], &mut vbar);

    let push = WlrPush {
        width: w as u32,
        height: h as u32,
        radius: params.radius,
        options: params.options,
        ..Default::default()
    };
    let mut fit = vec![vec![0.0f32; n]; 8];
    reference::wlr_fit::wlr_fit(&push, feat, var, vis, color, &vbar, spp, &mut fit);
    report("wlr_fit");

    let push_s = SmoothPush {
        width: w as u32,
        height: h as u32,
        radius: gauss_smooth::radius(H_SMOOTH_SIGMA),
        sigma: H_SMOOTH_SIGMA,
        ..Default::default()
    };
    let mut hbar = vec![0.0f32; n];
    reference::gauss_smooth::smooth(&push_s, &fit[0], spp, &mut hbar);

    let mut out = vec![vec![0.0f32; n]; 5];
    let fit_in: [&[f32]; 4] = [&fit[1], &fit[2], &fit[3], &fit[4]];
    reference::wlr_final::wlr_final(
        &push, feat, var, vis, color, &vbar, spp, &hbar, fit_in, &mut out,
    );
    report("wlr_final");

    let [h_opt, _, _, _, kflags, b1, b2, b3] = <[Vec<f32>; 8]>::try_from(fit).unwrap();
    let [r, g, b, mse, flags] = <[Vec<f32>; 5]>::try_from(out).unwrap();
    let all = vec![h_opt, kflags, b1, b2, b3, hbar, r, g, b, mse, flags];
    Ok(WlrResult::from_planes(w, h, all))
}

/// WLR's entry in the method registry.
pub static INFO: MethodInfo = MethodInfo {
    method: Method::Wlr,
    name: "wlr",
    about: "weighted local regression (spec §2)",
    needs: &REGRESSION_LAYERS,
    prefilter_auto: true,
    outliers_auto: true,
    pyramid_auto: false,
    blend: super::blend::BlendDefaults {
        auto: true,
        k: 0.25,
        ..super::blend::BlendDefaults::BASE
    },
    map_method: Method::Wlr,
    passes: 5,
    pass_cap: None,
    map_check: false,
    sampling: SamplingParams {
        eps: sampling::EPS_DEFAULT,
        sigma_s: sampling::SIGMA_WLR,
        e_is_dmse: false,
        dim: DimSource::Kflags,
        floor: 0.3,
    },
    error_scale: 6.9,
    // PYRAMID-ERROR-SCALE: error_scale × 2.22.
    pyramid_error_scale: 15.3,
    // TEMPORAL-TEST-SCALE: the reference the others are measured against.
    inflate_scale: 1.0,
    align: 1,
    halo: |c| {
        let p = WlrParams::new(c.pass, &c.options)?;
        // WLR-VIS: the visibility's filter reads it within its reach.
        let nlm = if p.features > 9 { VIS_FILTER_REACH } else { 0 };
        Ok(p.radius as usize + gauss_smooth::radius(H_SMOOTH_SIGMA) as usize + nlm)
    },
    arena_bytes: |c, size| WlrPlanes::scratch_bytes(size, WlrParams::features(&c.options)),
    arena_kept: registry::nothing_kept,
    options_for: registry::same_options,
    ring_bytes: |c, (w, h)| {
        WlrPlanes::ring_bytes(w, h, c.precision, WlrParams::features(&c.options))
    },
    gpu: |a| {
        Ok(Box::new(WlrStage {
            planes: WlrPlanes::new(
                a.ctx,
                a.size,
                a.config.precision,
                a.arena,
                WlrParams::features(&a.config.options),
            )?,
            params: WlrParams::new(a.config.pass, &a.config.options)?,
        }))
    },
    cpu: |clean, a| {
        let params = WlrParams::new(a.pass, &a.options)?;
        let r = run_cpu_with_progress(clean, params, a.progress)?;
        let mse = r.mse.clone();
        Ok(CpuResult {
            error: RgbImage::from_planes(
                clean.width,
                clean.height,
                [mse.clone(), mse.clone(), mse],
            ),
            dim: r.rank(),
            debug: if a.debug {
                r.debug_layers()
            } else {
                Vec::new()
            },
            color: r.color,
            stats: Vec::new(),
            map_error: None,
        })
    },
};

/// WLR's GPU stage.
struct WlrStage {
    planes: WlrPlanes,
    params: WlrParams,
}

impl GpuStage for WlrStage {
    fn record(&self, batch: &mut Batch, run: &StageRun) -> Result<()> {
        let c = run.config;
        let skip = [
            (c.debug, WLR_SKIP_DEBUG),
            (run.maps || c.error || c.debug, WLR_SKIP_MSE),
        ];
        let params = WlrParams {
            options: super::chain::skip_bits(self.params.options, &skip),
            ..self.params
        };
        record_wlr(
            batch,
            run.precision,
            run.stats,
            &self.planes,
            params,
            run.visibility,
        )
    }

    fn color(&self, _: &GpuStats) -> [BufferSlice; 3] {
        self.planes.color()
    }

    fn error(&self, _: &GpuStats) -> [BufferSlice; 3] {
        [self.planes.mse(); 3]
    }

    fn dim(&self) -> (BufferSlice, bool) {
        (self.planes.kflags(), true)
    }

    fn download(
        &self,
        _: &GpuStats,
        (w, h): (usize, usize),
        _: Option<Rect>,
        debug: bool,
        out: &mut ChainOutput,
    ) -> Result<()> {
        if debug {
            out.debug = download(&self.planes, w, h)?.debug_layers();
        }
        Ok(())
    }
}
