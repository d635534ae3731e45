//! Scenes of the built-in path tracer: camera, materials, objects, and the
//! TOML file format they are read from (see the README, "Scene files").
//!
//! A scene is a camera, an environment colour, a table of named materials
//! and a list of objects. Objects become primitives — spheres,
//! parallelograms ("quads") and triangles — each with a material and an
//! optional linear motion over the shutter interval `[0, 1)`: at shutter
//! time `τ` the primitive is translated by `τ · motion`.
//!
//! ```toml
//! environment = [0.0, 0.0, 0.0]   # radiance of every ray that leaves the scene
//! max_depth = 8                    # path vertices after the camera (optional)
//!
//! [camera]
//! position = [0.0, 1.0, 3.5]
//! look_at = [0.0, 1.0, 0.0]
//! up = [0.0, 1.0, 0.0]             # optional, default +Y
//! fov = 40.0                       # vertical field of view, degrees
//! aperture = 0.05                  # thin-lens radius (optional, default 0: pinhole)
//! focus_distance = 3.5             # optional, default |look_at − position|
//!
//! [materials.white]
//! type = "diffuse"
//! albedo = [0.73, 0.73, 0.73]
//!
//! [materials.floor]
//! type = "diffuse"
//! albedo = { texture = "checker", a = [0.8, 0.8, 0.8], b = [0.1, 0.1, 0.1], scale = 4.0 }
//!
//! [materials.lamp]
//! type = "emissive"
//! radiance = [17.0, 12.0, 4.0]
//!
//! [[objects]]
//! type = "sphere"
//! center = [0.0, 0.5, 0.0]
//! radius = 0.5
//! material = "white"
//! motion = [0.3, 0.0, 0.0]         # optional
//!
//! [[objects]]
//! type = "quad"                    # corner + s·u + t·v, s, t in [0, 1]
//! corner = [-0.25, 1.99, -0.25]
//! u = [0.5, 0.0, 0.0]
//! v = [0.0, 0.0, 0.5]              # emits on the side of u × v only
//! material = "lamp"
//! ```
//!
//! Further material types: `conductor` (`color` = reflectance at normal
//! incidence, `roughness`), `plastic` (`albedo` as for diffuse, `roughness`,
//! `ior` = 1.5) and `dielectric` (`ior`, `roughness` = 0, `tint` = white);
//! roughness is perceptual (GGX width = roughness²). Further object types: `box` (`min`, `max`, optional `rotate_y` in
//! degrees about its centre: six quads) and `mesh` (`file = "x.obj"`,
//! relative to the scene file, or inline `vertices = [[x, y, z], …]` and
//! `indices = [[i, j, k], …]`; optional `scale` and `translate`). Textures
//! (`albedo = { texture = "checker" | "noise", a, b, scale }`) are evaluated
//! at the hit point's position at shutter time 0, in world units × `scale`,
//! in the object's placement as the file writes it: they move with it.
//!
//! A scene animates with an `[animation]` table — `frames = 24`, and
//! `[[animation.camera]]` keyframes (`frame`, and any of `position`,
//! `look_at`, `focus_distance`) — and objects' `keyframes = [{ frame = 0,
//! translate = [0, 0, 0], rotate_y = 0 }, …]` (rotation in degrees about
//! the vertical axis through the object's centre, then translation). Values
//! are interpolated linearly between keyframes and hold outside them;
//! [`Scene::at_frame`] places everything at one frame, a keyframed object
//! moving over that frame's shutter by its translation to the next.
//!
//! Every primitive of an `emissive` material is a light: spheres emit
//! outward, quads on their front side, mesh triangles on both sides.
//! Its `radiance` may be a texture like an albedo (a lit sign:
//! `radiance = { texture = "checker", a = [8, 2, 1], b = [0.5, 0.5, 0.5], scale = 3.0 }`).
//! Next-event estimation samples every light, picked in proportion to its
//! power; `next_event = false` on an emissive material leaves its
//! primitives to BSDF sampling only (as the environment always is).
//!
//! Loading checks the values, and an error names the field with its
//! material, object (by index in `objects`) or keyframe (by index in its
//! list): every number finite; `fov` in (0, 180); every position, edge,
//! offset and length — the camera's `position`, `look_at`, `aperture` and
//! `focus_distance` (also in its keyframes), objects' geometry, `motion`,
//! keyframe `translate`s, mesh vertices once scaled and translated (an OBJ
//! file's when [`Scene::primitives`] reads it) — within ±1e8 world units
//! ([`MAX_COORDINATE`]: f32 positions there are 8 units apart, and beyond
//! it the renderer's sums of squared positions overflow);
//! `radius` and `focus_distance` > 0; `up` not parallel to the view
//! direction; albedos (diffuse, plastic, their textures' `a` and `b`) in
//! `[0, 1]`; radiance, `environment`, conductor `color` and dielectric
//! `tint` non-negative; `ior` positive.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::error::{Error, Result};

/// A 3-vector in scene files: `[x, y, z]`.
pub type Vec3 = [f32; 3];

/// The thin-lens camera.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Centre of the lens, world units.
    pub position: Vec3,
    /// A point the camera looks at (the image centre).
    pub look_at: Vec3,
    /// Up direction (default `[0, 1, 0]`).
    #[serde(default = "default_up")]
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov: f32,
    /// Radius of the lens in world units; 0 is a pinhole (everything sharp).
    #[serde(default)]
    pub aperture: f32,
    /// Distance from the lens to the plane in focus; default
    /// `|look_at − position|`.
    #[serde(default)]
    pub focus_distance: Option<f32>,
}

fn default_up() -> Vec3 {
    [0.0, 1.0, 0.0]
}

fn default_max_depth() -> u32 {
    8
}

/// A procedural albedo texture: blends colour `a` and `b`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "texture", rename_all = "snake_case", deny_unknown_fields)]
pub enum Texture {
    /// 3D checkerboard of cells `1/scale` wide: `a` and `b` alternate.
    Checker {
        /// First colour.
        a: Vec3,
        /// Second colour.
        b: Vec3,
        /// Cells per world unit.
        scale: f32,
    },
    /// Three octaves of 3D value noise, `mix(a, b, noise)`.
    Noise {
        /// Colour where the noise is 0.
        a: Vec3,
        /// Colour where the noise is 1.
        b: Vec3,
        /// Noise features per world unit.
        scale: f32,
    },
}

