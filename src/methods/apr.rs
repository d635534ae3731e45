//! APR, adaptive polynomial rendering (spec §4), on sanitised (and
//! outlier-cleaned, §4.4) statistics. The CPU path runs
//! [`crate::reference::apr`]; its features come from the G-buffer prefilter
//! when that ran (PREFILTER-STACK), else they are the input's, or with
//! `apr.prefilter=on` APR's own 5×5 polynomial prefilter (§4.6; off by
//! default, see [`AprParams::prefilter`]).

use crate::error::{Error, Result};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::options::Options;
use crate::reference::apr::{self as r, Planes};
use crate::reference::spp_of;

/// APR's options.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct AprParams {
    /// Stages T (`apr.stages`, ≥ 1; 2 in the paper).
    pub stages: usize,
    /// `apr.prefilter`: run §4.6's 5×5 feature prefilter when the G-buffer
    /// prefilter does not. Off by default (decision APR-PF-OFF): at a small
    /// light's rim it blurs albedo across the edge and the blocks then paint
    /// the wall with the light (glossy_cornell at 4 spp: rMSE 1.37 against
    /// the input's 0.27; 0.017 without it).
    pub prefilter: bool,
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
    let (mut feats, fvar) = features(clean)?;
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
        };
        let res = r::channel(&pl, params.stages);
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
