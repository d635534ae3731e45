//! The built-in path tracer: a small but real Monte Carlo renderer as Vulkan
//! compute, which accumulates exactly what the denoiser reads.
//!
//! It is a client of the library like an outside renderer: it uses the
//! facade types ([`AccumLayout`], [`Batch`], [`BufferSlice`],
//! [`GpuContext`]) and the shared Vulkan plumbing of [`crate::gpu`], never
//! the methods or kernels.
//!
//! ```no_run
//! use std::sync::Arc;
//! use mcdenoise::render::{Renderer, Samples, Scene};
//! use mcdenoise::{Batch, GpuContext};
//! # fn demo(ctx: Arc<GpuContext>) -> mcdenoise::Result<()> {
//! let scene = Scene::builtin("cornell")?;
//! let renderer = Renderer::new(&ctx, &scene, 256, 256, 1)?;
//! let mut batch = Batch::new(&ctx)?;
//! renderer.record_clear(&mut batch);
//! renderer.record_pass(&mut batch, Samples::Uniform(4))?;
//! batch.finish()?;
//! let stats = renderer.statistics()?; // mean and variance per layer
//! # Ok(()) }
//! ```
//!
//! - Geometry: spheres, quads (and boxes of quads), triangle meshes (OBJ or
//!   inline) in a binary BVH built by `obvhs` and traversed in the shader
//!   with a stack of [`STACK_SIZE`](crate::render::gpu_scene::STACK_SIZE) entries.
//! - Materials: diffuse with constant, checker or value-noise albedo; GGX
//!   rough conductor and rough plastic (next-event estimation with MIS);
//!   smooth and rough glass (BSDF sampling only); emitters with constant
//!   or textured radiance: spheres (sampled by the cone they subtend),
//!   quads and two-sided triangles (sampled by area), picked from one light
//!   table in proportion to power by a binary search over its cumulative
//!   probabilities and combined with BSDF sampling by MIS (an emissive
//!   material with `next_event = false` is found by BSDF sampling only); a
//!   uniform environment colour (BSDF sampling).
//! - Camera: thin lens; per-object linear motion over the shutter.
//! - Random numbers are a hash of (pixel, sample index, dimension, seed):
//!   the sample index of a pixel's `k`-th sample is `k`, counted by the
//!   count plane, and each pixel adds its samples to its planes one by one
//!   in sample order, so the same seed gives bit-identical planes for the
//!   same samples per pixel however they are split into passes and bands.
//!
//! What one sample adds (all features at the first hit; a miss adds 0 to
//! every feature and 1 to the count): colour, albedo (emitters: their
//! radiance clamped to 1), the shading normal facing the ray, the distance
//! from the lens point, the position at shutter time 0 (`M⁻¹·s` for moving
//! objects), and visibility — 1 if the next-event shadow ray at the first
//! hit reached its light, else 0 (1 when no emitter is sampled by
//! next-event estimation — no lights, or only `next_event = false` ones —
//! or the first hit is an emitter, a mirror or glass, where no shadow ray
//! is traced).

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};

use crate::error::{Error, Result};
use crate::gpu::reflect::{read, write};
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, KernelDecl, Precision};
use crate::{AccumLayout, StatsImage};

pub mod adaptive;
pub mod gpu_scene;
pub mod reference;
pub mod scene;

pub use gpu_scene::GpuScene;
pub use scene::{Albedo, Camera, Material, Object, Primitive, Scene, Shape, Texture};

/// Push constants of `render_trace` (mirrors its `Push` block).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, Pod, Zeroable)]
pub struct TracePush {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// First row of the band (set by [`Batch::dispatch`]).
    pub row0: u32,
    /// Samples per pixel when `use_map` is 0.
    pub uniform_spp: u32,
    /// 1: samples per pixel from the sample map binding.
    pub use_map: u32,
    /// Low 32 bits of the seed.
    pub seed_lo: u32,
    /// High 32 bits of the seed.
    pub seed_hi: u32,
    /// f32 values between plane starts.
    pub plane_stride: u32,
    /// Non-zero: each sample's 14 values go to the debug binding, this many
    /// samples per pixel apart (a test aid).
    pub debug_stride: u32,
    /// This dispatch traces samples `[chunk·chunk_size, (chunk+1)·chunk_size)`
    /// of each pixel's count.
    pub chunk: u32,
    /// [`RENDER_CHUNK`].
    pub chunk_size: u32,
    /// Padding.
    pub pad: u32,
}

