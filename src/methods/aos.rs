//! AOS (spec §5) on the CPU: the NL-means feature prefilter (§5.2; only
//! visibility when the G-buffer prefilter already ran, PREFILTER-STACK),
//! then [`crate::reference::aos::run`] per pixel. GPU kernels are not built
//! yet: on the GPU backend `--method aos` is a clear error.

use super::Pass;
use crate::error::{Error, Result};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::options::Options;
use crate::reference::aos::{self as r, Settings, Variance};
use crate::reference::apr::invalid_fill;
use crate::reference::spp_of;

/// AOS's options.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct AosParams {
    /// Window radius: 9 in the final pass, 5 in intermediate ones (§5.1).
    pub radius: usize,
    /// `aos.variance`, `aos.bias_test`, `aos.identity` (§5.3, and our
    /// decisions AOS-BIAS-TEST and AOS-IDENTITY in `reference::aos`).
    pub settings: Settings,
}

impl AosParams {
    /// From the pass and `--opt aos.variance=paper|sandwich`,
    /// `aos.bias_test=on|off`, `aos.identity=on|off`.
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
            },
        })
    }
}

/// What AOS returns on the CPU.
#[derive(Clone, Debug)]
pub struct AosResult {
    /// The reconstruction, clamped to ≥ 0.
    pub color: RgbImage,
    /// `MSE_c` per pixel (the same in the three channels, §5.3 step 8).
    pub error: RgbImage,
    /// The TSVD rank `k` per pixel (the local dimension `d` of §9.1).
    pub dim: Vec<f32>,
    /// Debug layers (§5.5): `aos_order` (0: the input), `aos_rank`,
    /// `aos_bias1`, `aos_var1`, `aos_bias3`, `aos_var3`, `aos_sigma2`,
    /// `aos_bias_sd1`, `aos_bias_sd3`, and the prefiltered features
    /// `aos_feature.*`.
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
    let valid: Vec<bool> = need(Layer::Spp)?[0]
        .iter()
        .map(|&s| spp_of(s) >= 1.0)
        .collect();
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
    };
    let res = r::run(&pl, params.radius, params.settings);
    let mut color: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut mse = vec![0.0f32; n];
    let mut dim = vec![0.0f32; n];
    let names = [
        "aos_order",
        "aos_rank",
        "aos_bias1",
        "aos_var1",
        "aos_bias3",
        "aos_var3",
        "aos_sigma2",
        "aos_bias_sd1",
        "aos_bias_sd3",
    ];
    let mut layers: Vec<Vec<f32>> = vec![vec![0.0; n]; names.len()];
    for i in 0..n {
        match &res[i] {
            Some(p) => {
                for ch in 0..3 {
                    color[ch][i] = p.color[ch].max(0.0) as f32;
                }
                mse[i] = p.mse as f32;
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
        dim,
        debug: out_debug,
    })
}
