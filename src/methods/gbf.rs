//! GBF: the G-buffer prefilter with world positions and SURE (spec §6). It
//! replaces normal, albedo and depth (and their variances) of sanitised
//! statistics by filtered ones before a denoiser runs (§1).

use crate::error::{Error, Result};
use crate::image::{Layer, StatsImage};
use crate::kernels::gauss_smooth;
use crate::reference;
use crate::reference::gbf::{self as rg, SMOOTH_SIGMA};
use crate::shared::SmoothPush;

/// The layers the prefilter reads.
pub const NEEDS: [Layer; 3] = [
    Layer::Position,
    Layer::PositionVariance,
    Layer::PositionCovariance,
];

/// The feature layers it replaces, with their variances.
pub const FEATURES: [(Layer, Layer); 3] = [
    (Layer::Normal, Layer::NormalVariance),
    (Layer::Albedo, Layer::AlbedoVariance),
    (Layer::Depth, Layer::DepthVariance),
];

/// What a CPU run leaves for debugging: `h_opt` and `hbar` per pixel.
#[derive(Clone, Debug)]
pub struct GbfMaps {
    pub h_opt: Vec<f32>,
    pub hbar: Vec<f32>,
}

/// The CPU path (scalar twins) on sanitised statistics, in place.
pub fn run_cpu(clean: &mut StatsImage) -> Result<GbfMaps> {
    for l in NEEDS {
        if !clean.has(l) {
            return Err(Error::BadData(format!(
                "the G-buffer prefilter needs the {} layer",
                l.name()
            )));
        }
    }
    let (w, h) = (clean.width, clean.height);
    let n = w * h;
    let spp = clean.get(Layer::Spp).unwrap()[0].clone();
    let smooth = |map: &[f32]| {
        let push = SmoothPush {
            width: w as u32,
            height: h as u32,
            radius: gauss_smooth::radius(SMOOTH_SIGMA),
            sigma: SMOOTH_SIGMA,
            ..Default::default()
        };
        let mut out = vec![0.0f32; n];
        reference::gauss_smooth::gauss_smooth(&push, map, &spp, &mut out);
        out
    };
    let sbar: Vec<Vec<f32>> = clean
        .get(Layer::PositionCovariance)
        .unwrap()
        .iter()
        .map(|p| smooth(p))
        .collect();
    let pos = clean.get(Layer::Position).unwrap();
    let pos_var = clean.get(Layer::PositionVariance).unwrap();
    let planes = rg::Planes {
        width: w,
        height: h,
        pos: std::array::from_fn(|k| pos[k].as_slice()),
        pos_var: std::array::from_fn(|k| pos_var[k].as_slice()),
        sbar: std::array::from_fn(|k| sbar[k].as_slice()),
        spp: &spp,
    };
    let mut h_opt = vec![0.0f32; n];
    let mut outs = vec![h_opt.clone()];
    reference::wlr::par_pixels::<1>(w, h, &mut outs, |x, y| {
        if !planes.valid(y * w + x) {
            return [0.0];
        }
        [rg::choose(&rg::sure(&planes, x, y)) as f32]
    });
    h_opt.copy_from_slice(&outs[0]);
    let hbar = smooth(&h_opt);
    let mut filtered = Vec::new();
    for (fl, vl) in FEATURES {
        let (Some(f), Some(v)) = (clean.get(fl), clean.get(vl)) else {
            continue;
        };
        let f: Vec<&[f32]> = f.iter().map(|p| p.as_slice()).collect();
        let v: Vec<&[f32]> = v.iter().map(|p| p.as_slice()).collect();
        let k = f.len();
        let mut fo = vec![vec![0.0f32; n]; k];
        let mut vo = vec![vec![0.0f32; n]; k];
        for y in 0..h {
            for x in 0..w {
                let q = y * w + x;
                if !planes.valid(q) {
                    for j in 0..k {
                        fo[j][q] = f[j][q];
                        vo[j][q] = v[j][q];
                    }
                    continue;
                }
                let r = rg::filter_features(&planes, x, y, hbar[q] as f64, &f, &v);
                for j in 0..k {
                    fo[j][q] = r[j].0 as f32;
                    vo[j][q] = r[j].1 as f32;
                }
            }
        }
        filtered.push((fl, fo, vl, vo));
    }
    for (fl, fo, vl, vo) in filtered {
        clean.set(fl, fo);
        clean.set(vl, vo);
    }
    Ok(GbfMaps { h_opt, hbar })
}