/// Samples per pixel one dispatch traces at most. lavapipe (llvmpipe) ends
/// all loops of an invocation after 65535 iterations in total
/// (`LP_MAX_TGSI_LOOP_ITERATIONS`, shared by every loop of the shader): one
/// invocation tracing 1024 samples of the Cornell box silently kept ~256.
/// A sample of the built-in scenes runs a few hundred loop iterations
/// (BVH traversal of every ray of its path), so 8 stay far below the limit.
pub const RENDER_CHUNK: u32 = 8;

/// Push constants of `render_rays` (mirrors its `Push` block).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, Pod, Zeroable)]
pub struct RaysPush {
    /// Rays per grid row.
    pub width: u32,
    /// Grid rows.
    pub height: u32,
    /// First row of the band.
    pub row0: u32,
    /// Number of rays.
    pub count: u32,
}

const SCENE_BINDINGS: [crate::gpu::BindingDecl; 5] = [
    read("params"),
    read("nodes"),
    read("prims"),
    read("materials"),
    read("lights"),
];

/// The path-tracing kernel (`spirv/render/render_trace.comp`).
pub const TRACE: KernelDecl = KernelDecl {
    name: "render_trace",
    bindings: &[
        SCENE_BINDINGS[0],
        SCENE_BINDINGS[1],
        SCENE_BINDINGS[2],
        SCENE_BINDINGS[3],
        SCENE_BINDINGS[4],
        read("spp_map"),
        write("accum0"),
        write("accum1"),
        write("accum2"),
        write("accum3"),
        write("debug"),
        read("normals"),
    ],
    push_size: std::mem::size_of::<TracePush>() as u32,
};

/// The light-selection kernel (`spirv/render/render_lights.comp`), a test
/// aid: the light table index the path tracer picks for a random number.
pub const LIGHTS: KernelDecl = KernelDecl {
    name: "render_lights",
    bindings: &[
        SCENE_BINDINGS[0],
        SCENE_BINDINGS[1],
        SCENE_BINDINGS[2],
        SCENE_BINDINGS[3],
        SCENE_BINDINGS[4],
        read("us"),
        write("picks"),
    ],
    push_size: std::mem::size_of::<RaysPush>() as u32,
};

/// The ray-list traversal kernel (`spirv/render/render_rays.comp`), a test aid.
pub const RAYS: KernelDecl = KernelDecl {
    name: "render_rays",
    bindings: &[
        SCENE_BINDINGS[0],
        SCENE_BINDINGS[1],
        SCENE_BINDINGS[2],
        SCENE_BINDINGS[3],
        SCENE_BINDINGS[4],
        read("rays"),
        write("hits"),
    ],
    push_size: std::mem::size_of::<RaysPush>() as u32,
};

/// Planes per accumulation binding of `render_trace` (four bindings of
/// eight: no binding exceeds 128 MiB below 4 Mpixels).
const ACCUM_GROUP: u64 = 8;

/// Every kernel of the renderer (for the reflection test).
pub const KERNELS: &[&KernelDecl] = &[&TRACE, &RAYS, &LIGHTS];

/// How many samples a pass adds per pixel.
#[derive(Copy, Clone, Debug)]
pub enum Samples {
    /// The same number in every pixel.
    Uniform(u32),
    /// One u32 per pixel (row-major), e.g. the denoiser's sample map
    /// ([`Outputs::samples`](crate::Outputs)), and the largest count in it
    /// (it sets how many [`RENDER_CHUNK`]-sample dispatches the pass takes;
    /// counts above it are not traced). A pixel with 0 costs nothing.
    Map(BufferSlice, u32),
}