/// A colour that may vary over a surface: a constant RGB or a texture. The
/// reflectance of diffuse and plastic materials (each component in
/// `[0, 1]`) and the radiance of emissive ones (any non-negative value).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Albedo {
    /// The same colour everywhere.
    Constant(Vec3),
    /// A procedural texture.
    Texture(Texture),
}

/// A material, referred to by its name in the scene's material table.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Material {
    /// Lambertian reflection.
    Diffuse {
        /// Reflectance.
        albedo: Albedo,
    },
    /// A rough metal: GGX microfacets with Schlick's Fresnel from the
    /// reflectance at normal incidence `color` (single scattering: a rough
    /// surface loses some energy to multiple bounces between microfacets).
    Conductor {
        /// Reflectance at normal incidence (F0), linear RGB.
        color: Vec3,
        /// Perceptual roughness in `[0, 1]`; the GGX width is its square.
        /// 0 is a perfect mirror.
        #[serde(default)]
        roughness: f32,
    },
    /// A diffuse base under a clear GGX coat of index `ior`.
    Plastic {
        /// Reflectance of the base.
        albedo: Albedo,
        /// Perceptual roughness of the coat in `[0.05, 1]` (smaller values
        /// are clamped to 0.05).
        roughness: f32,
        /// Index of refraction of the coat (default 1.5).
        #[serde(default = "default_ior")]
        ior: f32,
    },
    /// Glass: smooth (roughness 0) or rough (GGX) reflection and
    /// refraction at index `ior` (outside: 1), tinted on transmission.
    Dielectric {
        /// Index of refraction inside (the side the normal points away from).
        ior: f32,
        /// Perceptual roughness in `[0, 1]`.
        #[serde(default)]
        roughness: f32,
        /// Transmission colour per refraction (default white).
        #[serde(default = "white")]
        tint: Vec3,
    },
    /// A light: emits `radiance` (on the front side of quads, outward on
    /// spheres, on both sides of triangles) and reflects nothing.
    Emissive {
        /// Emitted radiance, linear RGB: a constant or a texture (a lit
        /// sign), evaluated like an albedo texture.
        radiance: Albedo,
        /// Whether next-event estimation samples this material's
        /// primitives (default true): each is an entry of the light table,
        /// picked in proportion to its power (area × mean luminance) and
        /// combined with BSDF sampling by MIS. `false`: found by BSDF
        /// sampling only, like the environment — for dim, large emitters
        /// that would take shadow rays from the lights that matter (like
        /// Cycles' per-material emission sampling setting), and for tests
        /// of the estimator.
        #[serde(default = "yes")]
        next_event: bool,
    },
}

/// An object's placement at one frame of an animation: rotated by
/// `rotate_y` degrees about the vertical axis through the centre of its
/// bounding box, then translated by `translate`. Between keyframes both are
/// interpolated linearly; before the first and after the last they hold.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Frame number (fractions allowed).
    pub frame: f32,
    /// Translation, world units.
    #[serde(default)]
    pub translate: Vec3,
    /// Rotation about the vertical axis through the object's centre, degrees.
    #[serde(default)]
    pub rotate_y: f32,
}

/// A camera keyframe: the properties it sets, each interpolated linearly
/// between the keyframes that set it (the `[camera]` table's value where
/// none does).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraKey {
    /// Frame number (fractions allowed).
    pub frame: f32,
    /// Centre of the lens.
    #[serde(default)]
    pub position: Option<Vec3>,
    /// The point at the image centre.
    #[serde(default)]
    pub look_at: Option<Vec3>,
    /// Distance to the plane in focus.
    #[serde(default)]
    pub focus_distance: Option<f32>,
}

/// The `[animation]` table: the sequence's length and the camera's
/// keyframes (objects carry their own `keyframes`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Animation {
    /// Frames of the sequence: frame numbers `0..frames`.
    pub frames: u32,
    /// Camera keyframes, in increasing frame order.
    #[serde(default)]
    pub camera: Vec<CameraKey>,
}

/// An object of a scene file; see the module documentation.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Object {
    /// A sphere.
    Sphere {
        /// Centre at shutter time 0.
        center: Vec3,
        /// Radius.
        radius: f32,
        /// Material name.
        material: String,
        /// Translation over the whole shutter interval.
        #[serde(default)]
        motion: Option<Vec3>,
        /// Placement over the frames of an animation ([`Keyframe`]).
        #[serde(default)]
        keyframes: Vec<Keyframe>,
    },
    /// The parallelogram `corner + s·u + t·v`, `s, t ∈ [0, 1]`.
    Quad {
        /// One corner.
        corner: Vec3,
        /// First edge.
        u: Vec3,
        /// Second edge; the front side is the side of `u × v`.
        v: Vec3,
        /// Material name.
        material: String,
        /// Translation over the whole shutter interval.
        #[serde(default)]
        motion: Option<Vec3>,
        /// Placement over the frames of an animation ([`Keyframe`]).
        #[serde(default)]
        keyframes: Vec<Keyframe>,
    },
    /// An axis-aligned box (before `rotate_y`), as six outward-facing quads.
    Box {
        /// Minimum corner.
        min: Vec3,
        /// Maximum corner.
        max: Vec3,
        /// Rotation about the vertical axis through the box centre, degrees.
        #[serde(default)]
        rotate_y: f32,
        /// Material name.
        material: String,
        /// Translation over the whole shutter interval.
        #[serde(default)]
        motion: Option<Vec3>,
        /// Placement over the frames of an animation ([`Keyframe`]).
        #[serde(default)]
        keyframes: Vec<Keyframe>,
    },
    /// A triangle mesh: from an OBJ file or inline.
    Mesh {
        /// OBJ file (relative paths are relative to the scene file).
        #[serde(default)]
        file: Option<PathBuf>,
        /// Inline vertex positions (without `file`).
        #[serde(default)]
        vertices: Vec<Vec3>,
        /// Inline triangles as vertex indices (without `file`).
        #[serde(default)]
        indices: Vec<[u32; 3]>,
        /// Inline per-vertex shading normals (optional; without them, and
        /// for OBJ files without `vn`, triangles are flat).
        #[serde(default)]
        normals: Vec<Vec3>,
        /// Uniform scale applied to the vertices (before `translate`).
        #[serde(default = "one")]
        scale: f32,
        /// Translation applied after `scale`.
        #[serde(default)]
        translate: Vec3,
        /// Material name.
        material: String,
        /// Translation over the whole shutter interval.
        #[serde(default)]
        motion: Option<Vec3>,
        /// Placement over the frames of an animation ([`Keyframe`]).
        #[serde(default)]
        keyframes: Vec<Keyframe>,
    },
}

