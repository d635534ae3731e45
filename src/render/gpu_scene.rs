//! The scene as the render kernels read it (`spirv/render/render_scene.glsl`):
//! camera parameters, a binary BVH built with `obvhs` and flattened to two
//! vec4 per node, primitives reordered to the BVH's leaf order, materials
//! and the light table (every emissive primitive whose material has
//! `next_event`, picked in proportion to its power).

use bytemuck::{Pod, Zeroable};
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::{Boundable, BvhBuildParams};
use obvhs_glam::Vec3A;

use super::scene::{Albedo, Material, Primitive, Scene, Shape, Texture, Vec3};
use crate::error::{Error, Result};

/// Entries of the traversal stack in the shader (`STACK_SIZE` in
/// `render_scene.glsl`): the BVH may be at most this deep.
pub const STACK_SIZE: usize = 32;

/// Mirrors the `Params` block of `render_scene.glsl`.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, Pod, Zeroable)]
pub struct GpuParams {
    /// Lens centre, w: lens radius.
    pub cam_pos: [f32; 4],
    /// Unit right vector.
    pub lens_u: [f32; 4],
    /// Unit up vector.
    pub lens_v: [f32; 4],
    /// Forward × focus distance.
    pub focus_w: [f32; 4],
    /// Right × half the image width at the focus distance.
    pub half_u: [f32; 4],
    /// Up × half the image height at the focus distance.
    pub half_v: [f32; 4],
    /// Environment radiance (rgb).
    pub env: [f32; 4],
    /// Node count, primitive count, max depth, light count.
    pub counts: [u32; 4],
}

/// Kinds in the low two bits of a primitive's first word.
const KIND_SPHERE: u32 = 0;
const KIND_QUAD: u32 = 1;
const KIND_TRIANGLE: u32 = 2;

/// A primitive's first word: its kind in bits 0–1, its material in bits
/// 2–15 and its placement (an index into [`GpuScene::rest`]) in bits 16–22
/// (`prim_material` and `rest_position` in the shaders). The word is
/// stored as a float's bits: below bit 23 its exponent stays 0, so it is
/// never a NaN, whose payload a GPU need not keep.
const PLACEMENT_SHIFT: u32 = 16;
const MAX_MATERIALS: usize = 1 << (PLACEMENT_SHIFT - 2);
const MAX_PLACEMENTS: usize = 1 << (23 - PLACEMENT_SHIFT);

/// Material classes (low byte of a material's first word) and albedo
/// textures (second byte).
const MAT_DIFFUSE: u32 = 0;
const MAT_EMISSIVE: u32 = 3;
const MAT_CONDUCTOR: u32 = 4;
const MAT_PLASTIC: u32 = 5;
const MAT_DIELECTRIC: u32 = 6;
const TEX_CHECKER: u32 = 1;
const TEX_NOISE: u32 = 2;

/// `(texture << 8, scale, a, b)` of an albedo.
fn albedo_words(albedo: &Albedo) -> (u32, f32, Vec3, Vec3) {
    match albedo {
        Albedo::Constant(c) => (0, 1.0, *c, *c),
        Albedo::Texture(Texture::Checker { a, b, scale }) => (TEX_CHECKER << 8, *scale, *a, *b),
        Albedo::Texture(Texture::Noise { a, b, scale }) => (TEX_NOISE << 8, *scale, *a, *b),
    }
}

/// Distinct values of the shader's uniform random numbers (`rand2` in
/// `render_scene.glsl`: 24-bit multiples of 2⁻²⁴).
const RANDOM_STEPS: f64 = 16_777_216.0;

/// GGX width from perceptual roughness.
fn ggx_alpha(roughness: f32) -> f32 {
    let r = roughness.clamp(0.0, 1.0);
    r * r
}

