//! APR, adaptive polynomial rendering (spec §4), on sanitised (and
//! outlier-cleaned, §4.4) statistics. The CPU path runs
//! [`crate::reference::apr`]; its features come from the G-buffer prefilter
//! when that ran (PREFILTER-STACK), else they are the input's, or with
//! `apr.prefilter=on` APR's own 5×5 polynomial prefilter (§4.6; off by
//! default, see [`AprParams::prefilter`]). The visibility, when present,
//! is read as WLR-VIS filters it (APR-VIS, [`AprParams::filter_visibility`]).

use std::sync::Arc;

use super::chain::ChainOutput;
use super::registry::{self, CpuResult, GpuStage, MethodInfo, StageRun, REGRESSION_LAYERS};
use super::sampling::{self, DimSource, SamplingParams};
use super::stats::GpuStats;
use super::tiles::Rect;
use super::Method;
use crate::error::{Error, Result};
use crate::gpu::{plane_stride, Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::kernels::apr_block::{self, AprChannel};
use crate::kernels::apr_gather::{self, EXTRA_PLANES, OUTPUTS, STAGE_OUTPUTS};
use crate::kernels::{apr_pack, spp_total};
use crate::options::Options;
use crate::reference::apr::{self as r, Planes};
use crate::reference::apr_block::{grid, RADIUS, STATE};
use crate::reference::spp_of;
use crate::shared::{AprPush, APR_CLAMPED, APR_COUNT_CAP, APR_PIXEL_TEST, APR_VIS};

/// APR's options.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct AprParams {
    /// Stages T (`apr.stages`, ≥ 1; 2 in the paper).
    pub stages: usize,
    /// `apr.prefilter`: run §4.6's 5×5 feature prefilter when the G-buffer
    /// prefilter does not. Off by default (APR-PF-OFF): at a small light's
    /// rim it blurs albedo across the edge and the blocks then paint the
    /// wall with the light.
    pub prefilter: bool,
    /// `apr.outlier_weight=clamped` (default): the block kernel is
    /// `K_h·o_i`, `o_i = 1/max(v_i, 1)` (decision APR-OUTLIER-W, see
    /// [`r::outlier_weight`]).
    pub clamped: bool,
    /// `apr.pixel_test=on` (default): APR-PIXEL-TEST (see
    /// `reference::apr_gather::apr_gather`).
    pub pixel_test: bool,
    /// `apr.count_cap=on` (default): APR-COUNT-CAP, the interval test takes
    /// a pixel with more than twice the image's mean count at the variance
    /// it would have with twice the mean (see [`r::test_scale`]).
    pub count_cap: bool,
    /// `apr.visibility=filtered` (default): APR-VIS, the visibility feature
    /// is its 3×3 means, NL-means filtered, as WLR-VIS reads it
    /// ([`super::wlr::filter_visibility`]); `raw`: the input's, as §4.1
    /// reads it. The raw mean of a pixel's shadow rays carries the noise of
    /// the colour's direct light, which a block's fit on it passes to the
    /// output.
    pub filter_visibility: bool,
}

impl AprParams {
    /// From `--opt apr.stages=T`.
    pub fn new(opts: &Options) -> Result<AprParams> {
        let stages = if opts.is_set("apr.stages") {
            opts.get("apr.stages")
                .parse::<usize>()
                .ok()
                .filter(|&t| (1..=4).contains(&t))
                .ok_or_else(|| Error::InvalidArgument("apr.stages: an integer 1..=4".into()))?
        } else {
            r::STAGES
        };
        Ok(AprParams {
            stages,
            prefilter: opts.get("apr.prefilter") == "on",
            clamped: opts.get("apr.outlier_weight") == "clamped",
            pixel_test: opts.get("apr.pixel_test") == "on",
            count_cap: opts.get("apr.count_cap") == "on",
            filter_visibility: opts.get("apr.visibility") == "filtered",
        })
    }
}

/// What APR returns on the CPU.
#[derive(Clone, Debug)]
pub struct AprResult {
    /// The reconstruction, clamped to ≥ 0.
    pub color: RgbImage,
    /// Blended `ξ̂_i` per channel (§4.3).
    pub error: RgbImage,
    /// Blended `tr H(K̂²)`, mean over the channels (`d_i` of §9.1).
    pub dim: Vec<f32>,
    /// Debug planes: `apr_order.R/G/B` (K̂²+1 at the sparse centres),
    /// `apr_extra.R/G/B` (COVER), `apr_trace`.
    pub debug: Vec<(String, Vec<f32>)>,
}