fn one() -> f32 {
    1.0
}

fn default_ior() -> f32 {
    1.5
}

fn white() -> Vec3 {
    [1.0; 3]
}

fn yes() -> bool {
    true
}

/// A whole scene; see the module documentation for the file format.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    /// Radiance of rays that leave the scene (a uniform environment).
    #[serde(default)]
    pub environment: Vec3,
    /// Maximum number of path vertices after the camera (default 8).
    #[serde(default = "default_max_depth")]
    pub max_depth: u32,
    /// Materials by name.
    #[serde(default)]
    pub materials: BTreeMap<String, Material>,
    /// The objects.
    #[serde(default)]
    pub objects: Vec<Object>,
    /// The sequence, for an animated scene.
    #[serde(default)]
    pub animation: Option<Animation>,
    /// The frame the camera and the objects are placed at (not in the
    /// file; [`Scene::at_frame`] sets it, 0 otherwise).
    #[serde(skip)]
    pub frame: f32,
    /// Directory relative mesh paths are resolved against (not in the file).
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
}

/// One primitive, as the GPU intersects it. Positions are at shutter time 0.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Shape {
    /// Centre and radius.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
    /// `corner + s·u + t·v`, `s, t ∈ [0, 1]`.
    Quad {
        /// Corner.
        corner: Vec3,
        /// First edge.
        u: Vec3,
        /// Second edge.
        v: Vec3,
    },
    /// Vertices `a`, `b`, `c`.
    Triangle {
        /// First vertex.
        a: Vec3,
        /// Second vertex.
        b: Vec3,
        /// Third vertex.
        c: Vec3,
    },
}

/// A primitive with its material (index into [`Scene::material_list`]) and
/// motion over the shutter (zero when static).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Primitive {
    /// Geometry at shutter time 0.
    pub shape: Shape,
    /// Material index.
    pub material: u32,
    /// Translation over the shutter interval.
    pub motion: Vec3,
    /// Per-vertex shading normals of a triangle (interpolated), if any.
    pub normals: Option<[Vec3; 3]>,
    /// The map from a point of the primitive at shutter time 0 back to its
    /// object's placement as the scene file writes it, before keyframes
    /// (the rows of a 3×4 affine matrix): a keyframed object's points keep
    /// these coordinates from frame to frame. `None` where the two
    /// coincide.
    pub rest: Option<[[f32; 4]; 3]>,
}

fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

impl Primitive {
    /// Where the point `p` of the primitive at shutter time 0 lies in its
    /// object's placement as the scene file writes it ([`Primitive::rest`]).
    pub fn rest_point(&self, p: Vec3) -> Vec3 {
        match &self.rest {
            None => p,
            Some(m) => {
                std::array::from_fn(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3])
            }
        }
    }

    /// Bounding box over the shutter interval: the union of the boxes at
    /// times 0 and 1 (motion is linear).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let pts: Vec<Vec3> = match self.shape {
            Shape::Sphere { center, radius } => {
                let r = [radius; 3];
                vec![sub(center, r), add(center, r)]
            }
            Shape::Quad { corner, u, v } => {
                vec![
                    corner,
                    add(corner, u),
                    add(corner, v),
                    add(add(corner, u), v),
                ]
            }
            Shape::Triangle { a, b, c } => vec![a, b, c],
        };
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in pts.iter().flat_map(|p| [*p, add(*p, self.motion)]) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// Surface area (for light sampling).
    pub fn area(&self) -> f64 {
        let cross_len = |u: Vec3, v: Vec3| {
            let c = cross64(u, v);
            (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
        };
        match self.shape {
            Shape::Sphere { radius, .. } => 4.0 * std::f64::consts::PI * (radius as f64).powi(2),
            Shape::Quad { u, v, .. } => cross_len(u, v),
            Shape::Triangle { a, b, c } => 0.5 * cross_len(sub(b, a), sub(c, a)),
        }
    }

    /// The host twin of the shader's intersection: distance along `dir`
    /// (any length; `t` is in units of `dir`) of the nearest hit in
    /// `(tmin, ∞)` at shutter time `time`, in f64. For tests.
    pub fn intersect(&self, origin: [f64; 3], dir: [f64; 3], time: f64, tmin: f64) -> Option<f64> {
        let o = [
            origin[0] - time * self.motion[0] as f64,
            origin[1] - time * self.motion[1] as f64,
            origin[2] - time * self.motion[2] as f64,
        ];
        let f = |v: Vec3| [v[0] as f64, v[1] as f64, v[2] as f64];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let parallelogram = |p0: [f64; 3], e1: [f64; 3], e2: [f64; 3], tri: bool| {
            let p = cross3(dir, e2);
            let det = dot(e1, p);
            if det.abs() < 1e-300 {
                return None;
            }
            let s = [o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]];
            let u = dot(s, p) / det;
            let q = cross3(s, e1);
            let v = dot(dir, q) / det;
            let inside = u >= 0.0
                && v >= 0.0
                && if tri {
                    u + v <= 1.0
                } else {
                    u <= 1.0 && v <= 1.0
                };
            let t = dot(e2, q) / det;
            (inside && t > tmin).then_some(t)
        };
        match self.shape {
            Shape::Sphere { center, radius } => {
                let c = f(center);
                let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
                let a = dot(dir, dir);
                let b = dot(oc, dir);
                let cc = dot(oc, oc) - (radius as f64).powi(2);
                let disc = b * b - a * cc;
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                [(-b - sq) / a, (-b + sq) / a]
                    .into_iter()
                    .find(|&t| t > tmin)
            }
            Shape::Quad { corner, u, v } => parallelogram(f(corner), f(u), f(v), false),
            Shape::Triangle { a, b, c } => parallelogram(f(a), f(sub(b, a)), f(sub(c, a)), true),
        }
    }
}

fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn cross64(a: Vec3, b: Vec3) -> [f64; 3] {
    let f = |v: Vec3| [v[0] as f64, v[1] as f64, v[2] as f64];
    cross3(f(a), f(b))
}

/// The scene files shipped with mcdenoise (`scenes/*.toml`), by name.
const BUILTIN: &[(&str, &str)] = &[
    ("cornell", include_str!("../../scenes/cornell.toml")),
    ("dof", include_str!("../../scenes/dof.toml")),
    ("motion", include_str!("../../scenes/motion.toml")),
    (
        "soft_shadows",
        include_str!("../../scenes/soft_shadows.toml"),
    ),
    ("glossy", include_str!("../../scenes/glossy.toml")),
    ("mix", include_str!("../../scenes/mix.toml")),
    ("hidden_lamp", include_str!("../../scenes/hidden_lamp.toml")),
    ("caustics", include_str!("../../scenes/caustics.toml")),
    (
        "sky_textures",
        include_str!("../../scenes/sky_textures.toml"),
    ),
    (
        "night_lights",
        include_str!("../../scenes/night_lights.toml"),
    ),
    (
        "rough_metals",
        include_str!("../../scenes/rough_metals.toml"),
    ),
    ("fence", include_str!("../../scenes/fence.toml")),
    (
        "window_interior",
        include_str!("../../scenes/window_interior.toml"),
    ),
    ("panel", include_str!("../../scenes/panel.toml")),
    ("fireflies", include_str!("../../scenes/fireflies.toml")),
    ("pan_room", include_str!("../../scenes/pan_room.toml")),
    ("moving_box", include_str!("../../scenes/moving_box.toml")),
    (
        "moving_highlight",
        include_str!("../../scenes/moving_highlight.toml"),
    ),
];

impl Scene {
    /// Parses a scene from TOML text. Relative mesh paths resolve against
    /// `base_dir` (the current directory when `None`). `what` names the
    /// source in error messages.
    pub fn from_toml(text: &str, what: &Path, base_dir: Option<&Path>) -> Result<Scene> {
        let mut scene: Scene =
            toml::from_str(text).map_err(|e| Error::bad_input(what, format!("{e}")))?;
        scene.base_dir = base_dir.map(Path::to_owned);
        scene.validate().map_err(|m| Error::bad_input(what, m))?;
        Ok(scene)
    }