/// Everything the kernels read about a scene, in host memory.
#[derive(Clone, Debug)]
pub struct GpuScene {
    /// Camera and counts.
    pub params: GpuParams,
    /// Two vec4 per node (8 f32).
    pub nodes: Vec<[f32; 8]>,
    /// Four vec4 per primitive (16 f32), in BVH leaf order.
    pub prims: Vec<[f32; 16]>,
    /// The primitives in the same order as `prims`.
    pub primitives: Vec<Primitive>,
    /// Three vec4 per material.
    pub materials: Vec<[f32; 12]>,
    /// One vec4 per light: (primitive index bits, cumulative selection
    /// probability, 0, 0); the last cumulative probability is 1.
    pub lights: Vec<[f32; 4]>,
    /// Three vec4 (vertex normals) per triangle with shading normals.
    pub normals: Vec<[f32; 12]>,
    /// Three vec4 per placement (the rows of [`Primitive::rest`]); entry 0
    /// is the identity, the placement of every primitive without one.
    pub rest: Vec<[f32; 12]>,
    /// Depth of the BVH (edges from the root to the deepest leaf).
    pub depth: usize,
}

struct Bounded(Aabb);

impl Boundable for Bounded {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

fn v3(a: Vec3) -> Vec3A {
    Vec3A::new(a[0], a[1], a[2])
}

fn luminance(c: Vec3) -> f64 {
    (0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]) as f64
}

/// Mean luminance of a radiance over a surface: a checker's two colours
/// cover half of it each, and value noise averages ½ (it only weighs the
/// light's selection, never its estimate, so an approximation is unbiased).
fn mean_luminance(radiance: &Albedo) -> f64 {
    match radiance {
        Albedo::Constant(c) => luminance(*c),
        Albedo::Texture(Texture::Checker { a, b, .. } | Texture::Noise { a, b, .. }) => {
            0.5 * (luminance(*a) + luminance(*b))
        }
    }
}