/// Feature planes and their variances, f64.
pub type FeaturePlanes = (Vec<Vec<f64>>, Vec<Vec<f64>>);

/// The feature planes APR reads, in §4.1's order: normal xyz, albedo rgb,
/// depth, visibility when present; with their variances.
pub fn features(clean: &StatsImage) -> Result<FeaturePlanes> {
    let mut f = Vec::new();
    let mut v = Vec::new();
    for (l, lv, required) in [
        (Layer::Normal, Layer::NormalVariance, true),
        (Layer::Albedo, Layer::AlbedoVariance, true),
        (Layer::Depth, Layer::DepthVariance, true),
        (Layer::Visibility, Layer::VisibilityVariance, false),
    ] {
        let Some(p) = clean.get(l) else {
            if required {
                return Err(Error::BadData(format!("APR needs the {} layer", l.name())));
            }
            continue;
        };
        let pv = clean.get(lv);
        for (c, plane) in p.iter().enumerate() {
            f.push(plane.iter().map(|&x| x as f64).collect());
            v.push(match pv {
                Some(pv) => pv[c].iter().map(|&x| x as f64).collect(),
                None => vec![0.0; plane.len()],
            });
        }
    }
    Ok((f, v))
}

/// APR on the CPU. `prefilter_features`: run §4.6 (false when the G-buffer
/// prefilter already replaced the features).
pub fn run_cpu(
    clean: &StatsImage,
    params: AprParams,
    prefilter_features: bool,
) -> Result<AprResult> {
    let (w, h) = (clean.width, clean.height);
    let n = w * h;
    let need = |l: Layer| {
        clean
            .get(l)
            .ok_or_else(|| Error::BadData(format!("APR needs the {} layer", l.name())))
    };
    let col = need(Layer::Color)?;
    let cvar = need(Layer::ColorVariance)?;
    let valid: Vec<bool> = need(Layer::Spp)?[0]
        .iter()
        .map(|&s| spp_of(s) >= 1.0)
        .collect();
    let (mut feats, mut fvar) = features(clean)?;
    let spp = &need(Layer::Spp)?[0];
    if params.filter_visibility && feats.len() == 8 {
        let f32s = |p: &[f64]| p.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let [g, gv] = super::wlr::filter_visibility(w, h, &f32s(&feats[7]), &f32s(&fvar[7]), spp);
        feats[7] = g.iter().map(|&x| x as f64).collect();
        fvar[7] = gv.iter().map(|&x| x as f64).collect();
    }
    let scales = r::test_scales(spp, params.count_cap);
    if prefilter_features {
        for (f, v) in feats.iter_mut().zip(&fvar) {
            *f = r::prefilter_plane(w, h, f, v, &valid);
        }
    }
    let mut color: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut error: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut dim = vec![0.0f32; n];
    let mut debug = Vec::new();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let y: Vec<f64> = col[c].iter().map(|&x| x as f64).collect();
        let v: Vec<f64> = cvar[c].iter().map(|&x| x as f64).collect();
        let pl = Planes {
            w,
            h,
            y: &y,
            v: &v,
            feats: &feats,
            valid: &valid,
            test_scale: Some(&scales),
        };
        let res = r::channel(
            &pl,
            params.stages,
            r::block_shape(params.clamped),
            params.pixel_test.then_some(spp.as_slice()),
        );
        for i in 0..n {
            let out = if valid[i] {
                res.color[i]
            } else {
                r::invalid_fill(w, h, &y, &valid, i)
            };
            color[c][i] = out.max(0.0) as f32;
            error[c][i] = res.error[i] as f32;
            dim[i] += (res.dim[i] / 3.0) as f32;
        }
        debug.push((
            format!("apr_order.{name}"),
            res.centre_order.iter().map(|&x| x as f32).collect(),
        ));
        debug.push((
            format!("apr_extra.{name}"),
            res.extra.iter().map(|&x| x as f32).collect(),
        ));
    }
    debug.push(("apr_trace".into(), dim.clone()));
    Ok(AprResult {
        color: RgbImage::from_planes(w, h, color),
        error: RgbImage::from_planes(w, h, error),
        dim,
        debug,
    })
}

