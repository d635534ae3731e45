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
//!   same samples per pixel however they are split into passes, windows
//!   and bands.
//! - Work (RENDER-ITEMS): one invocation per sample, not per pixel. A pass
//!   numbers its samples (`render_scan`: an exclusive prefix sum of its
//!   per-pixel counts), traces windows of them (`render_trace`, each
//!   sample's values to a scratch buffer) and adds each window to the
//!   planes (`render_resolve`: one invocation per pixel's run of samples,
//!   in sample order; gather, no atomics). So a pass costs what its
//!   samples cost, however crowded: a sample map that puts thousands of
//!   samples in a few pixels traces them at the rate a uniform pass traces
//!   those pixels (SIMD lanes are samples, not pixels).
//!
//! What one sample adds (features at the first hit, but albedo and normal
//! behind a smooth mirror, RENDER-FEATURES; a miss adds 0 to every feature
//! and 1 to the count): colour, albedo (emitters: `L/(1+L)` per channel of
//! their radiance), the shading normal facing the ray, the distance
//! from the lens point, the position at shutter time 0 (`M⁻¹·s` for moving
//! objects) in the object's placement as the scene file writes it (a
//! keyframed object's point keeps its position from frame to frame, spec
//! §10.1's `W`), and visibility — 1 if the next-event shadow ray at the first
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
pub mod sequence;

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
    /// First grid row of the band (set by [`Batch::dispatch`]); a grid row
    /// is [`GRID_WIDTH`] items.
    pub row0: u32,
    /// The window's first item (of the pass).
    pub item0: u32,
    /// Items in the window.
    pub items: u32,
    /// Low 32 bits of the seed.
    pub seed_lo: u32,
    /// High 32 bits of the seed.
    pub seed_hi: u32,
    /// Samples per pixel of a uniform pass (the pixel of item `i` is
    /// `i / uniform_spp`); 0: a map pass (binary search in the prefix sums).
    pub uniform_spp: u32,
}

/// Push constants of `render_scan` (mirrors its `Push` block).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, Pod, Zeroable)]
pub struct ScanPush {
    /// Pixels of the image.
    pub pixels: u32,
    /// Blocks of [`SCAN_BLOCK`] pixels (the last one may be partial).
    pub blocks: u32,
    /// First grid row of the band (set by [`Batch::dispatch`]).
    pub row0: u32,
    /// 0: block sums; 1: their exclusive prefix (one workgroup); 2: the
    /// per-pixel entries.
    pub phase: u32,
    /// [`SCAN_BLOCK`].
    pub block: u32,
    /// Samples per pixel when `use_map` is 0.
    pub uniform_spp: u32,
    /// 1: samples per pixel from the sample map binding.
    pub use_map: u32,
    /// Padding.
    pub pad: u32,
}

/// Push constants of `render_resolve` (mirrors its `Push` block).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, Pod, Zeroable)]
pub struct ResolvePush {
    /// First item to resolve (an index into the window's items).
    pub begin: u32,
    /// One past the last (`end - begin` ≤ [`RESOLVE_CHUNK`]).
    pub end: u32,
    /// First grid row of the band (set by [`Batch::dispatch`]).
    pub row0: u32,
    /// f32 values between plane starts.
    pub plane_stride: u32,
    /// The layout's position origin (the lens centre) in xyz; w unused.
    pub origin: [f32; 4],
    /// The window's first item (of the pass).
    pub item0: u32,
    /// Pixels of the image.
    pub pixels: u32,
    /// [`RESOLVE_LANES`]: invocation `k` takes the resolve's pixels
    /// `first + k`, `first + k + lanes`, …
    pub lanes: u32,
    /// Padding.
    pub pad: u32,
}

/// Items (samples) one grid row of `render_trace` and `render_resolve`
/// holds: the grid is `GRID_WIDTH × rows`, so [`Batch::dispatch`] splits a
/// window into bands of whole rows. The kernels read the row width from
/// their dispatch (`gl_NumWorkGroups.x · gl_WorkGroupSize.x`).
pub const GRID_WIDTH: u32 = 64;