impl GpuScene {
    /// Builds the BVH and the GPU tables of `scene` for a `width × height`
    /// image.
    pub fn new(scene: &Scene, width: usize, height: usize) -> Result<GpuScene> {
        // A scene built in code has not been through the loader's checks.
        scene.check()?;
        let prims_in = scene.primitives()?;
        let (nodes, order, depth) = build(&prims_in)?;
        let primitives: Vec<Primitive> = order.iter().map(|&i| prims_in[i as usize]).collect();
        let mats = scene.material_list();

        // Lights: emissive primitives with next-event estimation, chosen in
        // proportion to power (a two-sided triangle's one side counts, as
        // a shading point sees one).
        let mut light_prims = Vec::new();
        let mut powers = Vec::new();
        for (i, p) in primitives.iter().enumerate() {
            if let Material::Emissive {
                radiance,
                next_event: true,
            } = mats[p.material as usize].1
            {
                let power = p.area() * mean_luminance(radiance);
                if power > 0.0 {
                    light_prims.push(i);
                    powers.push(power);
                }
            }
        }
        let total: f64 = powers.iter().sum();
        let mut light_pdf = vec![0.0f32; primitives.len()];
        let mut lights = Vec::new();
        let mut cdf = 0.0;
        let mut picked_below = 0.0;
        for (k, (&i, &pw)) in light_prims.iter().zip(&powers).enumerate() {
            cdf += pw / total;
            let c = if k + 1 == light_prims.len() {
                1.0
            } else {
                cdf as f32
            };
            lights.push([f32::from_bits(i as u32), c, 0.0, 0.0]);
            // The selection probability is the exact share of the shader's
            // random numbers (multiples of 2⁻²⁴ in [0, 1)) below the f32
            // boundary that pick this light: a light too dim to own one
            // gets 0, is never picked, and its BSDF hits keep full weight.
            let picked = (c as f64 * RANDOM_STEPS).ceil();
            let select = (picked - picked_below) / RANDOM_STEPS;
            picked_below = picked;
            light_pdf[i] = (select / primitives[i].area()) as f32;
        }

        if mats.len() > MAX_MATERIALS {
            return Err(Error::InvalidArgument(format!(
                "a scene has {} materials; the renderer takes at most {MAX_MATERIALS}",
                mats.len()
            )));
        }
        let mut rest: Vec<[f32; 12]> =
            vec![std::array::from_fn(|i| if i % 5 == 0 { 1.0 } else { 0.0 })];
        // One entry per distinct placement (an object's primitives share
        // theirs but are not consecutive in BVH order).
        let mut seen = std::collections::HashMap::new();
        let mut rest_index = Vec::with_capacity(primitives.len());
        for p in &primitives {
            let index = match p.rest {
                None => 0,
                Some(m) => {
                    let words: [f32; 12] = std::array::from_fn(|i| m[i / 4][i % 4]);
                    *seen.entry(words.map(f32::to_bits)).or_insert_with(|| {
                        rest.push(words);
                        rest.len() - 1
                    })
                }
            };
            if index >= MAX_PLACEMENTS {
                return Err(Error::InvalidArgument(format!(
                    "a scene has more than {} keyframed objects",
                    MAX_PLACEMENTS - 1
                )));
            }
            rest_index.push(index as u32);
        }

        let mut normals = Vec::new();
        let prims = primitives
            .iter()
            .zip(&light_pdf)
            .zip(&rest_index)
            .map(|((p, &pdf), &placement)| {
                let normal_index = match p.normals {
                    Some(n) => {
                        normals.push(std::array::from_fn(|i| {
                            if i % 4 == 3 {
                                0.0
                            } else {
                                n[i / 4][i % 4]
                            }
                        }));
                        normals.len() as u32 - 1
                    }
                    None => u32::MAX,
                };
                let (kind, a, b, c, radius) = match p.shape {
                    Shape::Sphere { center, radius } => {
                        (KIND_SPHERE, center, [0.0; 3], [0.0; 3], radius)
                    }
                    Shape::Quad { corner, u, v } => (KIND_QUAD, corner, u, v, 0.0),
                    Shape::Triangle { a, b, c } => {
                        let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                        let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                        (KIND_TRIANGLE, a, e1, e2, 0.0)
                    }
                };
                let m = p.motion;
                [
                    a[0],
                    a[1],
                    a[2],
                    f32::from_bits(kind | p.material << 2 | placement << PLACEMENT_SHIFT),
                    b[0],
                    b[1],
                    b[2],
                    radius,
                    c[0],
                    c[1],
                    c[2],
                    pdf,
                    m[0],
                    m[1],
                    m[2],
                    f32::from_bits(normal_index),
                ]
            })
            .collect();

        let materials = mats
            .iter()
            .map(|(_, m)| {
                let (kind, scale, a, b, alpha, ior) = match m {
                    Material::Diffuse { albedo } => {
                        let (t, scale, a, b) = albedo_words(albedo);
                        (MAT_DIFFUSE | t, scale, a, b, 0.0, 1.0)
                    }
                    Material::Conductor { color, roughness } => (
                        MAT_CONDUCTOR,
                        1.0,
                        *color,
                        *color,
                        ggx_alpha(*roughness),
                        1.0,
                    ),
                    Material::Plastic {
                        albedo,
                        roughness,
                        ior,
                    } => {
                        let (t, scale, a, b) = albedo_words(albedo);
                        let alpha = ggx_alpha(roughness.max(0.05));
                        (MAT_PLASTIC | t, scale, a, b, alpha, *ior)
                    }
                    Material::Dielectric {
                        ior,
                        roughness,
                        tint,
                    } => (
                        MAT_DIELECTRIC,
                        1.0,
                        *tint,
                        *tint,
                        ggx_alpha(*roughness),
                        *ior,
                    ),
                    Material::Emissive { radiance, .. } => {
                        let (t, scale, a, b) = albedo_words(radiance);
                        (MAT_EMISSIVE | t, scale, a, b, 0.0, 1.0)
                    }
                };
                [
                    f32::from_bits(kind),
                    scale,
                    alpha,
                    ior,
                    a[0],
                    a[1],
                    a[2],
                    0.0,
                    b[0],
                    b[1],
                    b[2],
                    0.0,
                ]
            })
            .collect();

        let params = camera_params(
            scene,
            width,
            height,
            nodes.len(),
            primitives.len(),
            lights.len(),
        );
        Ok(GpuScene {
            params,
            nodes,
            prims,
            primitives,
            materials,
            lights,
            normals,
            rest,
            depth,
        })
    }