/// GPU buffers of one APR run (spec §4.7): the block states of the three
/// channels, the extra blocks' planes, two sets of stage planes (`ŷ_t`,
/// `σ̂_t²`, used in turn) and the outputs.
#[derive(Debug)]
pub struct AprPlanes {
    /// `3 × blocks × STATE` f32: the last recorded stage's block states.
    pub state: GpuBuffer,
    /// `3 × EXTRA_PLANES` planes (COVER blocks' values at their pixel).
    pub extra: PlaneSet,
    /// The queue of a band's extra blocks (u32, `apr_block::queue_words`).
    pub queue: GpuBuffer,
    /// Stage planes, [`STAGE_OUTPUTS`] each.
    pub stage: [PlaneSet; 2],
    /// The [`OUTPUTS`] planes: colour RGB, error RGB, dimension, extra mask RGB.
    pub out: PlaneSet,
    /// The features packed by [`apr_pack`] (2 vec4 planes, APR-PACKED).
    pub packed: PlaneSet,
    /// The image's sample total ([`spp_total`], APR-COUNT-CAP).
    pub total: GpuBuffer,
    /// APR-VIS: the filtered visibility and its variance (2 planes), which
    /// [`record_pack`] packs.
    pub vis: PlaneSet,
    width: usize,
    height: usize,
}

impl AprPlanes {
    /// Allocates the planes for a `width × height` image. Fails with
    /// [`Error::Limit`] when a binding would exceed `maxStorageBufferRange`.
    pub fn new(ctx: &Arc<GpuContext>, width: usize, height: usize) -> Result<AprPlanes> {
        let n = width * height;
        let (gw, gh) = grid(width, height);
        let state_bytes = (3 * gw * gh * STATE * 4) as u64;
        let limit = ctx.info.max_storage_buffer_range as u64;
        for (what, bytes) in [
            ("block state", state_bytes),
            ("extra planes", plane_stride(n) * (3 * EXTRA_PLANES) as u64),
            ("output planes", plane_stride(n) * OUTPUTS as u64),
        ] {
            if bytes > limit {
                return Err(Error::Limit(format!(
                    "APR's {what} for {width}x{height} ({bytes} bytes, one binding) exceed maxStorageBufferRange ({limit} bytes)"
                )));
            }
        }
        Ok(AprPlanes {
            state: GpuBuffer::new(ctx, "apr.state", state_bytes)?,
            extra: PlaneSet::new(ctx, "apr.extra", n, 3 * EXTRA_PLANES)?,
            queue: GpuBuffer::new(
                ctx,
                "apr.queue",
                4 * apr_block::queue_words(width, height) as u64,
            )?,
            stage: [
                PlaneSet::new(ctx, "apr.stage0", n, STAGE_OUTPUTS)?,
                PlaneSet::new(ctx, "apr.stage1", n, STAGE_OUTPUTS)?,
            ],
            out: PlaneSet::new(ctx, "apr.out", n, OUTPUTS)?,
            packed: PlaneSet::new(ctx, "apr.packed", 4 * n, 2)?,
            total: GpuBuffer::new(ctx, "apr.total", 4 * spp_total::WORDS as u64)?,
            vis: PlaneSet::new(ctx, "apr.vis", n, 2)?,
            width,
            height,
        })
    }

    /// The output colour planes R, G, B (clamped ≥ 0).
    pub fn color(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out.plane(c))
    }

    /// `ξ̂_i` per channel.
    pub fn error(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out.plane(3 + c))
    }

    /// The blended `tr H`, mean over the channels (`d_i` of §9.1).
    pub fn dim(&self) -> BufferSlice {
        self.out.plane(6)
    }
}

/// The feature bindings APR reads from `clean` (normal xyz, albedo rgb,
/// depth, visibility) and whether visibility is present (otherwise the
/// normal's x plane stands in and the kernels read 0).
pub fn gpu_features(clean: &GpuStats) -> ([BufferSlice; 8], bool) {
    let vis = clean.has(Layer::Visibility);
    let f = [
        clean.plane(Layer::Normal, 0),
        clean.plane(Layer::Normal, 1),
        clean.plane(Layer::Normal, 2),
        clean.plane(Layer::Albedo, 0),
        clean.plane(Layer::Albedo, 1),
        clean.plane(Layer::Albedo, 2),
        clean.plane(Layer::Depth, 0),
        if vis {
            clean.plane(Layer::Visibility, 0)
        } else {
            clean.plane(Layer::Normal, 0)
        },
    ];
    (f, vis)
}