    /// Reads a scene file.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_owned(),
            source,
        })?;
        Scene::from_toml(&text, path, path.parent())
    }

    /// The names of the built-in scenes.
    pub fn builtin_names() -> Vec<&'static str> {
        BUILTIN.iter().map(|(n, _)| *n).collect()
    }

    /// The names of the built-in still scenes (without `[animation]`): the
    /// set the equal-sample tables are measured on.
    pub fn builtin_still_names() -> Vec<&'static str> {
        BUILTIN
            .iter()
            .map(|(n, _)| *n)
            .filter(|n| Scene::builtin(n).is_ok_and(|s| s.animation.is_none()))
            .collect()
    }

    /// A built-in scene by name (see [`builtin_names`](Self::builtin_names)).
    pub fn builtin(name: &str) -> Result<Scene> {
        let (_, text) = BUILTIN.iter().find(|(n, _)| *n == name).ok_or_else(|| {
            Error::InvalidArgument(format!(
                "no built-in scene {name:?}; the built-in scenes are {}",
                Scene::builtin_names().join(", ")
            ))
        })?;
        Scene::from_toml(text, Path::new(&format!("scenes/{name}.toml")), None)
    }

    /// A built-in scene's name or a scene file's path.
    pub fn by_name_or_file(name: &str) -> Result<Scene> {
        if BUILTIN.iter().any(|(n, _)| *n == name) {
            Scene::builtin(name)
        } else if !Path::new(name).exists() {
            Err(Error::InvalidArgument(format!(
                "{name}: neither a scene file nor a built-in scene ({})",
                Scene::builtin_names().join(", ")
            )))
        } else {
            Scene::load(Path::new(name))
        }
    }

    /// The source text of a built-in scene (for caching by content).
    pub fn builtin_source(name: &str) -> Option<&'static str> {
        BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
    }

    /// Checks the scene as [`from_toml`](Self::from_toml) and
    /// [`at_frame`](Self::at_frame) do (the renderer checks a scene built
    /// in code the same way): an error names the offending field.
    pub fn check(&self) -> Result<()> {
        self.validate().map_err(Error::InvalidArgument)
    }

    fn validate(&self) -> std::result::Result<(), String> {
        let c = &self.camera;
        if !(c.fov > 0.0 && c.fov < 180.0) {
            return Err(format!(
                "camera.fov must be in (0, 180) degrees, not {}",
                c.fov
            ));
        }
        check_point("camera.position", c.position)?;
        check_point("camera.look_at", c.look_at)?;
        if !c.up.iter().all(|x| x.is_finite()) {
            return Err(format!("camera.up must be finite, not {:?}", c.up));
        }
        check_length("camera.aperture", c.aperture, true)?;
        if let Some(f) = c.focus_distance {
            check_length("camera.focus_distance", f, false)?;
        }
        if sub(c.look_at, c.position) == [0.0; 3] {
            return Err("camera.look_at equals camera.position".into());
        }
        // The camera's right vector is view direction × up.
        let (dir, up) = (sub(c.look_at, c.position), c.up);
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let widen = |v: Vec3| v.map(f64::from);
        if norm(cross64(dir, up)) <= 1e-6 * norm(widen(dir)) * norm(widen(up)) {
            return Err(format!(
                "camera.up {up:?} must be non-zero and not parallel to the view direction"
            ));
        }
        check_colour("environment", self.environment, f32::INFINITY)?;
        for (name, m) in &self.materials {
            let ior = match m {
                Material::Plastic { ior, .. } | Material::Dielectric { ior, .. } => *ior,
                _ => 1.0,
            };
            if !(ior > 0.0 && ior.is_finite()) {
                return Err(format!(
                    "material {name:?}: ior must be positive, not {ior}"
                ));
            }
            let field = |f: &str| format!("material {name:?}: {f}");
            match m {
                Material::Diffuse { albedo } | Material::Plastic { albedo, .. } => {
                    check_albedo(&field("albedo"), albedo, 1.0)?
                }
                Material::Conductor { color, .. } => {
                    check_colour(&field("color"), *color, f32::INFINITY)?
                }
                Material::Dielectric { tint, .. } => {
                    check_colour(&field("tint"), *tint, f32::INFINITY)?
                }
                Material::Emissive { radiance, .. } => {
                    check_albedo(&field("radiance"), radiance, f32::INFINITY)?
                }
            }
            if let Material::Conductor { roughness, .. }
            | Material::Plastic { roughness, .. }
            | Material::Dielectric { roughness, .. } = m
            {
                if !roughness.is_finite() {
                    return Err(format!(
                        "material {name:?}: roughness must be finite, not {roughness}"
                    ));
                }
            }
        }
        let increasing = |frames: &mut dyn Iterator<Item = f32>| {
            let v: Vec<f32> = frames.collect();
            v.iter().all(|f| f.is_finite()) && v.windows(2).all(|w| w[0] < w[1])
        };
        if let Some(a) = &self.animation {
            if a.frames == 0 {
                return Err("animation.frames must be at least 1".into());
            }
            if !increasing(&mut a.camera.iter().map(|k| k.frame)) {
                return Err("animation.camera keyframes must be in increasing frame order".into());
            }
            for (k, key) in a.camera.iter().enumerate() {
                let field = |f: &str| format!("animation.camera keyframe {k}: {f}");
                if let Some(p) = key.position {
                    check_point(&field("position"), p)?;
                }
                if let Some(p) = key.look_at {
                    check_point(&field("look_at"), p)?;
                }
                if let Some(f) = key.focus_distance {
                    check_length(&field("focus_distance"), f, false)?;
                }
            }
        }
        for (i, o) in self.objects.iter().enumerate() {
            if !increasing(&mut o.keyframes().iter().map(|k| k.frame)) {
                return Err(format!(
                    "object {i}: keyframes must be in increasing frame order"
                ));
            }
            for (k, key) in o.keyframes().iter().enumerate() {
                let field = |f: &str| format!("object {i} keyframe {k}: {f}");
                check_point(&field("translate"), key.translate)?;
                check_angle(&field("rotate_y"), key.rotate_y)?;
            }
            o.validate_geometry(&|f: &str| format!("object {i}: {f}"))?;
        }
        for (i, o) in self.objects.iter().enumerate() {
            let m = match o {
                Object::Sphere { material, .. }
                | Object::Quad { material, .. }
                | Object::Box { material, .. }
                | Object::Mesh { material, .. } => material,
            };
            if !self.materials.contains_key(m) {
                return Err(format!("object {i} uses the undefined material {m:?}"));
            }
        }
        Ok(())
    }

    /// The materials in index order (the order of their names).
    pub fn material_list(&self) -> Vec<(&str, &Material)> {
        self.materials
            .iter()
            .map(|(n, m)| (n.as_str(), m))
            .collect()
    }

    fn material_index(&self, name: &str) -> u32 {
        self.materials
            .keys()
            .position(|k| k == name)
            .expect("validated") as u32
    }

    /// The scene's primitives, in object order (meshes loaded from disk).
    pub fn primitives(&self) -> Result<Vec<Primitive>> {
        let mut out = Vec::new();
        for (index, o) in self.objects.iter().enumerate() {
            let first = out.len();
            match o {
                Object::Sphere {
                    center,
                    radius,
                    material,
                    motion,
                    ..
                } => out.push(Primitive {
                    shape: Shape::Sphere {
                        center: *center,
                        radius: *radius,
                    },
                    material: self.material_index(material),
                    motion: motion.unwrap_or_default(),
                    normals: None,
                    rest: None,
                }),
                Object::Quad {
                    corner,
                    u,
                    v,
                    material,
                    motion,
                    ..
                } => out.push(Primitive {
                    shape: Shape::Quad {
                        corner: *corner,
                        u: *u,
                        v: *v,
                    },
                    material: self.material_index(material),
                    motion: motion.unwrap_or_default(),
                    normals: None,
                    rest: None,
                }),
                Object::Box {
                    min,
                    max,
                    rotate_y,
                    material,
                    motion,
                    ..
                } => {
                    let m = self.material_index(material);
                    for shape in box_quads(*min, *max, *rotate_y) {
                        out.push(Primitive {
                            shape,
                            material: m,
                            motion: motion.unwrap_or_default(),
                            normals: None,
                            rest: None,
                        });
                    }
                }
                Object::Mesh {
                    file,
                    vertices,
                    indices,
                    normals,
                    scale,
                    translate,
                    material,
                    motion,
                    ..
                } => {
                    let (verts, tris, norms) = match file {
                        Some(f) => self.load_obj(f)?,
                        None => (vertices.clone(), indices.clone(), normals.clone()),
                    };
                    if !norms.is_empty() && norms.len() != verts.len() {
                        return Err(Error::InvalidArgument(format!(
                            "a mesh has {} normals for {} vertices",
                            norms.len(),
                            verts.len()
                        )));
                    }
                    let m = self.material_index(material);
                    let get = |i: u32| -> Result<usize> {
                        ((i as usize) < verts.len())
                            .then_some(i as usize)
                            .ok_or_else(|| {
                                Error::InvalidArgument(format!(
                                    "mesh index {i} out of range ({} vertices)",
                                    verts.len()
                                ))
                            })
                    };
                    let place = |i: usize| {
                        let p = verts[i];
                        add([p[0] * scale, p[1] * scale, p[2] * scale], *translate)
                    };
                    // An OBJ file's numbers, and inline ones once scaled.
                    let field = |f: &str| format!("object {index}: {f}");
                    for k in 0..verts.len() {
                        check_point(&field(&format!("vertex {k} (placed)")), place(k))
                            .map_err(Error::InvalidArgument)?;
                    }
                    check_normals(&field, &norms).map_err(Error::InvalidArgument)?;
                    for t in tris {
                        let [i, j, k] = [get(t[0])?, get(t[1])?, get(t[2])?];
                        out.push(Primitive {
                            shape: Shape::Triangle {
                                a: place(i),
                                b: place(j),
                                c: place(k),
                            },
                            material: m,
                            motion: motion.unwrap_or_default(),
                            normals: (!norms.is_empty()).then(|| [norms[i], norms[j], norms[k]]),
                            rest: None,
                        });
                    }
                }
            }
            let keys = o.keyframes();
            if !keys.is_empty() {
                place(&mut out[first..], keys, self.frame);
            }
        }
        Ok(out)
    }

    /// Frames of the scene's sequence: `[animation] frames`, 1 for a still.
    pub fn frames(&self) -> u32 {
        self.animation.as_ref().map_or(1, |a| a.frames)
    }

    /// The scene at frame `frame` of its sequence: the camera and every
    /// keyframed object placed there, each keyframed object moving over
    /// the shutter by its translation to the next frame (a 360° shutter;
    /// rotations and the camera are not blurred). Textures move with their
    /// objects ([`Primitive::rest`]).
    pub fn at_frame(&self, frame: u32) -> Result<Scene> {
        if frame >= self.frames() {
            return Err(Error::InvalidArgument(format!(
                "frame {frame} is outside the scene's frames 0..{}",
                self.frames()
            )));
        }
        let mut s = self.clone();
        s.frame = frame as f32;
        if let Some(a) = &self.animation {
            let f = frame as f32;
            let keys = |get: fn(&CameraKey) -> Option<Vec3>| -> Vec<(f32, Vec3)> {
                a.camera
                    .iter()
                    .filter_map(|k| get(k).map(|v| (k.frame, v)))
                    .collect()
            };
            if let Some(p) = interpolate(&keys(|k| k.position), f) {
                s.camera.position = p;
            }
            if let Some(p) = interpolate(&keys(|k| k.look_at), f) {
                s.camera.look_at = p;
            }
            let focus: Vec<(f32, [f32; 1])> = a
                .camera
                .iter()
                .filter_map(|k| k.focus_distance.map(|d| (k.frame, [d])))
                .collect();
            if let Some([d]) = interpolate(&focus, f) {
                s.camera.focus_distance = Some(d);
            }
        }
        s.validate()
            .map_err(|m| Error::InvalidArgument(format!("the scene at frame {frame}: {m}")))?;
        Ok(s)
    }

    #[allow(clippy::type_complexity)] // (positions, triangles, normals)
    fn load_obj(&self, file: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>, Vec<Vec3>)> {
        let path = match &self.base_dir {
            Some(d) if file.is_relative() => d.join(file),
            _ => file.to_owned(),
        };
        let (models, _) = tobj::load_obj(&path, &tobj::GPU_LOAD_OPTIONS)
            .map_err(|e| Error::bad_input(&path, format!("cannot read the OBJ file: {e}")))?;
        let with_normals = models
            .iter()
            .all(|m| m.mesh.normals.len() == m.mesh.positions.len());
        let mut verts = Vec::new();
        let mut tris = Vec::new();
        let mut norms = Vec::new();
        for m in models {
            let base = verts.len() as u32;
            verts.extend(m.mesh.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
            if with_normals {
                norms.extend(m.mesh.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]));
            }
            tris.extend(
                m.mesh
                    .indices
                    .chunks_exact(3)
                    .map(|t| [base + t[0], base + t[1], base + t[2]]),
            );
        }
        Ok((verts, tris, norms))
    }
}

