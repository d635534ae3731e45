//! AOS (spec §5): the NL-means feature prefilter (§5.2; only visibility
//! when the G-buffer prefilter already ran, PREFILTER-STACK), then per pixel
//! the TSVD local space and the adaptive-order fits.
//!
//! On the CPU, [`crate::reference::aos::run`]. On the GPU (spec §5.4),
//! three kernels: `aos_nlm` per feature buffer, then per band of rows
//! `aos_space` (the local spaces, [`SPACE`] f32 per pixel in a scratch sized
//! for the band) and `aos_fit` (one workgroup per pixel).

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
use crate::kernels::aos_fit::{self, DEBUG_NAMES, OUTPUTS};
use crate::kernels::aos_nlm;
use crate::kernels::aos_space::{self, SPACE};
use crate::kernels::channel_mean;
use crate::options::Options;
use crate::reference::aos::{self as r, Settings, Variance};
use crate::reference::apr::invalid_fill;
use crate::reference::spp_of;
use crate::shared::AosPush;

/// AOS's options.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct AosParams {
    /// Window radius: 9 in the final pass, 5 in intermediate ones (§5.1).
    pub radius: usize,
    /// `aos.variance`, `aos.bias_test`, `aos.identity`,
    /// `aos.outlier_weight`, `aos.residual` (§5.3, and our decisions
    /// AOS-BIAS-TEST, AOS-IDENTITY, AOS-OUTLIER-W and AOS-RESIDUAL in
    /// `reference::aos`).
    pub settings: Settings,
}

impl AosParams {
    /// From the pass and `--opt aos.variance=paper|sandwich`,
    /// `aos.bias_test=on|off`, `aos.identity=on|off`, `aos.identity_floor=on|off`,
    /// `aos.outlier_weight=clamped|off`, `aos.residual=on|off`.
    pub fn new(pass: Pass, opts: &Options) -> Result<AosParams> {
        let variance = match opts.get("aos.variance") {
            "paper" => Variance::Paper,
            "sandwich" => Variance::Sandwich,
            v => {
                return Err(Error::InvalidArgument(format!(
                    "aos.variance: paper or sandwich, not {v}"
                )))
            }
        };
        Ok(AosParams {
            radius: match pass {
                Pass::Final => r::RADIUS_FINAL,
                Pass::Intermediate => r::RADIUS_INTERMEDIATE,
            },
            settings: Settings {
                variance,
                bias_test: opts.get("aos.bias_test") == "on",
                identity: opts.get("aos.identity") == "on",
                identity_floor: opts.get("aos.identity_floor") == "on",
                outlier_weight: opts.get("aos.outlier_weight") == "clamped",
                residual: opts.get("aos.residual") == "on",
                feature_noise: opts.get("aos.feature_noise") == "on",
            },
        })
    }
}

/// What AOS returns on the CPU.
#[derive(Clone, Debug)]
pub struct AosResult {
    /// The reconstruction, clamped to ≥ 0.
    pub color: RgbImage,
    /// The error estimate per pixel: `MSE_c` plus AOS-FEATNOISE's term (the
    /// same in the three channels).
    pub error: RgbImage,
    /// `MSE_c` (§5.3 step 8), the sample map's `E_i`.
    pub map_error: Vec<f32>,
    /// The TSVD rank `k` per pixel (the local dimension `d` of §9.1).
    pub dim: Vec<f32>,
    /// Debug layers (§5.5): `aos_order` (0: the input), `aos_rank`,
    /// `aos_bias1`, `aos_var1`, `aos_bias3`, `aos_var3`, `aos_sigma2`,
    /// `aos_bias_sd1`, `aos_bias_sd3`, `aos_map_mse`, and the prefiltered
    /// features `aos_feature.*`.
    pub debug: Vec<(String, Vec<f32>)>,
}

/// The feature buffers of §5.1 in AOS's order, with the number of channels
/// of each (NL-means filters a buffer as a whole).
const BUFFERS: [(Layer, Layer, &str, bool); 4] = [
    (Layer::Depth, Layer::DepthVariance, "depth", true),
    (Layer::Albedo, Layer::AlbedoVariance, "albedo", true),
    (Layer::Normal, Layer::NormalVariance, "normal", true),
    (
        Layer::Visibility,
        Layer::VisibilityVariance,
        "visibility",
        false,
    ),
];