/// Which visibility [`record_pack`] packs.
#[derive(Copy, Clone)]
pub enum VisFeature<'a> {
    /// The input's (§4.1).
    Raw,
    /// APR-VIS: filtered first into the two planes of this scratch set
    /// (`aos_nlm_vis`: its 3×3 means, NL-means filtered, as WLR-VIS reads
    /// it).
    Filter(&'a PlaneSet),
    /// APR-VIS, already filtered by the caller (`StageRun::visibility`):
    /// the filtered visibility plane.
    Filtered(BufferSlice),
}

impl<'a> VisFeature<'a> {
    /// APR-VIS's choice for `params`: the caller's filtered plane when
    /// given, else a filter into `scratch`; the raw feature when
    /// `apr.visibility=raw`.
    pub(super) fn of(
        params: AprParams,
        scratch: &'a PlaneSet,
        filtered: Option<[BufferSlice; 2]>,
    ) -> Self {
        match (params.filter_visibility, filtered) {
            (false, _) => VisFeature::Raw,
            (true, Some([v, _])) => VisFeature::Filtered(v),
            (true, None) => VisFeature::Filter(scratch),
        }
    }
}

/// Records `apr_pack` (APR-PACKED): `clean`'s features into the two vec4
/// planes `out`, the visibility as `vis_feature` says. Returns whether
/// visibility is present (else its lane is 0).
pub fn record_pack(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    vis_feature: VisFeature,
    out: [BufferSlice; 2],
) -> Result<bool> {
    let (mut feats, vis) = gpu_features(clean);
    if vis {
        match vis_feature {
            VisFeature::Raw => {}
            VisFeature::Filter(scratch) => {
                super::wlr::record_visibility(batch, precision, clean, scratch, 0)?;
                feats[7] = scratch.plane(0);
            }
            VisFeature::Filtered(plane) => feats[7] = plane,
        }
    }
    apr_pack::record(
        batch,
        precision,
        &AprPush {
            width: clean.width as u32,
            height: clean.height as u32,
            flags: apr_flags(vis, false, false),
            ..Default::default()
        },
        &feats,
        out,
    )?;
    Ok(vis)
}

/// [`AprPush::flags`] of a dispatch.
pub(super) fn apr_flags(vis: bool, clamped: bool, count_cap: bool) -> u32 {
    (if vis { APR_VIS } else { 0 })
        | (if clamped { APR_CLAMPED } else { 0 })
        | (if count_cap { APR_COUNT_CAP } else { 0 })
}

/// Records APR (§4.2–4.3) on sanitised (and outlier-cleaned) statistics:
/// the image's sample total (APR-COUNT-CAP: `total`, the whole image's when
/// this is a tile, else counted here), then per stage the sparse blocks of
/// each channel, the extra blocks, the gather. The outputs stay on the GPU
/// in `planes`. The feature prefilter (§4.6, `apr.prefilter=on`) runs on
/// the CPU backend only.
pub fn record_apr(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &AprPlanes,
    params: AprParams,
    total: Option<[u32; 3]>,
    filtered: Option<[BufferSlice; 2]>,
) -> Result<()> {
    let (w, h) = (clean.width, clean.height);
    if (w, h) != (planes.width, planes.height) {
        return Err(Error::InvalidArgument(format!(
            "APR planes are {}x{}, the statistics {w}x{h}",
            planes.width, planes.height
        )));
    }
    let vis = clean.has(Layer::Visibility);
    let spp = clean.plane(Layer::Spp, 0);
    let color: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::Color, c));
    let var: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::ColorVariance, c));
    let stride = (plane_stride(w * h) / 4) as u32;
    let stages = params.stages.max(1);
    match total {
        Some(words) => {
            for (k, &word) in words.iter().enumerate() {
                batch.fill(planes.total.range(4 * k as u64, 4), word);
            }
        }
        None => {
            batch.fill(planes.total.slice(), 0);
            spp_total::record(batch, w as u32, h as u32, spp, planes.total.slice())?;
        }
    }
    let sppt = (spp, planes.total.slice());
    // APR-PACKED: the features as 2 vec4 planes, read by every stage.
    let packed = [planes.packed.plane(0), planes.packed.plane(1)];
    let vis_feature = VisFeature::of(params, &planes.vis, filtered);
    record_pack(batch, precision, clean, vis_feature, packed)?;
    for stage in 1..=stages {
        let last = stage == stages;
        let prev = (stage >= 2).then(|| &planes.stage[stage % 2]);
        let push = AprPush {
            width: w as u32,
            height: h as u32,
            last: last as u32,
            flags: apr_flags(vis, params.clamped, params.count_cap),
            stride,
            ..Default::default()
        };
        let io = StageBindings {
            chans: std::array::from_fn(|ch| AprChannel {
                y: color[ch],
                v: var[ch],
                yprev: prev.map_or(color[ch], |p| p.plane(ch)),
                s2prev: prev.map_or(var[ch], |p| p.plane(3 + ch)),
            }),
            packed,
            sppt,
            color,
            var,
            gather_packed: packed,
            gather_sppt: sppt,
            dst: if last {
                planes.out.all()
            } else {
                planes.stage[(stage + 1) % 2].all()
            },
        };
        record_stage(batch, precision, planes, push, params.pixel_test, &io)?;
    }
    Ok(())
}

