//! The accumulation layout: what a renderer sums per pixel, as the library's
//! GPU entry point takes it (`docs/input-format.md`, last paragraph).
//!
//! One buffer of planes, each plane `width * height` f32 values in row-major
//! order, starting at a multiple of [`PLANE_ALIGN`](crate::gpu::PLANE_ALIGN)
//! (256) bytes: plane `i` starts at byte `i * plane_stride(width * height)`.
//! Every plane can therefore be bound on its own and no binding grows with the
//! number of channels. Plane order:
//!
//! | planes | content |
//! |---|---|
//! | for each scalar channel `c` of [`AccumLayout::channels`] | `Σ x_c` then `Σ x_c²` (2 planes) |
//! | if `position`: 3 | `Σ x·y`, `Σ x·z`, `Σ y·z` of the position samples |
//! | 1 | sample count `n` (f32) |
//!
//! The scalar channels are colour R G B, albedo R G B, normal X Y Z, depth,
//! then position X Y Z (optional) and visibility (optional). A miss adds 0 to
//! every feature sum but counts as a sample (spec `input-format.md`).

use crate::gpu::plane_stride;
use crate::image::Layer;

/// Which optional buffers the renderer accumulates.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct AccumLayout {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// The renderer accumulates world positions: adds the position channels
    /// X Y Z and the three cross-product planes (needed by the G-buffer
    /// prefilter, spec §6, for the covariance `S`).
    pub position: bool,
    /// The renderer accumulates direct-light visibility: adds one channel.
    pub visibility: bool,
    /// The position samples are accumulated relative to this point: the
    /// renderer adds `p − origin` (and its squares and cross products), and
    /// finalisation adds `origin` back to the mean. Choose a point near the
    /// visible geometry (the built-in renderer uses the camera): f32 sums of
    /// raw world positions far from 0 lose the position variance and
    /// covariance the G-buffer prefilter reads (at |p| ≈ 1000 and 64 spp the
    /// rounding of Σp² is larger than the variance of a pixel's footprint).
    /// A miss's position is 0 as without an origin (`−origin` relative to it).
    /// Default 0. A denoiser finalises every call with the origin of the
    /// layout it was made with: keep one origin for all the frames a
    /// temporal denoiser filters (the built-in renderer uses the lens
    /// centre of the scene's frame 0 for a whole sequence), or their
    /// positions, and so the reprojection, move with it.
    pub position_origin: [f32; 3],
}

// Equality is total: the origin is finite (checked where it is set).
impl Eq for AccumLayout {}

/// A scalar channel of the accumulation: layer and component.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct AccumChannel {
    /// The layer the channel belongs to (mean layers only: never a variance).
    pub layer: Layer,
    /// Component within the layer: 0, 1, 2 for R G B or X Y Z; 0 for depth and
    /// visibility.
    pub component: usize,
}

impl AccumLayout {
    /// A layout for a `width × height` image (pixels) with the optional
    /// position and visibility channels.
    pub fn new(width: usize, height: usize, position: bool, visibility: bool) -> Self {
        AccumLayout {
            width,
            height,
            position,
            visibility,
            position_origin: [0.0; 3],
        }
    }

    /// The same layout with positions accumulated relative to `origin`
    /// ([`AccumLayout::position_origin`]). Panics if `origin` is not finite.
    pub fn with_position_origin(mut self, origin: [f32; 3]) -> Self {
        assert!(
            origin.iter().all(|v| v.is_finite()),
            "position origin {origin:?} is not finite"
        );
        self.position_origin = origin;
        self
    }

    /// What component `component` of `layer` is accumulated relative to:
    /// the position origin for positions, 0 otherwise.
    pub fn origin_of(&self, layer: Layer, component: usize) -> f32 {
        if layer == Layer::Position {
            self.position_origin[component]
        } else {
            0.0
        }
    }

    /// Pixels per plane: `width * height`.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// The mean layers accumulated, in order.
    pub fn layers(&self) -> Vec<Layer> {
        let mut l = vec![Layer::Color, Layer::Albedo, Layer::Normal, Layer::Depth];
        if self.position {
            l.push(Layer::Position);
        }
        if self.visibility {
            l.push(Layer::Visibility);
        }
        l
    }

    /// The scalar channels, in plane order.
    pub fn channels(&self) -> Vec<AccumChannel> {
        self.layers()
            .into_iter()
            .flat_map(|layer| {
                (0..layer.channels().len()).map(move |component| AccumChannel { layer, component })
            })
            .collect()
    }

