//! Per-pixel statistics on the GPU ([`GpuStats`]) and the finalize pass that
//! turns a renderer's accumulation buffer into them.

use std::sync::Arc;

use crate::accum::AccumLayout;
use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, StatsImage};
use crate::kernels::{finalize_covariance, finalize_stats};
use crate::shared::FinalizePush;

/// A [`StatsImage`] resident on the GPU: one plane per scalar channel of each
/// present layer, in [`Layer::ALL`] order, packed in one [`PlaneSet`].
#[derive(Debug)]
pub struct GpuStats {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The planes, `width * height` f32 each; see [`GpuStats::index`].
    pub planes: PlaneSet,
    /// `(layer, index of its first plane)` for each present layer.
    pub index: Vec<(Layer, usize)>,
}

impl GpuStats {
    /// Allocates planes for `layers` (contents undefined).
    pub fn new(
        ctx: &Arc<GpuContext>,
        name: &str,
        width: usize,
        height: usize,
        layers: &[Layer],
    ) -> Result<GpuStats> {
        let mut layers = layers.to_vec();
        layers.sort();
        layers.dedup();
        let mut index = Vec::new();
        let mut n = 0;
        for l in layers {
            index.push((l, n));
            n += l.channels().len();
        }
        Ok(GpuStats {
            width,
            height,
            planes: PlaneSet::new(ctx, name, width * height, n)?,
            index,
        })
    }

    /// Uploads every layer of `img`.
    pub fn upload(ctx: &Arc<GpuContext>, name: &str, img: &StatsImage) -> Result<GpuStats> {
        let layers: Vec<Layer> = img.layers().map(|(l, _)| l).collect();
        let g = GpuStats::new(ctx, name, img.width, img.height, &layers)?;
        g.upload_image(img)?;
        Ok(g)
    }

    /// Uploads every layer of `img` into its planes (`img` may lack layers
    /// these statistics have, as sanitation's estimated variances; every
    /// layer of `img` must be present here).
    pub fn upload_image(&self, img: &StatsImage) -> Result<()> {
        if (img.width, img.height) != (self.width, self.height) {
            return Err(Error::InvalidArgument(format!(
                "{}: a {}x{} image into {}x{} planes",
                self.planes.name(),
                img.width,
                img.height,
                self.width,
                self.height
            )));
        }
        let mut planes: Vec<(usize, &[f32])> = Vec::new();
        for (l, p) in img.layers() {
            let first = self.first_plane(l).ok_or_else(|| {
                Error::InvalidArgument(format!("{}: no {} layer", self.planes.name(), l.name()))
            })?;
            planes.extend(p.iter().enumerate().map(|(c, v)| (first + c, v.as_slice())));
        }
        self.planes.upload_some(&planes)
    }

    /// Downloads every layer.
    pub fn download(&self) -> Result<StatsImage> {
        let all = self.planes.download_all()?;
        let mut img = StatsImage::new(self.width, self.height);
        for &(l, first) in &self.index {
            img.set(l, all[first..first + l.channels().len()].to_vec());
        }
        Ok(img)
    }

    /// Downloads `layers` (each must be present) into an image holding only
    /// them.
    pub fn download_layers(&self, layers: &[Layer]) -> Result<StatsImage> {
        let mut img = StatsImage::new(self.width, self.height);
        for &l in layers {
            let first = self.first_plane(l).ok_or_else(|| {
                Error::InvalidArgument(format!("{}: no {} layer", self.planes.name(), l.name()))
            })?;
            let planes = (first..first + l.channels().len())
                .map(|i| self.planes.download_plane::<f32>(i))
                .collect::<Result<Vec<_>>>()?;
            img.set(l, planes);
        }
        Ok(img)
    }

    /// The index of `layer`'s first plane, if present.
    fn first_plane(&self, layer: Layer) -> Option<usize> {
        self.index
            .iter()
            .find(|(l, _)| *l == layer)
            .map(|&(_, f)| f)
    }

    /// Whether `layer` is present.
    pub fn has(&self, layer: Layer) -> bool {
        self.index.iter().any(|(l, _)| *l == layer)
    }

    /// Plane `component` of `layer` as a binding. Panics if absent.
    pub fn plane(&self, layer: Layer, component: usize) -> BufferSlice {
        self.planes.plane(self.plane_index(layer, component))
    }

    /// [`plane`](Self::plane) as a binding of whole vec4s
    /// ([`PlaneSet::plane_quads`]).
    pub fn plane_quads(&self, layer: Layer, component: usize) -> BufferSlice {
        self.planes.plane_quads(self.plane_index(layer, component))
    }

    /// The index in [`planes`](Self::planes) of plane `component` of
    /// `layer`. Panics if absent.
    fn plane_index(&self, layer: Layer, component: usize) -> usize {
        let first = self
            .first_plane(layer)
            .unwrap_or_else(|| panic!("layer {} not on the GPU", layer.name()));
        assert!(component < layer.channels().len());
        first + component
    }
}

/// The layers a finalize of `layout` produces.
pub fn finalized_layers(layout: &AccumLayout) -> Vec<Layer> {
    let mut out = vec![];
    for l in layout.layers() {
        out.push(l);
        out.push(l.variance().unwrap());
    }
    if layout.position {
        out.push(Layer::PositionCovariance);
    }
    out.push(Layer::Spp);
    out
}