/// The bindings of one APR stage: per channel the blocks' inputs, and the
/// packed features and sample counts and totals they read (the ring's in
/// APR's temporal window, `methods::apr_window`); the gather's colour,
/// variance, features and counts (the centre frame's there), and its
/// output planes.
pub struct StageBindings {
    /// The blocks' `y`, `v`, `ŷ_{t−1}`, `σ̂²_{t−1}` per channel.
    pub chans: [AprChannel; 3],
    /// The blocks' packed features.
    pub packed: [BufferSlice; 2],
    /// The blocks' counts and sample totals.
    pub sppt: (BufferSlice, BufferSlice),
    /// The gather's colour.
    pub color: [BufferSlice; 3],
    /// The gather's colour variance.
    pub var: [BufferSlice; 3],
    /// The gather's packed features.
    pub gather_packed: [BufferSlice; 2],
    /// The gather's counts and sample total.
    pub gather_sppt: (BufferSlice, BufferSlice),
    /// [`OUTPUTS`] planes after the last stage, else [`STAGE_OUTPUTS`].
    pub dst: BufferSlice,
}

/// Records one stage of APR (§4.3): the sparse and the extra blocks of
/// each channel, then the gather. `push` gives the size, `last`, the
/// plane stride, the blocks' flags and (temporal window) `window`; the
/// gather takes the same flags but APR-OUTLIER-W's, and APR-PIXEL-TEST's
/// with `pixel_test`.
pub fn record_stage(
    batch: &mut Batch,
    precision: Precision,
    planes: &AprPlanes,
    push: AprPush,
    pixel_test: bool,
    io: &StageBindings,
) -> Result<()> {
    batch.fill(planes.extra.all(), 0);
    for (ch, chan) in io.chans.iter().enumerate() {
        for mode in [0, 1] {
            let push = AprPush {
                channel: ch as u32,
                mode,
                ..push
            };
            apr_block::record(
                batch,
                precision,
                &push,
                chan,
                &io.packed,
                io.sppt,
                (
                    planes.state.slice(),
                    planes.extra.all(),
                    planes.queue.slice(),
                ),
                0.02,
            )?;
        }
    }
    let push = AprPush {
        flags: (push.flags & !APR_CLAMPED) | if pixel_test { APR_PIXEL_TEST } else { 0 },
        window: 0,
        ..push
    };
    apr_gather::record(
        batch,
        precision,
        &push,
        io.color,
        io.var,
        &io.gather_packed,
        io.gather_sppt,
        planes.state.slice(),
        planes.extra.all(),
        io.dst,
    )
}

/// Downloads a finished [`record_apr`] as the CPU path's [`AprResult`].
pub fn download(planes: &AprPlanes) -> Result<AprResult> {
    let (w, h) = (planes.width, planes.height);
    let out = planes.out.download_all()?;
    let (gw, gh) = grid(w, h);
    let state = planes.state.read_vec::<f32>(3 * gw * gh * STATE)?;
    let rgb = |k: usize| RgbImage::from_planes(w, h, std::array::from_fn(|c| out[k + c].clone()));
    let mut debug = Vec::new();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let mut order = vec![0.0f32; w * h];
        for b in 0..gw * gh {
            let r = RADIUS as usize;
            let i = (b / gw) * r * w + (b % gw) * r;
            let st = &state[(c * gw * gh + b) * STATE..];
            if st[2] > 0.0 {
                order[i] = st[0] + 1.0;
            }
        }
        debug.push((format!("apr_order.{name}"), order));
        debug.push((format!("apr_extra.{name}"), out[7 + c].clone()));
    }
    debug.push(("apr_trace".into(), out[6].clone()));
    Ok(AprResult {
        color: rgb(0),
        error: rgb(3),
        dim: out[6].clone(),
        debug,
    })
}