/// Most items one `render_trace` dispatch sequence traces before their
/// values are resolved (a window): the items buffer holds 64 bytes per
/// item, so 2^18 items take 16 MiB. A window costs one barrier and the
/// tail of its last band; at ~3 µs per sample on lavapipe it is ~0.8 s of
/// tracing, so that cost is far below 1 %.
pub const ITEM_WINDOW: u32 = 1 << 18;

/// Most items one `render_resolve` dispatch covers. lavapipe (llvmpipe)
/// ends all loops of an invocation after 65535 iterations in total
/// (`LP_MAX_TGSI_LOOP_ITERATIONS`, shared by every loop of the shader): one
/// invocation once tracing 1024 samples of the Cornell box silently kept
/// ~256. An invocation of the resolve adds its pixels' runs of items, so a
/// pixel with very many samples is resolved in chunks of at most this
/// many, one dispatch after the other; with the pixel loop
/// (≤ pixels / [`RESOLVE_LANES`] + 1) an invocation stays below 37,000
/// iterations up to 16 Mpixels.
pub const RESOLVE_CHUNK: u32 = 1 << 15;

/// Invocations of one `render_resolve` dispatch: enough that a pass of one
/// sample per pixel gives each a few neighbouring pixels (8 in a chunk of
/// [`RESOLVE_CHUNK`]), few enough that the many invocations without a pixel
/// cost little (its grid is 64 workgroups; one per item was ~10 % of a
/// 16-spp pass's GPU time on lavapipe).
pub const RESOLVE_LANES: u32 = 4096;

/// Pixels per block of `render_scan`: an invocation of its phases 0 and 2
/// loops over one block; phase 1 loops over `blocks / 64` block sums, 256 at
/// 4 Mpixels.
pub const SCAN_BLOCK: u32 = 256;

/// Bytes of one item: four uvec4 (the 14 values, the pixel, the sample index).
const ITEM_BYTES: u64 = 64;

/// Estimated operations of `render_resolve` per item (the accumulation of
/// 14 values, 31 sums) and of `render_scan` per pixel and phase.
const RESOLVE_FLOPS: f64 = 60.0;
const SCAN_FLOPS: f64 = 4.0;

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

// The renderer's bindings are its own buffers, sized from the scene and
// the image when the `Renderer` is made, never a caller's: they are
// declared `sized_by_record` and not checked again per dispatch.
const SCENE_BINDINGS: [crate::gpu::BindingDecl; 5] = [
    read("params").sized_by_record(),
    read("nodes").sized_by_record(),
    read("prims").sized_by_record(),
    read("materials").sized_by_record(),
    read("lights").sized_by_record(),
];

/// The path-tracing kernel (`spirv/render/render_trace.comp`): one
/// invocation per item (sample) of a window.
pub const TRACE: KernelDecl = KernelDecl {
    name: "render_trace",
    bindings: &[
        SCENE_BINDINGS[0],
        SCENE_BINDINGS[1],
        SCENE_BINDINGS[2],
        SCENE_BINDINGS[3],
        SCENE_BINDINGS[4],
        read("scan").sized_by_record(),
        write("items").sized_by_record(),
        read("normals").sized_by_record(),
        write("work").sized_by_record(),
        read("rest").sized_by_record(),
    ],
    push_size: std::mem::size_of::<TracePush>() as u32,
};

/// Features from samples of their own (`spirv/render/render_features.comp`,
/// [`FeatureSamples::Independent`]): one invocation per traced item of a
/// window, after [`TRACE`].
/// It takes [`TRACE`]'s bindings (it does not read `scan`).
pub const FEATURES: KernelDecl = KernelDecl {
    name: "render_features",
    bindings: TRACE.bindings,
    push_size: std::mem::size_of::<TracePush>() as u32,
};

/// The items of a pass (`spirv/render/render_scan.comp`): the exclusive
/// prefix sum of its per-pixel counts and each pixel's count at its start.
pub const SCAN: KernelDecl = KernelDecl {
    name: "render_scan",
    bindings: &[
        read("spp_map").sized_by_record(),
        read("count").sized_by_record(),
        write("scan").sized_by_record(),
        write("blocks").sized_by_record(),
    ],
    push_size: std::mem::size_of::<ScanPush>() as u32,
};