/// A ray for [`Renderer::trace_rays`].
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: [f32; 3],
    /// Direction (any length: hit distances are in its units).
    pub dir: [f32; 3],
    /// Shutter time in `[0, 1)`.
    pub time: f32,
    /// Hits at `t ≤ tmin` are ignored.
    pub tmin: f32,
}

/// The built-in renderer: a scene on the GPU and the accumulation buffer it
/// adds samples to. See the module documentation.
pub struct Renderer {
    ctx: Arc<GpuContext>,
    layout: AccumLayout,
    seed: u64,
    scene: GpuScene,
    params: GpuBuffer,
    nodes: GpuBuffer,
    prims: GpuBuffer,
    materials: GpuBuffer,
    lights: GpuBuffer,
    normals: GpuBuffer,
    accum: GpuBuffer,
    /// Bound where a binding is unused (no map, no debug output).
    dummy: GpuBuffer,
    flops_per_sample: f64,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer")
            .field("layout", &self.layout)
            .field("primitives", &self.scene.primitives.len())
            .field("bvh_depth", &self.scene.depth)
            .finish()
    }
}

/// Estimated floating-point work of one sample: a slab test is ~20
/// operations, a primitive test ~30; a path has a few vertices of two rays.
/// Calibrated on lavapipe so that [`Batch`]'s per-submit budget is about a
/// second of rendering (see the README's renderer table).
fn flops_per_sample(scene: &GpuScene) -> f64 {
    let n = scene.primitives.len().max(1) as f64;
    let rays = 2.0 * (scene.params.counts[2].min(4) as f64) + 1.0;
    let per_ray = 20.0 * (4.0 * n.log2() + 8.0) + 30.0 * 8.0;
    RENDER_FLOPS_SCALE * rays * per_ray
}

/// Scale of [`flops_per_sample`]: on lavapipe (2 cores) the Cornell box
/// takes ~4 µs per sample and the estimate is ~6,500, so a submit of
/// [`crate::gpu::batch::DEFAULT_FLOPS_PER_SUBMIT`] is under a second.
const RENDER_FLOPS_SCALE: f64 = 1.0;

fn buffer_of<T: Pod>(ctx: &Arc<GpuContext>, name: &str, data: &[T]) -> Result<GpuBuffer> {
    if data.is_empty() {
        GpuBuffer::from_slice(ctx, name, &[0u32; 4])
    } else {
        GpuBuffer::from_slice(ctx, name, data)
    }
}

impl Renderer {
    /// Builds the BVH and uploads `scene` for a `width × height` image, and
    /// allocates a zeroed accumulation buffer ([`layout`](Self::layout)).
    /// `seed` selects the random numbers.
    pub fn new(
        ctx: &Arc<GpuContext>,
        scene: &Scene,
        width: usize,
        height: usize,
        seed: u64,
    ) -> Result<Renderer> {
        if width == 0 || height == 0 {
            return Err(Error::InvalidArgument(format!(
                "cannot render an image of {width}x{height} pixels"
            )));
        }
        let gs = GpuScene::new(scene, width, height)?;
        // Positions relative to the lens centre, as render_trace adds them.
        let c = gs.params.cam_pos;
        let layout =
            AccumLayout::new(width, height, true, true).with_position_origin([c[0], c[1], c[2]]);
        let accum = GpuBuffer::new(ctx, "render.accum", layout.bytes())?;
        let r = Renderer {
            ctx: ctx.clone(),
            layout,
            seed,
            params: buffer_of(ctx, "render.params", std::slice::from_ref(&gs.params))?,
            nodes: buffer_of(ctx, "render.nodes", &gs.nodes)?,
            prims: buffer_of(ctx, "render.prims", &gs.prims)?,
            materials: buffer_of(ctx, "render.materials", &gs.materials)?,
            lights: buffer_of(ctx, "render.lights", &gs.lights)?,
            normals: buffer_of(ctx, "render.normals", &gs.normals)?,
            accum,
            dummy: GpuBuffer::from_slice(ctx, "render.dummy", &[0u32; 4])?,
            flops_per_sample: flops_per_sample(&gs),
            scene: gs,
        };
        let mut batch = Batch::new(ctx)?;
        r.record_clear(&mut batch);
        batch.finish()?;
        Ok(r)
    }