/// The rotation by `degrees` about the vertical axis (a vector's, about the
/// origin): how boxes and keyframes turn.
fn rotation_y(degrees: f32) -> impl Fn(Vec3) -> Vec3 + Copy {
    let (s, c) = degrees.to_radians().sin_cos();
    move |v: Vec3| [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]]
}

/// The six outward-facing faces of a box rotated about the vertical axis
/// through its centre.
fn box_quads(min: Vec3, max: Vec3, rotate_y: f32) -> Vec<Shape> {
    let c = [
        0.5 * (min[0] + max[0]),
        0.5 * (min[1] + max[1]),
        0.5 * (min[2] + max[2]),
    ];
    let rot = rotation_y(rotate_y);
    let pt = |p: Vec3| add(rot(sub(p, c)), c);
    let d = sub(max, min);
    let (dx, dy, dz) = ([d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]);
    let q = |corner: Vec3, u: Vec3, v: Vec3| Shape::Quad {
        corner: pt(corner),
        u: rot(u),
        v: rot(v),
    };
    let hi = max;
    // Edge order does not matter here: orient_outward fixes the front side.
    vec![
        q(min, dz, dx),
        q([min[0], hi[1], min[2]], dx, dz),
        q(min, dy, dz),
        q([hi[0], min[1], min[2]], dz, dy),
        q(min, dx, dy),
        q([min[0], min[1], hi[2]], dy, dx),
    ]
    .into_iter()
    .map(|s| orient_outward(s, pt(c)))
    .collect()
}

/// Swaps a quad's edges if its front (u × v) faces towards `centre`.
fn orient_outward(s: Shape, centre: Vec3) -> Shape {
    match s {
        Shape::Quad { corner, u, v } => {
            let n = cross64(u, v);
            let mid = add(
                corner,
                [
                    0.5 * (u[0] + v[0]),
                    0.5 * (u[1] + v[1]),
                    0.5 * (u[2] + v[2]),
                ],
            );
            let out = sub(mid, centre);
            let d = n[0] * out[0] as f64 + n[1] * out[1] as f64 + n[2] * out[2] as f64;
            if d < 0.0 {
                Shape::Quad { corner, u: v, v: u }
            } else {
                s
            }
        }
        s => s,
    }
}