/// APR's entry in the method registry.
pub static INFO: MethodInfo = MethodInfo {
    method: Method::Apr,
    name: "apr",
    about: "adaptive polynomial rendering: per-block polynomial order (spec §4; US patent 9,959,664 B2)",
    needs: &REGRESSION_LAYERS,
    prefilter_auto: true,
    outliers_auto: true,
    pyramid_auto: false,
    blend: super::blend::BlendDefaults {
        auto: true,
        k: 0.125,
        ..super::blend::BlendDefaults::BASE
    },
    // MAP-WLR: WLR's estimate places the adaptive passes' samples.
    map_method: Method::Wlr,
    passes: 5,
    // APR-CAP: a pass gives a pixel at most 4× its mean.
    pass_cap: Some(4.0),
    map_check: true,
    sampling: SamplingParams {
        eps: sampling::EPS_DEFAULT,
        sigma_s: sampling::SIGMA_APR,
        e_is_dmse: false,
        dim: DimSource::Plain,
        floor: 0.6,
    },
    error_scale: 2.5,
    // PYRAMID-ERROR-SCALE: error_scale × 2.06.
    pyramid_error_scale: 5.2,
    // TEMPORAL-TEST-SCALE: WLR's factor (the record has the measured ratio).
    inflate_scale: 1.0,
    // The sparse centres lie every RADIUS pixels (§4.3).
    align: RADIUS as usize,
    halo: |c| {
        let r = RADIUS as usize;
        let params = AprParams::new(&c.options)?;
        let stages = params.stages.max(1);
        // APR-VIS: the visibility's filter reads it within its reach.
        let nlm = if params.filter_visibility {
            super::wlr::VIS_FILTER_REACH
        } else {
            0
        };
        Ok(r + 2 * r * stages + nlm)
    },
    arena_bytes: registry::no_bytes,
    arena_kept: registry::nothing_kept,
    options_for: registry::same_options,
    ring_bytes: registry::no_bytes,
    gpu: |a| {
        let params = AprParams::new(&a.config.options)?;
        if params.prefilter {
            return Err(Error::InvalidArgument(
                "apr.prefilter=on (APR's own 5x5 feature prefilter) runs on the CPU backend only; use --backend cpu, or --prefilter gbf on the GPU".into(),
            ));
        }
        Ok(Box::new(AprStage {
            planes: AprPlanes::new(a.ctx, a.size.0, a.size.1)?,
            params,
        }))
    },
    cpu: |clean, a| {
        let params = AprParams::new(&a.options)?;
        let r = run_cpu(clean, params, params.prefilter && !a.prefiltered)?;
        Ok(CpuResult {
            color: r.color,
            error: r.error,
            dim: r.dim,
            debug: if a.debug { r.debug } else { Vec::new() },
            stats: Vec::new(),
            map_error: None,
        })
    },
};

/// APR's GPU stage.
struct AprStage {
    planes: AprPlanes,
    params: AprParams,
}

impl GpuStage for AprStage {
    fn record(&self, batch: &mut Batch, run: &StageRun) -> Result<()> {
        record_apr(
            batch,
            run.precision,
            run.stats,
            &self.planes,
            self.params,
            run.spp_total,
            run.visibility,
        )
    }

    fn color(&self, _: &GpuStats) -> [BufferSlice; 3] {
        self.planes.color()
    }

    fn error(&self, _: &GpuStats) -> [BufferSlice; 3] {
        self.planes.error()
    }

    fn dim(&self) -> (BufferSlice, bool) {
        (self.planes.dim(), false)
    }

    fn download(
        &self,
        _: &GpuStats,
        _: (usize, usize),
        _: Option<Rect>,
        debug: bool,
        out: &mut ChainOutput,
    ) -> Result<()> {
        if debug {
            out.debug = download(&self.planes)?.debug;
        }
        Ok(())
    }
}