/// AOS on sanitised (and outlier-cleaned) statistics. `gbf_ran`: the
/// G-buffer prefilter already replaced normal, albedo and depth, so only
/// visibility is NL-means filtered (PREFILTER-STACK).
pub fn run_cpu(clean: &StatsImage, params: AosParams, gbf_ran: bool) -> Result<AosResult> {
    let (w, h) = (clean.width, clean.height);
    let n = w * h;
    let need = |l: Layer| {
        clean
            .get(l)
            .ok_or_else(|| Error::BadData(format!("AOS needs the {} layer", l.name())))
    };
    let f64s = |p: &[f32]| p.iter().map(|&x| x as f64).collect::<Vec<f64>>();
    let col: Vec<Vec<f64>> = need(Layer::Color)?.iter().map(|p| f64s(p)).collect();
    let cvar = need(Layer::ColorVariance)?;
    let vbar: Vec<f64> = (0..n)
        .map(|i| (cvar[0][i] + cvar[1][i] + cvar[2][i]) as f64 / 3.0)
        .collect();
    let spp: Vec<f64> = need(Layer::Spp)?[0].iter().map(|&s| spp_of(s)).collect();
    let valid: Vec<bool> = spp.iter().map(|&s| s >= 1.0).collect();
    let mut feats = Vec::new();
    let mut fvar = Vec::new();
    let mut debug = Vec::new();
    for (layer, vlayer, name, required) in BUFFERS {
        let Some(planes) = clean.get(layer) else {
            if required {
                return Err(Error::BadData(format!(
                    "AOS needs the {} layer",
                    layer.name()
                )));
            }
            continue;
        };
        let g: Vec<Vec<f64>> = planes.iter().map(|p| f64s(p)).collect();
        let vg: Vec<Vec<f64>> = match clean.get(vlayer) {
            Some(v) => v.iter().map(|p| f64s(p)).collect(),
            None => vec![vec![0.0; n]; g.len()],
        };
        let filter = layer == Layer::Visibility || !gbf_ran;
        let (g, vg) = if filter {
            let gr: Vec<&[f64]> = g.iter().map(|p| p.as_slice()).collect();
            let vr: Vec<&[f64]> = vg.iter().map(|p| p.as_slice()).collect();
            r::nlmeans(w, h, &gr, &vr, &valid)
        } else {
            (g, vg)
        };
        for (c, (p, v)) in g.into_iter().zip(vg).enumerate() {
            debug.push((
                format!("aos_feature.{name}.{c}"),
                p.iter().map(|&x| x as f32).collect(),
            ));
            feats.push(p);
            fvar.push(v);
        }
    }
    let pl = r::Planes {
        w,
        h,
        color: [&col[0], &col[1], &col[2]],
        vbar: &vbar,
        feats: &feats,
        fvar: &fvar,
        valid: &valid,
        spp: &spp,
    };
    let res = r::run(&pl, params.radius, params.settings);
    let mut color: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut mse = vec![0.0f32; n];
    let mut map_mse = vec![0.0f32; n];
    let mut dim = vec![0.0f32; n];
    // The GPU kernel's debug planes, in its order.
    let names = DEBUG_NAMES;
    let mut layers: Vec<Vec<f32>> = vec![vec![0.0; n]; names.len()];
    for i in 0..n {
        match &res[i] {
            Some(p) => {
                for ch in 0..3 {
                    color[ch][i] = p.color[ch].max(0.0) as f32;
                }
                mse[i] = (p.mse + p.feat_var) as f32;
                map_mse[i] = p.mse as f32;
                dim[i] = p.rank as f32;
                let vals = [
                    p.order as f64,
                    p.rank as f64,
                    p.bias[0],
                    p.var[0],
                    p.bias[1],
                    p.var[1],
                    p.sigma2,
                    p.bias_sd[0],
                    p.bias_sd[1],
                    p.mse,
                ];
                for (l, v) in layers.iter_mut().zip(vals) {
                    l[i] = v as f32;
                }
            }
            None => {
                for ch in 0..3 {
                    color[ch][i] = invalid_fill(w, h, &col[ch], &valid, i).max(0.0) as f32;
                }
            }
        }
    }
    let mut out_debug: Vec<(String, Vec<f32>)> =
        names.iter().map(|s| s.to_string()).zip(layers).collect();
    out_debug.extend(debug);
    Ok(AosResult {
        color: RgbImage::from_planes(w, h, color),
        error: RgbImage::from_planes(w, h, [mse.clone(), mse.clone(), mse]),
        map_error: map_mse,
        dim,
        debug: out_debug,
    })
}