/// Adds traced items to the accumulation planes
/// (`spirv/render/render_resolve.comp`), each pixel's in sample order.
pub const RESOLVE: KernelDecl = KernelDecl {
    name: "render_resolve",
    bindings: &[
        read("items").sized_by_record(),
        read("scan").sized_by_record(),
        write("accum0").sized_by_record(),
        write("accum1").sized_by_record(),
        write("accum2").sized_by_record(),
        write("accum3").sized_by_record(),
    ],
    push_size: std::mem::size_of::<ResolvePush>() as u32,
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
        read("us").sized_by_record(),
        write("picks").sized_by_record(),
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
        read("rays").sized_by_record(),
        write("hits").sized_by_record(),
    ],
    push_size: std::mem::size_of::<RaysPush>() as u32,
};

/// Planes per accumulation binding of `render_resolve` (four bindings of
/// eight: no binding exceeds 128 MiB below 4 Mpixels).
const ACCUM_GROUP: u64 = 8;

/// Every kernel of the renderer (for the reflection test).
pub const KERNELS: &[&KernelDecl] = &[&TRACE, &FEATURES, &RAYS, &LIGHTS, &SCAN, &RESOLVE];

/// Which samples a renderer's feature planes (albedo, normal, depth,
/// position, visibility) average (RENDER-FEATURE-SAMPLES).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum FeatureSamples {
    /// The colour's own samples: a sample's features are those of its
    /// camera path. Where a pixel's coverage is random (edges under motion
    /// blur, lens blur, sub-pixel geometry) the features then carry the
    /// colour's noise, and a regression on them keeps it
    /// (FEATURE-SHARED-NOISE).
    #[default]
    Shared,
    /// Every sample's features from a camera path of its own, with
    /// independent pixel position, lens point, shutter time and light
    /// sample: as many feature samples as colour samples, whose noise is
    /// not the colour's. Costs a camera ray and a shadow ray per sample
    /// (`render_features`); the colour planes are those of
    /// [`Shared`](Self::Shared), bit for bit.
    Independent,
}

/// How many samples a pass adds per pixel.
#[derive(Copy, Clone, Debug)]
pub enum Samples {
    /// The same number in every pixel.
    Uniform(u32),
    /// A count per pixel: `map` holds one u32 per pixel (row-major), e.g.
    /// the denoiser's sample map ([`Outputs::samples`](crate::Outputs)),
    /// and `total` is the sum of its counts, which the host knows without
    /// reading the map back: a sample map sums to exactly its budget. The
    /// pass traces `total` samples, whatever their spread (a pixel with 0
    /// costs nothing). Should the map sum to more, the samples past the
    /// first `total` in pixel order are not traced (nor counted); should
    /// it sum to less, the missing ones trace nothing.
    Map {
        /// One u32 per pixel.
        map: BufferSlice,
        /// The sum of the counts.
        total: u32,
    },
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
    /// Keyframed objects' placements back to the scene file's
    /// ([`GpuScene::rest`]).
    rest: GpuBuffer,
    accum: GpuBuffer,
    /// A pass's items (`render_scan`): `pixels + 1` uvec2 entries.
    scan: GpuBuffer,
    /// `render_scan`'s block sums: one u32 per [`SCAN_BLOCK`] pixels.
    blocks: GpuBuffer,
    /// A window's traced items: [`ITEM_BYTES`] per item.
    items: GpuBuffer,
    /// Items per window (the capacity of `items`).
    window: u32,
    /// Bound where a binding is unused (no map).
    dummy: GpuBuffer,
    /// `render_trace`'s traversal counters: rays and BVH node visits, each
    /// a (low, high) pair of u32 words.
    work: GpuBuffer,
    flops_per_sample: f64,
    features: FeatureSamples,
}

/// Traversal work of a renderer's passes since its last clear
/// ([`Renderer::traversal`]): how much the samples cost, which samples per
/// second alone does not say (a sample that sees only the environment
/// traces one ray and visits no node; on the `panel` scene the average
/// sample traces 2.2 rays, on `rough_metals` 5.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traversal {
    /// Rays traced: camera and bounce rays and shadow rays.
    pub rays: u64,
    /// BVH nodes visited by them (inner nodes and leaves).
    pub nodes: u64,
}