/// Records the finalize of a renderer's accumulation buffer (`accum`, laid out
/// as [`AccumLayout`] says) into `out`, which must hold [`finalized_layers`].
/// `spp` is copied from the count plane through the finalize of the count
/// itself (mean of a plane of ones would be 1; the count is passed as is).
pub fn record_finalize(
    batch: &mut Batch,
    precision: Precision,
    layout: &AccumLayout,
    accum: BufferSlice,
    out: &GpuStats,
) -> Result<()> {
    if accum.size() < layout.bytes() {
        return Err(Error::InvalidArgument(format!(
            "the accumulation buffer range holds {} bytes; a {}x{} layout with {} planes needs {}",
            accum.size(),
            layout.width,
            layout.height,
            layout.plane_count(),
            layout.bytes()
        )));
    }
    if (out.width, out.height) != (layout.width, layout.height) {
        return Err(Error::InvalidArgument(format!(
            "statistics of {}x{} cannot hold a {}x{} accumulation",
            out.width, out.height, layout.width, layout.height
        )));
    }
    for l in finalized_layers(layout) {
        if !out.has(l) {
            return Err(Error::InvalidArgument(format!(
                "the statistics planes lack the {} layer",
                l.name()
            )));
        }
    }
    let stride = layout.plane_stride();
    let plane_bytes = (layout.pixels() as u64 * 4).max(4);
    let plane = |i: usize| accum.sub(i as u64 * stride, plane_bytes);
    let (w, h) = (layout.width as u32, layout.height as u32);
    let count = plane(layout.count_plane())?;
    for (c, ch) in layout.channels().iter().enumerate() {
        finalize_stats::record(
            batch,
            precision,
            w,
            h,
            plane(layout.sum_plane(c))?,
            plane(layout.sumsq_plane(c))?,
            count,
            out.plane(ch.layer, ch.component),
            out.plane(ch.layer.variance().unwrap(), ch.component),
            layout.origin_of(ch.layer, ch.component),
        )?;
    }
    if layout.position {
        let p0 = layout.channel_index(Layer::Position, 0).unwrap();
        let three = |f: &dyn Fn(usize) -> usize| -> Result<[BufferSlice; 3]> {
            Ok([plane(f(0))?, plane(f(1))?, plane(f(2))?])
        };
        let sums = three(&|a| layout.sum_plane(p0 + a))?;
        let sumsqs = three(&|a| layout.sumsq_plane(p0 + a))?;
        let cross = three(&|k| layout.cross_plane(k).unwrap())?;
        let cov = std::array::from_fn(|k| out.plane(Layer::PositionCovariance, k));
        finalize_covariance::record(batch, precision, w, h, sums, sumsqs, cross, count, cov)?;
    }
    batch.copy(count, out.plane(Layer::Spp, 0));
    Ok(())
}

/// [`record_finalize`] of `accum` into new planes at `precision`, run and
/// downloaded: the statistics exactly as a denoiser reading the
/// accumulation buffer at that precision finalises them (blocking).
pub fn finalize_gpu(
    ctx: &Arc<GpuContext>,
    precision: Precision,
    layout: &AccumLayout,
    accum: BufferSlice,
) -> Result<StatsImage> {
    let out = GpuStats::new(
        ctx,
        "finalized",
        layout.width,
        layout.height,
        &finalized_layers(layout),
    )?;
    let mut batch = Batch::new(ctx)?;
    record_finalize(&mut batch, precision, layout, accum, &out)?;
    batch.finish()?;
    out.download()
}

/// The same on the CPU with the scalar twins: `planes` in layout order.
pub fn finalize_cpu(layout: &AccumLayout, planes: &[Vec<f32>]) -> StatsImage {
    use crate::reference::{
        finalize_covariance::finalize_covariance, finalize_stats::finalize_stats,
    };
    let n = layout.pixels();
    let push = FinalizePush {
        width: layout.width as u32,
        height: layout.height as u32,
        ..Default::default()
    };
    let count = &planes[layout.count_plane()];
    let mut img = StatsImage::new(layout.width, layout.height);
    for layer in layout.layers() {
        let k = layer.channels().len();
        let mut means = vec![vec![0.0f32; n]; k];
        let mut vars = vec![vec![0.0f32; n]; k];
        for comp in 0..k {
            let c = layout.channel_index(layer, comp).unwrap();
            let push = FinalizePush {
                origin: layout.origin_of(layer, comp),
                ..push
            };
            finalize_stats(
                &push,
                &planes[layout.sum_plane(c)],
                &planes[layout.sumsq_plane(c)],
                count,
                &mut means[comp],
                &mut vars[comp],
            );
        }
        img.set(layer, means);
        img.set(layer.variance().unwrap(), vars);
    }
    if layout.position {
        let p0 = layout.channel_index(Layer::Position, 0).unwrap();
        let mut cov: [Vec<f32>; 6] = std::array::from_fn(|_| vec![0.0; n]);
        finalize_covariance(
            &push,
            std::array::from_fn(|a| planes[layout.sum_plane(p0 + a)].as_slice()),
            std::array::from_fn(|a| planes[layout.sumsq_plane(p0 + a)].as_slice()),
            std::array::from_fn(|k| planes[layout.cross_plane(k).unwrap()].as_slice()),
            count,
            &mut cov,
        );
        img.set(Layer::PositionCovariance, cov.to_vec());
    }
    img.set(Layer::Spp, vec![count.clone()]);
    img
}
