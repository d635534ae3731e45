//! Planar per-pixel statistics: the in-memory form of a render-statistics EXR
//! (`docs/input-format.md`) and of the GPU planes.
//!
//! Every scalar channel is one plane of `width * height` f32 values in row-major
//! order (pixel `(x, y)` at index `y * width + x`). A [`StatsImage`] holds the
//! planes of each [`Layer`] that is present.

use std::collections::BTreeMap;

/// One layer of the render-statistics format. The order of the variants is the
/// order layers are listed in (inspect output, EXR channel order).
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Layer {
    /// `color.R G B`: mean linear radiance of the pixel's samples.
    Color,
    /// `color_variance.R G B`: variance of that mean (sample variance / spp).
    ColorVariance,
    /// `albedo.R G B`: mean first-hit texture albedo.
    Albedo,
    /// `albedo_variance.R G B`: variance of the albedo mean.
    AlbedoVariance,
    /// `normal.X Y Z`: mean first-hit shading normal, world space.
    Normal,
    /// `normal_variance.X Y Z`: variance of the normal mean.
    NormalVariance,
    /// `depth.Z`: mean first-hit distance from the camera (scene units).
    Depth,
    /// `depth_variance.Z`: variance of the depth mean.
    DepthVariance,
    /// `position.X Y Z`: mean first-hit world position (G-buffer prefilter, spec §6).
    Position,
    /// `position_variance.X Y Z`: variance of the position mean, per axis.
    PositionVariance,
    /// `position_covariance.XX XY XZ YY YZ ZZ`: covariance of the position
    /// *samples* divided by spp (`S_i`, spec §0.1).
    PositionCovariance,
    /// `visibility.Y`: mean direct-light visibility, in 0..1 (optional).
    Visibility,
    /// `visibility_variance.Y`: variance of the visibility mean.
    VisibilityVariance,
    /// `spp.Y`: samples in the pixel (`n_i`; a pixel is valid when `>= 1`, spec §0.2).
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

    /// Full EXR channel names of the layer (`layer.channel`), in order.
    pub fn channel_names(self) -> Vec<String> {
        self.channels()
            .iter()
            .map(|c| format!("{}.{c}", self.name()))
            .collect()
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

    /// Whether an input file must carry this layer: colour, albedo, normal,
    /// depth and spp are required, their variances are estimated if missing,
    /// the rest is optional.
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

    /// The layer of an EXR layer name ([`Layer::name`]), or `None`.
    pub fn from_name(name: &str) -> Option<Layer> {
        Layer::ALL.into_iter().find(|l| l.name() == name)
    }
}

/// The per-pixel statistics of one frame, planar.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StatsImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
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

    /// Pixels per plane: `width * height`.
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

    /// Takes a layer out of the image, returning its planes if it was present.
    pub fn remove(&mut self, layer: Layer) -> Option<Vec<Vec<f32>>> {
        self.layers.remove(&layer)
    }

    /// The planes of a layer (one per [`Layer::channels`] entry), if present.
    pub fn get(&self, layer: Layer) -> Option<&[Vec<f32>]> {
        self.layers.get(&layer).map(|v| v.as_slice())
    }

    /// The planes of a layer, mutably, if present.
    pub fn get_mut(&mut self, layer: Layer) -> Option<&mut [Vec<f32>]> {
        self.layers.get_mut(&layer).map(|v| v.as_mut_slice())
    }

    /// Whether the layer is present.
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
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The R, G, B planes, `width * height` f32 values each, row-major.
    pub planes: [Vec<f32>; 3],
}

impl RgbImage {
    /// A black (all-zero) image of `width × height` pixels.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        RgbImage {
            width,
            height,
            planes: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
        }
    }

    /// Wraps three planes; panics if a plane's length is not `width * height`.
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

    /// The R, G, B planes as slices, as the twins take them.
    pub fn plane_slices(&self) -> [&[f32]; 3] {
        [&self.planes[0], &self.planes[1], &self.planes[2]]
    }

    /// A crop `[x0, x0+w) x [y0, y0+h)`, which must lie inside the image.
    pub fn crop(&self, x0: usize, y0: usize, w: usize, h: usize) -> RgbImage {
        RgbImage {
            width: w,
            height: h,
            planes: std::array::from_fn(|c| crop_plane(&self.planes[c], self.width, x0, y0, w, h)),
        }
    }
}