    /// The accumulation layout: position and visibility included.
    pub fn layout(&self) -> AccumLayout {
        self.layout
    }

    /// The accumulation buffer, as [`Denoiser::record`](crate::Denoiser::record) reads it.
    pub fn accum(&self) -> BufferSlice {
        self.accum.slice()
    }

    /// The scene tables as uploaded (primitives in BVH order: the primitive
    /// indices [`trace_rays`](Self::trace_rays) returns index this order).
    pub fn gpu_scene(&self) -> &GpuScene {
        &self.scene
    }

    /// Estimated work of one sample, in the units of
    /// [`Batch::max_flops_per_submit`].
    pub fn flops_per_sample(&self) -> f64 {
        self.flops_per_sample
    }

    /// Records zeroing the accumulation buffer (every sum and the count).
    pub fn record_clear(&self, batch: &mut Batch) {
        batch.fill(self.accum.slice(), 0);
    }

    fn scene_bindings(&self) -> [BufferSlice; 5] {
        [
            self.params.slice(),
            self.nodes.slice(),
            self.prims.slice(),
            self.materials.slice(),
            self.lights.slice(),
        ]
    }

    /// Records one pass: every pixel traces its samples and adds them to the
    /// accumulation buffer, in dispatches of at most [`RENDER_CHUNK`]
    /// samples per pixel, each split into row bands by its estimated work
    /// ([`Batch::dispatch`]). A band is at least one workgroup (8 rows)
    /// high; [`record_uniform`](Self::record_uniform) also splits a uniform
    /// render into passes to keep each submit within the batch's budget.
    pub fn record_pass(&self, batch: &mut Batch, samples: Samples) -> Result<()> {
        self.record(batch, samples, None)
    }

    fn record(
        &self,
        batch: &mut Batch,
        samples: Samples,
        debug: Option<(BufferSlice, u32)>,
    ) -> Result<()> {
        let l = self.layout;
        let (uniform_spp, use_map, map, max) = match samples {
            Samples::Uniform(n) => (n, 0, self.dummy.slice(), n),
            Samples::Map(m, max) => {
                if m.size() < l.pixels() as u64 * 4 {
                    return Err(Error::InvalidArgument(format!(
                        "the sample map holds {} bytes; {} pixels need {}",
                        m.size(),
                        l.pixels(),
                        l.pixels() * 4
                    )));
                }
                (0, 1, m, max)
            }
        };
        if max == 0 {
            return Ok(());
        }
        let (dbg, debug_stride) = debug.unwrap_or((self.dummy.slice(), 0));
        let push = TracePush {
            width: l.width as u32,
            height: l.height as u32,
            uniform_spp,
            use_map,
            seed_lo: self.seed as u32,
            seed_hi: (self.seed >> 32) as u32,
            plane_stride: (l.plane_stride() / 4) as u32,
            debug_stride,
            chunk_size: RENDER_CHUNK,
            ..Default::default()
        };
        let [a, b, c, d, e] = self.scene_bindings();
        let group = |g: u64| {
            let stride = l.plane_stride();
            self.accum.range(
                g * ACCUM_GROUP * stride,
                (ACCUM_GROUP - 1) * stride + l.pixels() as u64 * 4,
            )
        };
        let bindings = [
            a,
            b,
            c,
            d,
            e,
            map,
            group(0),
            group(1),
            group(2),
            group(3),
            dbg,
            self.normals.slice(),
        ];
        let chunks = max.div_ceil(RENDER_CHUNK);
        for k in 0..chunks {
            let push = TracePush { chunk: k, ..push };
            // Samples per pixel of this chunk, at most (sizes the bands).
            let expected = (max - k * RENDER_CHUNK).min(RENDER_CHUNK) as f64;
            batch.dispatch(
                &TRACE,
                Precision::F32,
                &bindings,
                bytemuck::bytes_of(&push),
                push.width,
                push.height,
                self.flops_per_sample * expected.max(1e-3),
            )?;
        }
        Ok(())
    }