/// The feature planes of the GPU path: per buffer (depth, albedo, normal,
/// visibility) its NL-means output, channels then variances, at
/// [`FEAT_BASE`]`[b]`.
const FEAT_PLANES: usize = 16;
/// First plane of each buffer's block in [`AosPlanes::feat`].
const FEAT_BASE: [usize; 4] = [0, 2, 8, 14];

/// Most bytes of one band's scratch of local spaces (and never more than
/// `maxStorageBufferRange`).
const SPACE_BAND_BYTES: u64 = 64 << 20;

/// GPU buffers of one AOS run.
#[derive(Debug)]
pub struct AosPlanes {
    /// NL-means outputs (`FEAT_PLANES`; the visibility block stays 0 when
    /// the input has none: a constant feature, see `reference::aos_space`).
    pub feat: PlaneSet,
    /// `vbar`.
    pub vbar: PlaneSet,
    /// Local spaces of one band of rows.
    pub space: GpuBuffer,
    /// Rows per band.
    pub band_rows: usize,
    /// The [`OUTPUTS`] planes of `aos_fit`.
    pub out: PlaneSet,
    width: usize,
    height: usize,
}

/// Rows of one band of local spaces (`row_bytes` per row) in a binding of
/// `cap` bytes: the whole image if it fits, else a multiple of 8 rows —
/// `aos_space` runs whole workgroups of 8 rows, so a band that is not would
/// have its last workgroup write past it. `None` if 8 rows do not fit.
fn space_band_rows(row_bytes: u64, height: usize, cap: u64) -> Option<usize> {
    let fit = (cap / row_bytes.max(1)) as usize;
    if fit >= height {
        Some(height.max(1))
    } else if fit >= 8 {
        Some(fit / 8 * 8)
    } else {
        None
    }
}

impl AosPlanes {
    /// Allocates the planes for a `width × height` image.
    pub fn new(ctx: &Arc<GpuContext>, width: usize, height: usize) -> Result<AosPlanes> {
        let n = width * height;
        let row_bytes = (width * SPACE * 4) as u64;
        let cap = SPACE_BAND_BYTES.min(ctx.info.max_storage_buffer_range as u64);
        let band_rows = space_band_rows(row_bytes, height, cap).ok_or_else(|| {
            Error::Limit(format!(
                "AOS's local spaces of 8 rows of {width} pixels ({} bytes) exceed one binding ({cap} bytes)",
                8 * row_bytes
            ))
        })?;
        Ok(AosPlanes {
            feat: PlaneSet::new(ctx, "aos.feat", n, FEAT_PLANES)?,
            vbar: PlaneSet::new(ctx, "aos.vbar", n, 1)?,
            space: GpuBuffer::new(ctx, "aos.space", band_rows as u64 * row_bytes)?,
            band_rows,
            out: PlaneSet::new(ctx, "aos.out", n, OUTPUTS)?,
            width,
            height,
        })
    }

    /// The output colour planes R, G, B (clamped ≥ 0).
    pub fn color(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out.plane(c))
    }

    /// `MSE_c` (shared by the channels).
    pub fn mse(&self) -> BufferSlice {
        self.out.plane(3)
    }

    /// `MSE_c` without AOS-FEATNOISE's term: the sample map's `E_i`.
    pub fn map_mse(&self) -> BufferSlice {
        self.out.plane(13)
    }

    /// The TSVD rank (`d_i` of §9.1).
    pub fn dim(&self) -> BufferSlice {
        self.out.plane(5)
    }
}

/// The mean TSVD rank the cost count assumes (measured on the public
/// scenes' windows: mostly 2 to 4).
const COST_RANK: f64 = 3.0;