    /// The light-table index a linear scan of the cumulative selection
    /// probabilities picks for the random number `u ∈ [0, 1)`: the first
    /// light with `u < cdf`, or the last. The host twin of the shader's
    /// binary search (`select_light` in `render_scene.glsl`); `None` when
    /// the scene has no lights.
    pub fn select_light_linear(&self, u: f32) -> Option<u32> {
        let n = self.lights.len();
        (n > 0).then(|| {
            let mut l = 0;
            while l + 1 < n && u >= self.lights[l][1] {
                l += 1;
            }
            l as u32
        })
    }
}

fn camera_params(
    scene: &Scene,
    width: usize,
    height: usize,
    nodes: usize,
    prims: usize,
    lights: usize,
) -> GpuParams {
    let c = &scene.camera;
    let f = |a: Vec3| obvhs_glam::Vec3::new(a[0], a[1], a[2]);
    let pos = f(c.position);
    let to = f(c.look_at) - pos;
    let forward = to.normalize();
    let right = forward.cross(f(c.up)).normalize();
    let up = right.cross(forward);
    let focus = c.focus_distance.unwrap_or(to.length());
    let half_h = (0.5 * c.fov.to_radians()).tan() * focus;
    let half_w = half_h * width as f32 / height.max(1) as f32;
    let v4 = |v: obvhs_glam::Vec3, w: f32| [v.x, v.y, v.z, w];
    GpuParams {
        cam_pos: v4(pos, c.aperture),
        lens_u: v4(right, 0.0),
        lens_v: v4(up, 0.0),
        focus_w: v4(forward * focus, 0.0),
        half_u: v4(right * half_w, 0.0),
        half_v: v4(up * half_h, 0.0),
        env: [
            scene.environment[0],
            scene.environment[1],
            scene.environment[2],
            0.0,
        ],
        counts: [nodes as u32, prims as u32, scene.max_depth, lights as u32],
    }
}

/// Builds the BVH: returns the flattened nodes, the primitive order (leaf
/// ranges index the reordered list) and the depth.
fn build(prims: &[Primitive]) -> Result<(Vec<[f32; 8]>, Vec<u32>, usize)> {
    if prims.is_empty() {
        return Ok((Vec::new(), Vec::new(), 0));
    }
    let boxes: Vec<Bounded> = prims
        .iter()
        .map(|p| {
            let (lo, hi) = p.bounds();
            // Pad by a relative epsilon: the shader's f32 slab test must not
            // miss a flat primitive lying on a box face.
            let ext = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
            let mag = lo.iter().chain(&hi).fold(0.0f32, |m, x| m.max(x.abs()));
            let pad = 1e-5 * ext + 1e-6 * mag + 1e-7;
            Bounded(Aabb::new(
                v3(lo) - Vec3A::splat(pad),
                v3(hi) + Vec3A::splat(pad),
            ))
        })
        .collect();
    let mut params = BvhBuildParams::medium_build();
    params.max_prims_per_leaf = 4;
    let mut t = std::time::Duration::ZERO;
    let bvh = build_bvh2(&boxes, params, &mut t);
    let order = bvh.primitive_indices.clone();
    let nodes: Vec<[f32; 8]> = bvh
        .nodes
        .iter()
        .map(|n| {
            let (lo, hi) = (n.aabb.min, n.aabb.max);
            [
                lo.x,
                lo.y,
                lo.z,
                f32::from_bits(n.first_index),
                hi.x,
                hi.y,
                hi.z,
                f32::from_bits(n.prim_count),
            ]
        })
        .collect();
    // Depth by walking the tree (iteratively: user meshes may be deep).
    let mut depth = 0;
    let mut todo = vec![(0usize, 0usize)];
    while let Some((n, d)) = todo.pop() {
        let node = &bvh.nodes[n];
        if node.prim_count == 0 {
            let c = node.first_index as usize;
            todo.push((c, d + 1));
            todo.push((c + 1, d + 1));
        } else {
            depth = depth.max(d);
        }
    }
    if depth > STACK_SIZE {
        return Err(Error::Limit(format!(
            "the scene's BVH is {depth} levels deep; the render kernel's traversal stack holds {STACK_SIZE}"
        )));
    }
    Ok((nodes, order, depth))
}