/// The largest magnitude of any coordinate, offset or length in a scene,
/// world units: f32 positions near 1e8 are 8 units apart, and beyond it the
/// renderer's sums of squared positions leave f32 range.
pub const MAX_COORDINATE: f32 = 1e8;

/// `what` (a point or vector) is finite, each component within
/// ±[`MAX_COORDINATE`].
fn check_point(what: &str, v: Vec3) -> std::result::Result<(), String> {
    if v.iter().all(|x| x.is_finite() && x.abs() <= MAX_COORDINATE) {
        Ok(())
    } else {
        Err(format!(
            "{what} must be finite, each component within ±{MAX_COORDINATE:e}, not {v:?}"
        ))
    }
}

/// `what` (a length) is finite, positive (or 0 if `zero_ok`) and at most
/// [`MAX_COORDINATE`].
fn check_length(what: &str, x: f32, zero_ok: bool) -> std::result::Result<(), String> {
    let low_ok = if zero_ok { x >= 0.0 } else { x > 0.0 };
    if low_ok && x <= MAX_COORDINATE {
        Ok(())
    } else {
        let low = if zero_ok { "≥ 0" } else { "> 0" };
        Err(format!(
            "{what} must be {low} and at most {MAX_COORDINATE:e}, not {x}"
        ))
    }
}

/// `what` (an angle in degrees) is finite.
fn check_angle(what: &str, x: f32) -> std::result::Result<(), String> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(format!("{what} must be finite, not {x}"))
    }
}

/// `what` (a colour) is finite with every component in `[0, max]`.
fn check_colour(what: &str, v: Vec3, max: f32) -> std::result::Result<(), String> {
    if v.iter().all(|x| x.is_finite() && *x >= 0.0 && *x <= max) {
        Ok(())
    } else if max.is_finite() {
        Err(format!(
            "{what} must have every component in [0, {max}], not {v:?}"
        ))
    } else {
        Err(format!("{what} must be finite and non-negative, not {v:?}"))
    }
}

/// An albedo or radiance: its colours as [`check_colour`], a texture's
/// `scale` finite.
fn check_albedo(what: &str, albedo: &Albedo, max: f32) -> std::result::Result<(), String> {
    match albedo {
        Albedo::Constant(c) => check_colour(what, *c, max),
        Albedo::Texture(Texture::Checker { a, b, scale } | Texture::Noise { a, b, scale }) => {
            check_colour(&format!("{what}.a"), *a, max)?;
            check_colour(&format!("{what}.b"), *b, max)?;
            check_angle(&format!("{what}.scale"), *scale)
        }
    }
}

impl Object {
    /// Checks the object's own numbers (not its keyframes); `field` names
    /// a field in an error message.
    fn validate_geometry(&self, field: &dyn Fn(&str) -> String) -> std::result::Result<(), String> {
        let motion = match self {
            Object::Sphere {
                center,
                radius,
                motion,
                ..
            } => {
                check_point(&field("center"), *center)?;
                check_length(&field("radius"), *radius, false)?;
                motion
            }
            Object::Quad {
                corner,
                u,
                v,
                motion,
                ..
            } => {
                check_point(&field("corner"), *corner)?;
                check_point(&field("u"), *u)?;
                check_point(&field("v"), *v)?;
                motion
            }
            Object::Box {
                min,
                max,
                rotate_y,
                motion,
                ..
            } => {
                check_point(&field("min"), *min)?;
                check_point(&field("max"), *max)?;
                check_angle(&field("rotate_y"), *rotate_y)?;
                motion
            }
            Object::Mesh {
                vertices,
                normals,
                scale,
                translate,
                motion,
                ..
            } => {
                for (k, p) in vertices.iter().enumerate() {
                    check_point(&field(&format!("vertex {k}")), *p)?;
                }
                check_normals(field, normals)?;
                if !(scale.is_finite() && scale.abs() <= MAX_COORDINATE) {
                    return Err(format!(
                        "{} must be finite and within ±{MAX_COORDINATE:e}, not {scale}",
                        field("scale")
                    ));
                }
                check_point(&field("translate"), *translate)?;
                motion
            }
        };
        if let Some(m) = motion {
            check_point(&field("motion"), *m)?;
        }
        Ok(())
    }
}

/// A mesh's normals are finite.
fn check_normals(
    field: &dyn Fn(&str) -> String,
    normals: &[Vec3],
) -> std::result::Result<(), String> {
    match normals
        .iter()
        .position(|n| !n.iter().all(|x| x.is_finite()))
    {
        Some(k) => Err(format!(
            "{} must be finite, not {:?}",
            field(&format!("normal {k}")),
            normals[k]
        )),
        None => Ok(()),
    }
}

impl Object {
    /// The object's keyframes (empty when it is not animated).
    pub fn keyframes(&self) -> &[Keyframe] {
        match self {
            Object::Sphere { keyframes, .. }
            | Object::Quad { keyframes, .. }
            | Object::Box { keyframes, .. }
            | Object::Mesh { keyframes, .. } => keyframes,
        }
    }
}

/// The value at frame `f` of keys `(frame, value)` in increasing frame
/// order: linear between two keys, the first or last key's outside them;
/// `None` without keys.
fn interpolate<const N: usize>(keys: &[(f32, [f32; N])], f: f32) -> Option<[f32; N]> {
    let (first, last) = (keys.first()?, keys.last()?);
    if f <= first.0 {
        return Some(first.1);
    }
    if f >= last.0 {
        return Some(last.1);
    }
    let i = keys.iter().position(|k| k.0 > f)?;
    let ((f0, a), (f1, b)) = (keys[i - 1], keys[i]);
    let t = (f - f0) / (f1 - f0);
    Some(std::array::from_fn(|k| a[k] + t * (b[k] - a[k])))
}