/// Records AOS on sanitised (and outlier-cleaned, prefiltered) statistics;
/// the outputs stay on the GPU in `planes`. `gbf_ran`: only visibility is
/// NL-means filtered (PREFILTER-STACK).
pub fn record_aos(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &AosPlanes,
    params: AosParams,
    gbf_ran: bool,
) -> Result<()> {
    let (w, h) = (clean.width, clean.height);
    if (w, h) != (planes.width, planes.height) {
        return Err(Error::InvalidArgument(format!(
            "AOS planes are {}x{}, the statistics {w}x{h}",
            planes.width, planes.height
        )));
    }
    let spp = clean.plane(Layer::Spp, 0);
    let color: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::Color, c));
    let cvar: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::ColorVariance, c));
    channel_mean::record(
        batch,
        precision,
        w as u32,
        h as u32,
        cvar,
        planes.vbar.plane(0),
    )?;
    let stride = (planes.feat.stride / 4) as u32;
    let base_push = AosPush {
        width: w as u32,
        height: h as u32,
        radius: params.radius as u32,
        flags: params.settings.flags(),
        ..Default::default()
    };
    let mut feats = Vec::with_capacity(8);
    let mut vars = Vec::with_capacity(8);
    for (b, (layer, vlayer, _, required)) in BUFFERS.into_iter().enumerate() {
        let base = FEAT_BASE[b];
        let nc = layer.channels().len();
        if !clean.has(layer) {
            if required {
                return Err(Error::BadData(format!(
                    "AOS needs the {} layer",
                    layer.name()
                )));
            }
            // A constant (zero) feature with zero variance.
            batch.fill(planes.feat.plane(base), 0);
            batch.fill(planes.feat.plane(base + 1), 0);
            feats.push(planes.feat.plane(base));
            vars.push(planes.feat.plane(base + 1));
            continue;
        }
        let g: Vec<BufferSlice> = (0..nc).map(|c| clean.plane(layer, c)).collect();
        // Sanitation gives every feature its variance layer (§0.4).
        let vg: Vec<BufferSlice> = (0..nc).map(|c| clean.plane(vlayer, c)).collect();
        if layer == Layer::Visibility || !gbf_ran {
            // The fit's flags are not the prefilter's: §5.2's NL-means, unclamped.
            let push = AosPush {
                channels: nc as u32,
                stride,
                flags: 0,
                ..base_push
            };
            let pick = |v: &[BufferSlice]| -> [BufferSlice; 3] {
                std::array::from_fn(|c| v[c.min(nc - 1)])
            };
            let dst = planes.feat.range(
                base as u64 * planes.feat.stride,
                (2 * nc - 1) as u64 * planes.feat.stride + (w * h * 4) as u64,
            );
            aos_nlm::record(batch, precision, &push, pick(&g), pick(&vg), spp, dst)?;
            for c in 0..nc {
                feats.push(planes.feat.plane(base + c));
                vars.push(planes.feat.plane(base + nc + c));
            }
        } else {
            feats.extend(g);
            vars.extend(vg);
        }
    }
    let feats: [BufferSlice; 8] = feats.try_into().expect("eight feature planes");
    let vars: [BufferSlice; 8] = vars.try_into().expect("eight variance planes");
    let out_stride = (planes.out.stride / 4) as u32;
    let mut y0 = 0;
    while y0 < h {
        let rows = planes.band_rows.min(h - y0);
        let push = AosPush {
            base_row: y0 as u32,
            stride: out_stride,
            ..base_push
        };
        aos_space::record(
            batch,
            precision,
            &push,
            rows as u32,
            &feats,
            &vars,
            spp,
            planes.space.slice(),
        )?;
        aos_fit::record(
            batch,
            precision,
            &push,
            rows as u32,
            &feats,
            color,
            planes.vbar.plane(0),
            spp,
            planes.space.slice(),
            &vars,
            planes.out.all(),
            COST_RANK,
        )?;
        y0 += rows;
    }
    Ok(())
}

/// Downloads a finished [`record_aos`] as the CPU path's [`AosResult`]
/// (debug layers: §5.5's, without the prefiltered features).
pub fn download(planes: &AosPlanes) -> Result<AosResult> {
    let (w, h) = (planes.width, planes.height);
    let out = planes.out.download_all()?;
    let rgb = |k: usize| RgbImage::from_planes(w, h, std::array::from_fn(|c| out[k + c].clone()));
    Ok(AosResult {
        color: rgb(0),
        error: RgbImage::from_planes(w, h, [out[3].clone(), out[3].clone(), out[3].clone()]),
        map_error: out[13].clone(),
        dim: out[5].clone(),
        debug: DEBUG_NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| (n.to_string(), out[4 + i].clone()))
            .collect(),
    })
}