    /// Plane index of `Σ x` of channel number `c` (in [`channels`](Self::channels) order).
    pub fn sum_plane(&self, c: usize) -> usize {
        2 * c
    }

    /// Plane index of `Σ x²` of channel number `c`.
    pub fn sumsq_plane(&self, c: usize) -> usize {
        2 * c + 1
    }

    /// Plane index of the position cross products `Σxy, Σxz, Σyz` (k = 0, 1, 2).
    pub fn cross_plane(&self, k: usize) -> Option<usize> {
        assert!(k < 3);
        self.position.then(|| 2 * self.channels().len() + k)
    }

    /// Plane index of the sample count.
    pub fn count_plane(&self) -> usize {
        2 * self.channels().len() + if self.position { 3 } else { 0 }
    }

    /// Number of planes: two per scalar channel, three position cross products
    /// if `position`, and the sample count.
    pub fn plane_count(&self) -> usize {
        self.count_plane() + 1
    }

    /// Bytes between plane starts.
    pub fn plane_stride(&self) -> u64 {
        plane_stride(self.pixels())
    }

    /// Size of the whole accumulation buffer in bytes.
    pub fn bytes(&self) -> u64 {
        self.plane_stride() * self.plane_count() as u64
    }

    /// Index of a channel by layer and component.
    pub fn channel_index(&self, layer: Layer, component: usize) -> Option<usize> {
        self.channels()
            .iter()
            .position(|c| c.layer == layer && c.component == component)
    }

    /// Finalises accumulation planes (`planes` in layout order, as
    /// downloaded) on the host: mean and variance of the mean per layer, the
    /// position covariance and `spp`, as a statistics file holds them. The
    /// same formulas as the GPU finalisation (spec §0.2).
    pub fn finalize(&self, planes: &[Vec<f32>]) -> crate::image::StatsImage {
        crate::methods::stats::finalize_cpu(self, planes)
    }

    /// Finalises an accumulation buffer on the GPU at `precision` (the
    /// kernels a denoiser reading `accum` runs) and downloads the result:
    /// the statistics bit for bit as that denoiser sees them, so that
    /// denoising them as a file reproduces its output. Blocking.
    pub fn finalize_gpu(
        &self,
        ctx: &std::sync::Arc<crate::gpu::GpuContext>,
        accum: crate::gpu::BufferSlice,
        precision: crate::gpu::Precision,
    ) -> crate::error::Result<crate::image::StatsImage> {
        crate::methods::stats::finalize_gpu(ctx, precision, self, accum)
    }
}

/// CPU-side accumulation, as a renderer would do it: sums in f64, stored f32.
/// Used by tests and by the built-in scene generator.
#[derive(Clone, Debug)]
pub struct Accumulator {
    /// The planes accumulated and their order.
    pub layout: AccumLayout,
    sums: Vec<Vec<f64>>,
}

impl Accumulator {
    /// An all-zero accumulation (no samples yet) of `layout`; holds
    /// [`AccumLayout::plane_count`] f64 planes of [`AccumLayout::pixels`] values.
    pub fn new(layout: AccumLayout) -> Self {
        Accumulator {
            layout,
            sums: vec![vec![0.0; layout.pixels()]; layout.plane_count()],
        }
    }

    /// Adds one sample to pixel `p`. `values` holds one value per scalar
    /// channel in [`AccumLayout::channels`] order; positions are stored
    /// relative to [`AccumLayout::position_origin`].
    pub fn add(&mut self, p: usize, values: &[f64]) {
        let l = self.layout;
        let channels = l.channels();
        assert_eq!(values.len(), channels.len());
        // Positions relative to the origin.
        let shifted =
            |c: usize| values[c] - l.origin_of(channels[c].layer, channels[c].component) as f64;
        for c in 0..channels.len() {
            let v = shifted(c);
            self.sums[l.sum_plane(c)][p] += v;
            self.sums[l.sumsq_plane(c)][p] += v * v;
        }
        if l.position {
            let px = l.channel_index(Layer::Position, 0).unwrap();
            let (x, y, z) = (shifted(px), shifted(px + 1), shifted(px + 2));
            for (k, v) in [x * y, x * z, y * z].into_iter().enumerate() {
                self.sums[l.cross_plane(k).unwrap()][p] += v;
            }
        }
        self.sums[l.count_plane()][p] += 1.0;
    }

    /// The planes as f32, in layout order.
    pub fn planes(&self) -> Vec<Vec<f32>> {
        self.sums
            .iter()
            .map(|p| p.iter().map(|&v| v as f32).collect())
            .collect()
    }
}
