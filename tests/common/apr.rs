//! APR's test images (`tests/apr_kernels.rs`, `tests/apr_window.rs`): a
//! noisy image with features, as the twins' inputs and as statistics.

use super::Rng;
use mcdenoise::reference::apr_block::Inputs;
use mcdenoise::reference::spp_total::{spp_total, spp_total_mean};

/// A noisy image with features in f32 (so both read the same values): a
/// ramp with a step, normals and albedo with an edge, depth, visibility;
/// some invalid pixels and a few spikes that reject everything.
pub struct Img {
    pub w: usize,
    pub h: usize,
    pub y: [Vec<f32>; 3],
    pub v: [Vec<f32>; 3],
    pub feats: Vec<Vec<f32>>,
    pub spp: Vec<f32>,
    /// APR-OUTLIER-W in the twins' inputs.
    pub clamped: bool,
    /// APR-PIXEL-TEST in the gather (the default).
    pub pixel_test: bool,
    /// APR-COUNT-CAP (the default).
    pub count_cap: bool,
}

pub fn image(w: usize, h: usize, seed: u64, vis: bool) -> Img {
    let mut rng = Rng(seed);
    let n = w * h;
    let edge = |i: usize| (i % w) * 3 > w + (i / w);
    let feats: Vec<Vec<f32>> = (0..if vis { 8 } else { 7 })
        .map(|k| {
            (0..n)
                .map(|i| {
                    let base = if edge(i) { 0.8 } else { 0.2 };
                    (base * (k as f64 * 0.3).cos() + 0.02 * rng.uniform()) as f32
                })
                .collect()
        })
        .collect();
    let mut y: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut v: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    for ch in 0..3 {
        for i in 0..n {
            let t =
                0.3 + 0.1 * ch as f64 + 0.004 * (i / w) as f64 + if edge(i) { 0.5 } else { 0.0 };
            y[ch][i] = (t + 0.05 * rng.normal()) as f32;
            v[ch][i] = (0.0025 * (0.5 + rng.uniform())) as f32;
        }
    }
    for k in 0..4 {
        let i = (7 + 13 * k) * w / 3 + 5 + 9 * k;
        for ch in 0..3 {
            y[ch][i % n] = 40.0;
        }
    }
    // Pixels dominated by one bright sample (variance > 1): accepted by the
    // confidence interval, weighted by 1/v under APR-OUTLIER-W.
    for i in (3..n).step_by(17) {
        for ch in 0..3 {
            y[ch][i] += 4.0;
            v[ch][i] = 3.0 + ch as f32;
        }
    }
    // Counts as an adaptive render leaves them (APR-COUNT-CAP matters).
    let spp = (0..n)
        .map(|_| match rng.uniform() {
            u if u < 0.03 => 0.0,
            u if u < 0.85 => 4.0,
            u if u < 0.95 => 16.0,
            _ => 64.0,
        })
        .collect();
    Img {
        w,
        h,
        y,
        v,
        feats,
        spp,
        clamped: true,
        pixel_test: true,
        count_cap: true,
    }
}

impl Img {
    pub fn inputs(&self, ch: usize) -> Inputs<'_> {
        Inputs {
            w: self.w,
            h: self.h,
            y: &self.y[ch],
            v: &self.v[ch],
            yprev: &self.y[ch],
            s2prev: &self.v[ch],
            feats: std::array::from_fn(|j| self.feats.get(j).map(|f| f.as_slice())),
            spp: &self.spp,
            clamped: self.clamped,
            pixel_test: self.pixel_test,
            nbar: self.count_cap.then(|| spp_total_mean(spp_total(&self.spp))),
        }
    }
}

/// The image as statistics (zero feature variances).
pub fn stats(img: &Img) -> mcdenoise::image::StatsImage {
    use mcdenoise::image::{Layer, StatsImage};
    let mut s = StatsImage::new(img.w, img.h);
    let n = img.w * img.h;
    s.set(Layer::Color, img.y.to_vec());
    s.set(Layer::ColorVariance, img.v.to_vec());
    s.set(Layer::Normal, img.feats[0..3].to_vec());
    s.set(Layer::NormalVariance, vec![vec![0.0; n]; 3]);
    s.set(Layer::Albedo, img.feats[3..6].to_vec());
    s.set(Layer::AlbedoVariance, vec![vec![0.0; n]; 3]);
    s.set(Layer::Depth, vec![img.feats[6].clone()]);
    s.set(Layer::DepthVariance, vec![vec![0.0; n]]);
    if img.feats.len() > 7 {
        s.set(Layer::Visibility, vec![img.feats[7].clone()]);
        s.set(Layer::VisibilityVariance, vec![vec![0.0; n]]);
    }
    s.set(Layer::Spp, vec![img.spp.clone()]);
    s
}