/// AOS's entry in the method registry.
pub static INFO: MethodInfo = MethodInfo {
    method: Method::Aos,
    name: "aos",
    about: "adaptive-order polynomial fitting in feature space: per-pixel order 1 or 3 (spec §5)",
    needs: &REGRESSION_LAYERS,
    // AOS-NO-GBF: its own NL-means prefilter (§5.2) does better.
    prefilter_auto: false,
    outliers_auto: true,
    pyramid_auto: false,
    blend: super::blend::BlendDefaults {
        auto: true,
        radius: 1,
        k: 2.0,
        // BLEND-AOS: a wider residual window and a lower z find the bias
        // AOS's estimate misses (the reflections in `panel`).
        residual_radius: 4,
        z: 0.7,
    },
    // MAP-WLR: WLR's estimate places the adaptive passes' samples.
    map_method: Method::Wlr,
    passes: 3,
    pass_cap: None,
    map_check: false,
    sampling: SamplingParams {
        eps: sampling::EPS_AOS,
        sigma_s: sampling::SIGMA_AOS,
        e_is_dmse: false,
        dim: DimSource::Plain,
        floor: 0.3,
    },
    error_scale: 4.3,
    // PYRAMID-ERROR-SCALE: error_scale × 2.16.
    pyramid_error_scale: 9.3,
    // TEMPORAL-TEST-SCALE: WLR's factor (the record has the measured ratio).
    inflate_scale: 1.0,
    align: 1,
    halo: |c| {
        let r = AosParams::new(c.pass, &c.options)?.radius;
        Ok(r + r::NLM_SEARCH + r::NLM_PATCH)
    },
    arena_bytes: registry::no_bytes,
    arena_kept: registry::nothing_kept,
    options_for: registry::same_options,
    ring_bytes: registry::no_bytes,
    gpu: |a| {
        Ok(Box::new(AosStage {
            planes: AosPlanes::new(a.ctx, a.size.0, a.size.1)?,
            params: AosParams::new(a.config.pass, &a.config.options)?,
        }))
    },
    cpu: |clean, a| {
        let params = AosParams::new(a.pass, &a.options)?;
        let r = run_cpu(clean, params, a.prefiltered)?;
        let (w, h) = (clean.width, clean.height);
        let m = r.map_error;
        Ok(CpuResult {
            color: r.color,
            error: r.error,
            dim: r.dim,
            debug: if a.debug { r.debug } else { Vec::new() },
            stats: Vec::new(),
            map_error: Some(RgbImage::from_planes(w, h, [m.clone(), m.clone(), m])),
        })
    },
};

/// AOS's GPU stage.
struct AosStage {
    planes: AosPlanes,
    params: AosParams,
}

impl GpuStage for AosStage {
    fn record(&self, batch: &mut Batch, run: &StageRun) -> Result<()> {
        record_aos(
            batch,
            run.precision,
            run.stats,
            &self.planes,
            self.params,
            run.prefiltered,
        )
    }

    fn color(&self, _: &GpuStats) -> [BufferSlice; 3] {
        self.planes.color()
    }

    fn error(&self, _: &GpuStats) -> [BufferSlice; 3] {
        [self.planes.mse(); 3]
    }

    /// `MSE_c` without AOS-FEATNOISE's term.
    fn sampling_error(&self, _: &GpuStats) -> [BufferSlice; 3] {
        [self.planes.map_mse(); 3]
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

#[cfg(test)]
mod tests {
    use super::space_band_rows;

    #[test]
    fn space_bands_are_whole_workgroups_of_rows() {
        // 1920 pixels per row, 64 MiB: 86 rows fit, 80 are used.
        let row = 1920 * 101 * 4;
        assert_eq!(space_band_rows(row, 1080, 64 << 20), Some(80));
        assert_eq!(space_band_rows(row, 50, 64 << 20), Some(50));
        assert_eq!(space_band_rows(row, 20, 7 * row), None);
        assert_eq!(space_band_rows(row, 7, 7 * row), Some(7));
        assert_eq!(space_band_rows(row, 0, 64 << 20), Some(1));
    }
}