    /// Records `spp` uniform samples per pixel as several passes, each small
    /// enough that an 8-row band stays within the batch's
    /// [`max_flops_per_submit`](Batch::max_flops_per_submit) (a reference
    /// render). The planes are bit-identical to one pass of `spp`.
    pub fn record_uniform(&self, batch: &mut Batch, spp: u32) -> Result<()> {
        let band = 8.0 * self.layout.width as f64 * self.flops_per_sample;
        let per_pass = ((batch.max_flops_per_submit / band).floor() as u32).clamp(1, spp.max(1));
        let mut left = spp;
        while left > 0 {
            let n = per_pass.min(left);
            self.record_pass(batch, Samples::Uniform(n))?;
            left -= n;
        }
        Ok(())
    }

    /// Renders `spp` samples per pixel and returns each sample's 14 values
    /// (AccumLayout channel order), `[pixel][sample][value]` flattened, while
    /// also adding them to the accumulation buffer. A test aid: it submits
    /// and waits.
    pub fn run_pass_debug(&self, spp: u32) -> Result<Vec<f32>> {
        let n = self.layout.pixels() * spp as usize * 14;
        let out = GpuBuffer::new(&self.ctx, "render.debug_samples", (n * 4) as u64)?;
        let mut batch = Batch::new(&self.ctx)?;
        batch.fill(out.slice(), 0);
        self.record(&mut batch, Samples::Uniform(spp), Some((out.slice(), spp)))?;
        batch.finish()?;
        out.read_vec(n)
    }

    /// Traces `rays` through the BVH and returns, per ray, the nearest hit
    /// as `Some((t, primitive index in BVH order))`. A test aid.
    pub fn trace_rays(&self, rays: &[Ray]) -> Result<Vec<Option<(f32, u32)>>> {
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let data: Vec<[f32; 8]> = rays
            .iter()
            .map(|r| {
                [
                    r.origin[0],
                    r.origin[1],
                    r.origin[2],
                    r.tmin,
                    r.dir[0],
                    r.dir[1],
                    r.dir[2],
                    r.time,
                ]
            })
            .collect();
        let rb = GpuBuffer::from_slice(&self.ctx, "render.rays", &data)?;
        let hb = GpuBuffer::new(&self.ctx, "render.hits", rays.len() as u64 * 8)?;
        let width = 64u32;
        let push = RaysPush {
            width,
            height: (rays.len() as u32).div_ceil(width),
            row0: 0,
            count: rays.len() as u32,
        };
        let [a, b, c, d, e] = self.scene_bindings();
        let mut batch = Batch::new(&self.ctx)?;
        batch.dispatch(
            &RAYS,
            Precision::F32,
            &[a, b, c, d, e, rb.slice(), hb.slice()],
            bytemuck::bytes_of(&push),
            push.width,
            push.height,
            1000.0,
        )?;
        batch.finish()?;
        let hits: Vec<[f32; 2]> = hb.read_vec(rays.len())?;
        Ok(hits
            .iter()
            .map(|h| (h[1] >= 0.0).then(|| (h[0], h[1] as u32)))
            .collect())
    }

    /// The light-table index (see [`GpuScene::lights`]) the path tracer's
    /// light selection picks for each random number of `us` (in `[0, 1)`).
    /// A test aid; empty when the scene has no lights.
    pub fn select_lights(&self, us: &[f32]) -> Result<Vec<u32>> {
        if us.is_empty() || self.scene.lights.is_empty() {
            return Ok(Vec::new());
        }
        let ub = GpuBuffer::from_slice(&self.ctx, "render.us", us)?;
        let pb = GpuBuffer::new(&self.ctx, "render.picks", us.len() as u64 * 4)?;
        let width = 64u32;
        let push = RaysPush {
            width,
            height: (us.len() as u32).div_ceil(width),
            row0: 0,
            count: us.len() as u32,
        };
        let [a, b, c, d, e] = self.scene_bindings();
        let mut batch = Batch::new(&self.ctx)?;
        batch.dispatch(
            &LIGHTS,
            Precision::F32,
            &[a, b, c, d, e, ub.slice(), pb.slice()],
            bytemuck::bytes_of(&push),
            push.width,
            push.height,
            100.0,
        )?;
        batch.finish()?;
        pb.read_vec(us.len())
    }