/// Places one object's primitives (at rest) at frame `frame` of `keys`:
/// rotated about the vertical axis through their bounding box's centre,
/// translated, and moving over the shutter by the translation to the next
/// frame on top of their own `motion`; each records the inverse placement
/// in [`Primitive::rest`].
fn place(prims: &mut [Primitive], keys: &[Keyframe], frame: f32) {
    let translate: Vec<(f32, Vec3)> = keys.iter().map(|k| (k.frame, k.translate)).collect();
    let rotate: Vec<(f32, [f32; 1])> = keys.iter().map(|k| (k.frame, [k.rotate_y])).collect();
    let at = |f: f32| interpolate(&translate, f).unwrap_or_default();
    let (t0, t1) = (at(frame), at(frame + 1.0));
    let [r0] = interpolate(&rotate, frame).unwrap_or_default();
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in prims.iter() {
        let (a, b) = Primitive {
            motion: [0.0; 3],
            ..*p
        }
        .bounds();
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    let c = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
    let rot = rotation_y(r0);
    let pt = |p: Vec3| add(add(rot(sub(p, c)), c), t0);
    // rest(p) = R⁻¹(p − c − t0) + c: columns R⁻¹ eₖ, offset c − R⁻¹(c + t0).
    let back = rotation_y(-r0);
    let cols = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]].map(back);
    let offset = sub(c, back(add(c, t0)));
    let rest: [[f32; 4]; 3] =
        std::array::from_fn(|i| [cols[0][i], cols[1][i], cols[2][i], offset[i]]);
    for p in prims {
        p.shape = match p.shape {
            Shape::Sphere { center, radius } => Shape::Sphere {
                center: pt(center),
                radius,
            },
            Shape::Quad { corner, u, v } => Shape::Quad {
                corner: pt(corner),
                u: rot(u),
                v: rot(v),
            },
            Shape::Triangle { a, b, c } => Shape::Triangle {
                a: pt(a),
                b: pt(b),
                c: pt(c),
            },
        };
        p.normals = p.normals.map(|n| n.map(rot));
        p.motion = add(rot(p.motion), sub(t1, t0));
        p.rest = Some(rest);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(text: &str) -> Scene {
        Scene::from_toml(text, Path::new("test.toml"), None).unwrap()
    }

    const ANIMATED: &str = r#"
[camera]
position = [0.0, 1.0, 4.0]
look_at = [0.0, 1.0, 0.0]
fov = 40.0

[materials.m]
type = "diffuse"
albedo = [0.5, 0.5, 0.5]

[[objects]]
type = "quad"
corner = [-1.0, 0.0, 0.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "m"
keyframes = [
    { frame = 0, translate = [0.0, 0.0, 0.0] },
    { frame = 10, translate = [1.0, 0.0, 0.0], rotate_y = 90.0 },
]

[[objects]]
type = "sphere"
center = [0.0, 0.5, 1.0]
radius = 0.5
material = "m"

[animation]
frames = 11

[[animation.camera]]
frame = 0
position = [0.0, 1.0, 4.0]

[[animation.camera]]
frame = 10
position = [2.0, 1.0, 4.0]
focus_distance = 3.0
"#;

    fn close(a: Vec3, b: Vec3) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 1e-5)
    }

    /// Keyframes interpolate linearly and hold outside their range; the
    /// camera's keyed properties follow theirs, the others keep `[camera]`.
    #[test]
    fn frames_place_the_camera_and_the_keyframed_objects() {
        let s = scene(ANIMATED);
        assert_eq!(s.frames(), 11);
        let mid = s.at_frame(5).unwrap();
        assert!(close(mid.camera.position, [1.0, 1.0, 4.0]));
        assert!(close(mid.camera.look_at, [0.0, 1.0, 0.0]));
        assert_eq!(mid.camera.focus_distance, Some(3.0));
        let p = mid.primitives().unwrap();
        // Halfway: rotated 45° about the quad's centre (0, 1, 0), moved
        // by 0.5 in x, and moving 0.1 in x over the shutter.
        let Shape::Quad { corner, u, v } = p[0].shape else {
            panic!("{:?}", p[0].shape)
        };
        let h = std::f32::consts::FRAC_1_SQRT_2;
        assert!(close(corner, [0.5 - h, 0.0, h]), "{corner:?}");
        assert!(close(u, [2.0 * h, 0.0, -2.0 * h]), "{u:?}");
        assert!(close(v, [0.0, 2.0, 0.0]));
        assert!(close(p[0].motion, [0.1, 0.0, 0.0]), "{:?}", p[0].motion);
        // Its points map back to where the file puts them.
        assert!(close(p[0].rest_point(corner), [-1.0, 0.0, 0.0]));
        let far = add(add(corner, u), v);
        assert!(close(p[0].rest_point(far), [1.0, 2.0, 0.0]), "{far:?}");
        // The sphere has no keyframes: where the file puts it, at rest.
        assert_eq!(p[1], s.primitives().unwrap()[1]);
        assert_eq!(p[1].rest, None);
        // The last frame holds the last keyframe; nothing moves after it.
        let last = s.at_frame(10).unwrap().primitives().unwrap();
        assert!(close(last[0].motion, [0.0; 3]));
        assert!(s.at_frame(11).is_err());
        // A still scene has one frame, itself.
        let still = scene(&ANIMATED.replace("[animation]\nframes = 11", "").replace(
            "[[animation.camera]]\nframe = 0\nposition = [0.0, 1.0, 4.0]\n\n[[animation.camera]]\nframe = 10\nposition = [2.0, 1.0, 4.0]\nfocus_distance = 3.0\n",
            "",
        ));
        assert_eq!(still.frames(), 1);
        assert!(still.at_frame(1).is_err());
    }

    #[test]
    fn keyframes_out_of_order_are_refused() {
        let text = ANIMATED.replace("{ frame = 10, translate", "{ frame = 0, translate");
        let e = Scene::from_toml(&text, Path::new("t.toml"), None).unwrap_err();
        assert!(e.to_string().contains("increasing frame order"), "{e}");
        let text = ANIMATED.replace("frames = 11", "frames = 0");
        assert!(Scene::from_toml(&text, Path::new("t.toml"), None).is_err());
    }
}