impl std::ops::Sub for Traversal {
    type Output = Traversal;
    fn sub(self, o: Traversal) -> Traversal {
        Traversal {
            rays: self.rays - o.rays,
            nodes: self.nodes - o.nodes,
        }
    }
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

/// A feature path's share of a sample's estimated work: a camera ray and a
/// shadow ray of a path's few vertices of two rays.
const FEATURE_FLOPS_SHARE: f64 = 0.5;

/// Scale of [`flops_per_sample`]: on lavapipe (2 cores) the Cornell box
/// takes ~4 µs per sample and the estimate is ~6,500, so a submit of
/// [`crate::gpu::batch::DEFAULT_FLOPS_PER_SUBMIT`] is under a second.
const RENDER_FLOPS_SCALE: f64 = 1.0;

/// Items per window for an image of `pixels`: [`ITEM_WINDOW`], or 64 per
/// pixel for a small image (its passes rarely need more, and the items
/// buffer stays small), within `maxStorageBufferRange`; whole grid rows.
fn default_window(ctx: &GpuContext, pixels: u64) -> u32 {
    let limit = ctx.info().max_storage_buffer_range as u64 / ITEM_BYTES;
    let items = (pixels * 64).min(ITEM_WINDOW as u64).min(limit);
    ((items / GRID_WIDTH as u64).max(1) * GRID_WIDTH as u64) as u32
}

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
        let pixels = (width * height) as u64;
        let window = default_window(ctx, pixels);
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
            rest: buffer_of(ctx, "render.rest", &gs.rest)?,
            accum,
            scan: GpuBuffer::new(ctx, "render.scan", (pixels + 1) * 8)?,
            blocks: GpuBuffer::new(
                ctx,
                "render.scan_blocks",
                pixels.div_ceil(SCAN_BLOCK as u64) * 4,
            )?,
            items: GpuBuffer::new(ctx, "render.items", window as u64 * ITEM_BYTES)?,
            window,
            dummy: GpuBuffer::from_slice(ctx, "render.dummy", &[0u32; 4])?,
            work: GpuBuffer::from_slice(ctx, "render.work", &[0u32; 4])?,
            flops_per_sample: flops_per_sample(&gs),
            features: FeatureSamples::Shared,
            scene: gs,
        };
        let mut batch = Batch::new(ctx)?;
        r.record_clear(&mut batch);
        batch.finish()?;
        Ok(r)
    }

    /// The accumulation layout: position and visibility included, the
    /// positions relative to the lens centre unless
    /// [`with_position_origin`](Self::with_position_origin) chose another
    /// point.
    pub fn layout(&self) -> AccumLayout {
        self.layout
    }

    /// The same renderer with positions accumulated relative to `origin`
    /// ([`AccumLayout::position_origin`]) instead of the lens centre: the
    /// frames of a sequence share one, since a denoiser finalises every
    /// frame with the layout it was made for. Panics if `origin` is not
    /// finite.
    pub fn with_position_origin(mut self, origin: [f32; 3]) -> Renderer {
        self.layout = self.layout.with_position_origin(origin);
        self
    }

    /// The same renderer with its features from `features`' samples
    /// ([`FeatureSamples::Shared`] unless set).
    pub fn with_feature_samples(mut self, features: FeatureSamples) -> Renderer {
        self.features = features;
        self
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

    /// Records zeroing the accumulation buffer (every sum and the count)
    /// and the traversal counters ([`traversal`](Self::traversal)).
    pub fn record_clear(&self, batch: &mut Batch) {
        batch.fill(self.accum.slice(), 0);
        batch.fill(self.work.slice(), 0);
    }

    /// The rays traced and BVH nodes visited by the passes finished since
    /// the last clear (read back from the GPU: call it after the batch).
    pub fn traversal(&self) -> Result<Traversal> {
        let w = self.work.read_vec::<u32>(4)?;
        let wide = |lo: usize| w[lo] as u64 | (w[lo + 1] as u64) << 32;
        Ok(Traversal {
            rays: wide(0),
            nodes: wide(2),
        })
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

    /// Records one pass: every sample of the pass is a work item,
    /// `render_scan` numbers them (pixel by pixel, each pixel's in sample
    /// order), and windows of at most [`ITEM_WINDOW`] items are traced
    /// (`render_trace`, one invocation per sample, split into bands of
    /// whole grid rows by their estimated work, [`Batch::dispatch`]) and
    /// then added to the planes (`render_resolve`). A pass costs what its
    /// samples cost, however they are spread over the pixels.
    ///
    /// A uniform pass of more than 2^32 − 1 samples is recorded as several
    /// passes (the items are counted in u32); the planes do not change.
    pub fn record_pass(&self, batch: &mut Batch, samples: Samples) -> Result<()> {
        self.record(batch, samples, None)
    }

    /// [`record_pass`](Self::record_pass); with `debug`, each window's
    /// items are also copied there, [`ITEM_BYTES`] per item of the pass.
    fn record(
        &self,
        batch: &mut Batch,
        samples: Samples,
        debug: Option<BufferSlice>,
    ) -> Result<()> {
        let l = self.layout;
        let pixels = l.pixels() as u64;
        let (uniform_spp, use_map, map, total) = match samples {
            Samples::Uniform(n) => {
                let total = n as u64 * pixels;
                if total > u32::MAX as u64 {
                    if debug.is_some() {
                        return Err(Error::Limit(format!(
                            "a debug pass of {total} samples; at most {} fit",
                            u32::MAX
                        )));
                    }
                    let per = (u32::MAX as u64 / pixels) as u32;
                    let mut left = n;
                    while left > 0 {
                        let k = per.min(left);
                        self.record(batch, Samples::Uniform(k), None)?;
                        left -= k;
                    }
                    return Ok(());
                }
                (n, 0, self.dummy.slice(), total as u32)
            }
            Samples::Map { map, total } => {
                if map.size() < pixels * 4 {
                    return Err(Error::InvalidArgument(format!(
                        "the sample map holds {} bytes; {} pixels need {}",
                        map.size(),
                        pixels,
                        pixels * 4
                    )));
                }
                (0, 1, map, total)
            }
        };
        if total == 0 {
            return Ok(());
        }
        self.record_scan(batch, uniform_spp, use_map, map)?;
        let [a, b, c, d, e] = self.scene_bindings();
        let trace_bindings = [
            a,
            b,
            c,
            d,
            e,
            self.scan.slice(),
            self.items.slice(),
            self.normals.slice(),
            self.work.slice(),
            self.rest.slice(),
        ];
        let group = |g: u64| {
            let stride = l.plane_stride();
            self.accum.range(
                g * ACCUM_GROUP * stride,
                (ACCUM_GROUP - 1) * stride + pixels * 4,
            )
        };
        let resolve_bindings = [
            self.items.slice(),
            self.scan.slice(),
            group(0),
            group(1),
            group(2),
            group(3),
        ];
        let origin = l.position_origin;
        let mut item0 = 0u32;
        while item0 < total {
            let items = (total - item0).min(self.window);
            let push = TracePush {
                width: l.width as u32,
                height: l.height as u32,
                row0: 0,
                item0,
                items,
                seed_lo: self.seed as u32,
                seed_hi: (self.seed >> 32) as u32,
                uniform_spp,
            };
            batch.dispatch(
                &TRACE,
                Precision::F32,
                &trace_bindings,
                bytemuck::bytes_of(&push),
                GRID_WIDTH,
                items.div_ceil(GRID_WIDTH),
                self.flops_per_sample,
            )?;
            if self.features == FeatureSamples::Independent {
                batch.dispatch(
                    &FEATURES,
                    Precision::F32,
                    &trace_bindings,
                    bytemuck::bytes_of(&push),
                    GRID_WIDTH,
                    items.div_ceil(GRID_WIDTH),
                    FEATURE_FLOPS_SHARE * self.flops_per_sample,
                )?;
            }
            if let Some(dbg) = debug {
                let bytes = items as u64 * ITEM_BYTES;
                batch.copy(
                    self.items.range(0, bytes),
                    dbg.sub(item0 as u64 * ITEM_BYTES, bytes)?,
                );
            }
            let mut begin = 0u32;
            while begin < items {
                let end = (begin + RESOLVE_CHUNK).min(items);
                let push = ResolvePush {
                    begin,
                    end,
                    row0: 0,
                    plane_stride: (l.plane_stride() / 4) as u32,
                    origin: [origin[0], origin[1], origin[2], 0.0],
                    item0,
                    pixels: pixels as u32,
                    lanes: RESOLVE_LANES,
                    pad: 0,
                };
                batch.dispatch(
                    &RESOLVE,
                    Precision::F32,
                    &resolve_bindings,
                    bytemuck::bytes_of(&push),
                    GRID_WIDTH,
                    RESOLVE_LANES / GRID_WIDTH,
                    RESOLVE_FLOPS * (end - begin) as f64 / RESOLVE_LANES as f64,
                )?;
                begin = end;
            }
            item0 += items;
        }
        Ok(())
    }

    /// Records `render_scan`'s three phases: the pass's prefix sums and
    /// count snapshot in `scan`.
    fn record_scan(
        &self,
        batch: &mut Batch,
        uniform_spp: u32,
        use_map: u32,
        map: BufferSlice,
    ) -> Result<()> {
        let l = self.layout;
        let pixels = l.pixels() as u32;
        let blocks = pixels.div_ceil(SCAN_BLOCK);
        let count = self
            .accum
            .range(l.count_plane() as u64 * l.plane_stride(), pixels as u64 * 4);
        let bindings = [map, count, self.scan.slice(), self.blocks.slice()];
        for phase in 0..3 {
            let push = ScanPush {
                pixels,
                blocks,
                row0: 0,
                phase,
                block: SCAN_BLOCK,
                uniform_spp,
                use_map,
                pad: 0,
            };
            // Phase 1 is one workgroup; 0 and 2 one invocation per block.
            let (width, rows, flops) = match phase {
                1 => (1, 1, SCAN_FLOPS * blocks as f64),
                _ => (
                    GRID_WIDTH,
                    blocks.div_ceil(GRID_WIDTH),
                    SCAN_FLOPS * SCAN_BLOCK as f64,
                ),
            };
            batch.dispatch(
                &SCAN,
                Precision::F32,
                &bindings,
                bytemuck::bytes_of(&push),
                width,
                rows,
                flops,
            )?;
        }
        Ok(())
    }

    /// Records `spp` uniform samples per pixel (a reference render): one
    /// pass, whose trace the batch splits into submits within its
    /// [`max_flops_per_submit`](Batch::max_flops_per_submit). The planes
    /// are bit-identical to any split of `spp` into passes.
    pub fn record_uniform(&self, batch: &mut Batch, spp: u32) -> Result<()> {
        self.record_pass(batch, Samples::Uniform(spp))
    }

    /// Items per window (see [`ITEM_WINDOW`]).
    pub fn item_window(&self) -> u32 {
        self.window
    }

    /// Sets the items per window (rounded up to whole grid rows of
    /// [`GRID_WIDTH`]) and reallocates the items buffer, 64 bytes per item.
    /// The planes do not depend on it; a test aid, and a memory bound.
    pub fn set_item_window(&mut self, items: u32) -> Result<()> {
        let limit = self.ctx.info().max_storage_buffer_range as u64 / ITEM_BYTES;
        let window = (items.max(1).div_ceil(GRID_WIDTH) as u64 * GRID_WIDTH as u64).min(limit);
        self.items = GpuBuffer::new(&self.ctx, "render.items", window * ITEM_BYTES)?;
        self.window = window as u32;
        Ok(())
    }

    /// The items of a pass as `render_scan` numbers them: for each pixel
    /// the exclusive prefix sum of the pass's counts and the pixel's count
    /// (its first sample index of the pass), then the total. Records and
    /// submits only the scan. A test aid.
    pub fn pass_items(&self, samples: Samples) -> Result<(Vec<u32>, Vec<u32>)> {
        let (uniform_spp, use_map, map) = match samples {
            Samples::Uniform(n) => (n, 0, self.dummy.slice()),
            Samples::Map { map, .. } => (0, 1, map),
        };
        let mut batch = Batch::new(&self.ctx)?;
        self.record_scan(&mut batch, uniform_spp, use_map, map)?;
        batch.finish()?;
        let n = self.layout.pixels();
        let entries: Vec<[u32; 2]> = self.scan.read_vec(n + 1)?;
        let prefix = entries.iter().map(|e| e[0]).collect();
        let first = entries[..n].iter().map(|e| e[1]).collect();
        Ok((prefix, first))
    }

    /// Renders `spp` samples per pixel and returns each sample's 14 values
    /// (AccumLayout channel order), `[pixel][sample][value]` flattened, while
    /// also adding them to the accumulation buffer: the items of a uniform
    /// pass are in that order, and each window's are copied out. A test
    /// aid: it submits and waits.
    pub fn run_pass_debug(&self, spp: u32) -> Result<Vec<f32>> {
        let items = self.layout.pixels() * spp as usize;
        if items == 0 {
            return Ok(Vec::new());
        }
        let out = GpuBuffer::new(&self.ctx, "render.debug_samples", items as u64 * ITEM_BYTES)?;
        let mut batch = Batch::new(&self.ctx)?;
        self.record(&mut batch, Samples::Uniform(spp), Some(out.slice()))?;
        batch.finish()?;
        let raw: Vec<[f32; 16]> = out.read_vec(items)?;
        Ok(raw.iter().flat_map(|v| v[..14].iter().copied()).collect())
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
        let hits: Vec<[f32; 2]> = self.run_aid(&RAYS, "render.rays", &data, 1000.0)?;
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
        self.run_aid(&LIGHTS, "render.us", us, 100.0)
    }

    /// Runs a test-aid kernel (`render_rays`, `render_lights`) over the
    /// records of `input`, one invocation each in rows of 64, and reads
    /// back one `O` per record.
    fn run_aid<I: bytemuck::Pod, O: bytemuck::Pod + Default>(
        &self,
        decl: &KernelDecl,
        label: &str,
        input: &[I],
        cost: f64,
    ) -> Result<Vec<O>> {
        let ib = GpuBuffer::from_slice(&self.ctx, label, input)?;
        let ob = GpuBuffer::new(
            &self.ctx,
            "render.aid_out",
            (input.len() * std::mem::size_of::<O>()) as u64,
        )?;
        let width = 64u32;
        let push = RaysPush {
            width,
            height: (input.len() as u32).div_ceil(width),
            row0: 0,
            count: input.len() as u32,
        };
        let [a, b, c, d, e] = self.scene_bindings();
        let mut batch = Batch::new(&self.ctx)?;
        batch.dispatch(
            decl,
            Precision::F32,
            &[a, b, c, d, e, ib.slice(), ob.slice()],
            bytemuck::bytes_of(&push),
            push.width,
            push.height,
            cost,
        )?;
        batch.finish()?;
        ob.read_vec(input.len())
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
    /// in f64 (as a statistics EXR holds them).
    pub fn statistics(&self) -> Result<StatsImage> {
        Ok(self.layout.finalize(&self.download()?))
    }

    /// The same statistics finalised on the GPU at `precision`, bit for bit
    /// what a denoiser at that precision reads from the accumulation
    /// buffer: denoising them again reproduces its output (blocking).
    pub fn statistics_at(&self, precision: Precision) -> Result<StatsImage> {
        self.layout
            .finalize_gpu(&self.ctx, self.accum.slice(), precision)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Layer;

    /// The plane numbers hard-coded in `render_resolve.comp`.
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
        assert_eq!(std::mem::size_of::<TracePush>(), 32);
        assert_eq!(std::mem::size_of::<ScanPush>(), 32);
        assert_eq!(std::mem::size_of::<ResolvePush>(), 48);
        assert_eq!(std::mem::offset_of!(ResolvePush, origin), 16);
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
            keyframes: Vec::new(),
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