    /// Downloads the accumulation planes, in layout order (blocking; no
    /// pass may be running).
    pub fn download(&self) -> Result<Vec<Vec<f32>>> {
        let l = self.layout;
        let mut bytes = vec![0u8; l.bytes() as usize];
        self.accum.download(0, &mut bytes)?;
        let stride = l.plane_stride() as usize;
        Ok((0..l.plane_count())
            .map(|i| bytemuck::pod_collect_to_vec(&bytes[i * stride..i * stride + l.pixels() * 4]))
            .collect())
    }

    /// The statistics of what has been accumulated: mean and variance of
    /// the mean per layer, position covariance, spp — finalised on the host
    /// (as a statistics EXR holds them).
    pub fn statistics(&self) -> Result<StatsImage> {
        Ok(self.layout.finalize(&self.download()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Layer;

    /// The plane numbers hard-coded in `render_trace.comp`.
    #[test]
    fn shader_planes_match_the_layout() {
        let l = AccumLayout::new(3, 2, true, true);
        let idx = |layer, c| l.channel_index(layer, c).unwrap();
        assert_eq!(idx(Layer::Color, 0), 0);
        assert_eq!(idx(Layer::Albedo, 0), 3);
        assert_eq!(idx(Layer::Normal, 0), 6);
        assert_eq!(idx(Layer::Depth, 0), 9);
        assert_eq!(idx(Layer::Position, 0), 10);
        assert_eq!(idx(Layer::Visibility, 0), 13);
        assert_eq!(l.sum_plane(13), 26);
        assert_eq!(l.sumsq_plane(13), 27);
        assert_eq!(l.cross_plane(0), Some(28));
        assert_eq!(l.count_plane(), 31);
        assert_eq!(l.plane_count(), 32);
        assert_eq!(l.plane_count() as u64, 4 * ACCUM_GROUP);
    }

    #[test]
    fn push_blocks_have_the_shader_sizes() {
        assert_eq!(std::mem::size_of::<TracePush>(), 48);
        assert_eq!(std::mem::size_of::<RaysPush>(), 16);
        assert_eq!(std::mem::size_of::<gpu_scene::GpuParams>(), 128);
    }

    /// A 200k-triangle mesh (a bumpy 317² grid) fits the shader's stack.
    #[test]
    fn a_large_mesh_fits_the_traversal_stack() {
        let n = 317u32;
        let mut vertices = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
                vertices.push([x, 0.05 * (20.0 * x).sin() * (17.0 * z).cos(), z]);
            }
        }
        let mut indices = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let v = j * (n + 1) + i;
                indices.push([v, v + 1, v + n + 2]);
                indices.push([v, v + n + 2, v + n + 1]);
            }
        }
        let mut s = Scene::builtin("cornell").unwrap();
        s.objects.push(Object::Mesh {
            file: None,
            vertices,
            indices,
            normals: Vec::new(),
            scale: 1.0,
            translate: [0.0; 3],
            material: "white".into(),
            motion: None,
        });
        let g = GpuScene::new(&s, 8, 8).unwrap();
        eprintln!("{} primitives, BVH depth {}", g.primitives.len(), g.depth);
        assert!(g.primitives.len() > 200_000 && g.depth <= gpu_scene::STACK_SIZE);
    }

    #[test]
    fn every_builtin_scene_parses_and_builds() {
        for name in Scene::builtin_names() {
            let s = Scene::builtin(name).unwrap();
            let g = GpuScene::new(&s, 16, 16).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(!g.primitives.is_empty(), "{name}");
        }
    }
}
