//! Planar per-pixel statistics: the in-memory form of a render-statistics EXR
//! (`../shared/docs/input-format.md`) and of the GPU planes.
//!
//! Every scalar channel is one plane of `width * height` f32 values in row-major
//! order (pixel `(x, y)` at index `y * width + x`). A [`StatsImage`] holds the
//! planes of each [`Layer`] that is present.

use std::collections::BTreeMap;

/// One layer of the render-statistics format. The order of the variants is the
/// order layers are listed in (inspect output, EXR channel order).
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Layer {
    Color,
    ColorVariance,
    Albedo,
    AlbedoVariance,
    Normal,
    NormalVariance,
    Depth,
    DepthVariance,
    Position,
    PositionVariance,
    PositionCovariance,
    Visibility,
    VisibilityVariance,
    Spp,
}

/// Whether a layer must be present in an input file.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Requirement {
    /// The file is rejected without it.
    Required,
    /// A variance layer: estimated from the image when missing (spec §0.4 step 4).
    Estimated,
    /// Needed only by the G-buffer prefilter (spec §6) or purely optional.
    Optional,
}

impl Layer {
    /// All layers, in file order.
    pub const ALL: [Layer; 14] = [
        Layer::Color,
        Layer::ColorVariance,
        Layer::Albedo,
        Layer::AlbedoVariance,
        Layer::Normal,
        Layer::NormalVariance,
        Layer::Depth,
        Layer::DepthVariance,
        Layer::Position,
        Layer::PositionVariance,
        Layer::PositionCovariance,
        Layer::Visibility,
        Layer::VisibilityVariance,
        Layer::Spp,
    ];

    /// The mean layers that carry a `<name>_variance` companion.
    pub const WITH_VARIANCE: [Layer; 6] = [
        Layer::Color,
        Layer::Albedo,
        Layer::Normal,
        Layer::Depth,
        Layer::Position,
        Layer::Visibility,
    ];

    /// EXR layer name (the part before the dot).
    pub fn name(self) -> &'static str {
        match self {
            Layer::Color => "color",
            Layer::ColorVariance => "color_variance",
            Layer::Albedo => "albedo",
            Layer::AlbedoVariance => "albedo_variance",
            Layer::Normal => "normal",
            Layer::NormalVariance => "normal_variance",
            Layer::Depth => "depth",
            Layer::DepthVariance => "depth_variance",
            Layer::Position => "position",
            Layer::PositionVariance => "position_variance",
            Layer::PositionCovariance => "position_covariance",
            Layer::Visibility => "visibility",
            Layer::VisibilityVariance => "visibility_variance",
            Layer::Spp => "spp",
        }
    }

    /// EXR channel names of the layer (the part after the dot), in order.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Layer::Color | Layer::ColorVariance | Layer::Albedo | Layer::AlbedoVariance => {
                &["R", "G", "B"]
            }
            Layer::Normal | Layer::NormalVariance | Layer::Position | Layer::PositionVariance => {
                &["X", "Y", "Z"]
            }
            Layer::Depth | Layer::DepthVariance => &["Z"],
            Layer::PositionCovariance => &["XX", "XY", "XZ", "YY", "YZ", "ZZ"],
            Layer::Visibility | Layer::VisibilityVariance | Layer::Spp => &["Y"],
        }
    }

    pub fn requirement(self) -> Requirement {
        match self {
            Layer::Color | Layer::Albedo | Layer::Normal | Layer::Depth | Layer::Spp => {
                Requirement::Required
            }
            Layer::ColorVariance
            | Layer::AlbedoVariance
            | Layer::NormalVariance
            | Layer::DepthVariance => Requirement::Estimated,
            _ => Requirement::Optional,
        }
    }

    /// The variance companion of a mean layer (`color` → `color_variance`).
    pub fn variance(self) -> Option<Layer> {
        match self {
            Layer::Color => Some(Layer::ColorVariance),
            Layer::Albedo => Some(Layer::AlbedoVariance),
            Layer::Normal => Some(Layer::NormalVariance),
            Layer::Depth => Some(Layer::DepthVariance),
            Layer::Position => Some(Layer::PositionVariance),
            Layer::Visibility => Some(Layer::VisibilityVariance),
            _ => None,
        }
    }

    pub fn from_name(name: &str) -> Option<Layer> {
        Layer::ALL.into_iter().find(|l| l.name() == name)
    }
}

/// The per-pixel statistics of one frame, planar.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StatsImage {
    pub width: usize,
    pub height: usize,
    layers: BTreeMap<Layer, Vec<Vec<f32>>>,
}

impl StatsImage {
    /// An image with no layers.
    pub fn new(width: usize, height: usize) -> Self {
        StatsImage {
            width,
            height,
            layers: BTreeMap::new(),
        }
    }

    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// Sets a layer. Panics if the number of planes or a plane's length is
    /// wrong: that is a programming error, file input is checked in `io`.
    pub fn set(&mut self, layer: Layer, planes: Vec<Vec<f32>>) {
        assert_eq!(planes.len(), layer.channels().len(), "{}", layer.name());
        for p in &planes {
            assert_eq!(p.len(), self.pixel_count(), "{}", layer.name());
        }
        self.layers.insert(layer, planes);
    }

    pub fn remove(&mut self, layer: Layer) -> Option<Vec<Vec<f32>>> {
        self.layers.remove(&layer)
    }

    pub fn get(&self, layer: Layer) -> Option<&[Vec<f32>]> {
        self.layers.get(&layer).map(|v| v.as_slice())
    }

    pub fn get_mut(&mut self, layer: Layer) -> Option<&mut [Vec<f32>]> {
        self.layers.get_mut(&layer).map(|v| v.as_mut_slice())
    }

    pub fn has(&self, layer: Layer) -> bool {
        self.layers.contains_key(&layer)
    }

    /// The layers present, in file order.
    pub fn layers(&self) -> impl Iterator<Item = (Layer, &[Vec<f32>])> {
        self.layers.iter().map(|(l, p)| (*l, p.as_slice()))
    }

    /// A crop `[x0, x0+w) x [y0, y0+h)` of every layer.
    pub fn crop(&self, x0: usize, y0: usize, w: usize, h: usize) -> StatsImage {
        assert!(x0 + w <= self.width && y0 + h <= self.height);
        let mut out = StatsImage::new(w, h);
        for (layer, planes) in self.layers() {
            let cropped = planes
                .iter()
                .map(|p| crop_plane(p, self.width, x0, y0, w, h))
                .collect();
            out.set(layer, cropped);
        }
        out
    }
}

/// A crop of one plane of row length `width`.
pub fn crop_plane(p: &[f32], width: usize, x0: usize, y0: usize, w: usize, h: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(w * h);
    for y in y0..y0 + h {
        out.extend_from_slice(&p[y * width + x0..y * width + x0 + w]);
    }
    out
}

/// An RGB image, planar (the denoiser's colour output, a reference, an error map).
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub planes: [Vec<f32>; 3],
}

impl RgbImage {
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        RgbImage {
            width,
            height,
            planes: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
        }
    }

    pub fn from_planes(width: usize, height: usize, planes: [Vec<f32>; 3]) -> Self {
        for p in &planes {
            assert_eq!(p.len(), width * height);
        }
        RgbImage {
            width,
            height,
            planes,
        }
    }

    pub fn crop(&self, x0: usize, y0: usize, w: usize, h: usize) -> RgbImage {
        RgbImage {
            width: w,
            height: h,
            planes: std::array::from_fn(|c| crop_plane(&self.planes[c], self.width, x0, y0, w, h)),
        }
    }
}
