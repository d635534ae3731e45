//! The benchmarks behind `mcdenoise bench`: a **quality** benchmark over a
//! folder of scenes with references, and a **timing** benchmark of whole
//! denoise calls. Both run every method through [`methods::denoise`], the
//! same entry point as the CLI, so a method shows up here as soon as
//! [`Method::available`] says it is built.
//!
//! # Cases and filters
//! Every measurement is a *case* with a dotted name:
//!
//! | benchmark | case name | example |
//! |---|---|---|
//! | quality | `method.scene.sppN` (`input.scene.sppN` for the noisy input) | `wlr.dof_checker.spp16` |
//! | timing | `method.inputs.WxH` | `none.synthetic.256x256` |
//!
//! The backend is a column of its own (the same case name can run on both).
//! A filter ([`case_matches`]) selects cases by substring; `a|b` selects the
//! cases matching either alternative.
//!
//! # Quality ([`run_quality`])
//! A folder laid out like `../shared/data/scenes/`: one subfolder per scene
//! holding `sppN.exr` render-statistics files and a `reference.exr` (a folder
//! that itself holds `sppN.exr` files is taken as a single scene). For every
//! scene × spp the noisy input's colour is scored (the `input` row), then
//! every method × backend (on the GPU, the first call of each method is
//! preceded by an untimed warm-up on a 32×32 crop, which builds the
//! pipelines): the denoise call's wall-clock time, its GPU time
//! (sum of the returned [`KernelTiming`]s) and the [`Metrics`] of its colour
//! against the reference. When the method returns an error estimate, the row
//! also holds [`error_correlation`] and [`naive_correlation`]. A file that is
//! missing or unreadable skips the cases that need it with a warning naming
//! the file; the rest of the table is still produced.
//!
//! # Timing ([`run_timing`])
//! One input (the deterministic [`synthetic`] frame, or a render-statistics
//! file, optionally centre-cropped) denoised by every method × backend: one
//! warm-up call (pipelines built, allocations made), then `runs` timed calls.
//! Reported per case: the median wall time, milliseconds per megapixel, and
//! the GPU time per kernel from the device's timestamp queries
//! ([`timings_per_kernel`]).
//!
//! # Output
//! Reports render as Markdown ([`QualityReport::to_markdown`],
//! [`TimingReport::to_markdown`]) and as JSON (`to_json`, written by hand:
//! non-finite numbers become `null`, absent values are `null`).

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::gpu::{timings_per_kernel, GpuContext, KernelTiming};
use crate::image::{Layer, RgbImage, StatsImage};
use crate::io;
use crate::methods::{self, Backend, DenoiseOutput, DenoiseRequest, Method};
use crate::metrics::{self, Metrics};

/// Every method of the spec, in the order the benchmarks run them.
pub const ALL_METHODS: [Method; 5] = [
    Method::None,
    Method::Wlr,
    Method::Lp,
    Method::Apr,
    Method::Aos,
];

/// The method called `name` ([`Method::name`]: `none`, `wlr`, `lp`, `apr`,
/// `aos`; case-insensitive).
pub fn method_from_name(name: &str) -> Option<Method> {
    ALL_METHODS
        .into_iter()
        .find(|m| m.name().eq_ignore_ascii_case(name.trim()))
}

/// `"gpu"` or `"cpu"`: the backend column of the tables.
pub fn backend_name(b: Backend) -> &'static str {
    match b {
        Backend::Gpu => "gpu",
        Backend::Cpu => "cpu",
    }
}

/// Whether the case `name` is selected by `filter`: no filter (or an empty
/// one) selects everything; otherwise the filter is split at `|` and the case
/// is selected if its name contains any of the alternatives (plain substring
/// matching, case-sensitive).
pub fn case_matches(name: &str, filter: Option<&str>) -> bool {
    match filter {
        None | Some("") => true,
        Some(f) => f.split('|').any(|alt| name.contains(alt)),
    }
}

/// Parses `WxH` (e.g. `256x256`; `X` accepted too) into `(width, height)`,
/// both ≥ 1 and within [`io::MAX_DIMENSION`].
pub fn parse_size(s: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::InvalidArgument(format!(
            "size `{s}`: expected WIDTHxHEIGHT, e.g. 256x256, each 1..={}",
            io::MAX_DIMENSION
        ))
    };
    let (w, h) = s.trim().split_once(['x', 'X']).ok_or_else(bad)?;
    let w: usize = w.trim().parse().map_err(|_| bad())?;
    let h: usize = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 || w > io::MAX_DIMENSION || h > io::MAX_DIMENSION {
        return Err(bad());
    }
    Ok((w, h))
}

/// Something a benchmark wants the user to see while it runs.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Note<'a> {
    /// Which case runs now (quiet runs drop these).
    Progress(&'a str),
    /// A case was skipped or a method is not built; also kept in the report.
    Warning(&'a str),
}

/// The methods to run: `requested` deduplicated in order (all of
/// [`ALL_METHODS`] when empty), split into (available, not built).
fn select_methods(requested: &[Method]) -> (Vec<Method>, Vec<Method>) {
    let wanted: Vec<Method> = if requested.is_empty() {
        ALL_METHODS.to_vec()
    } else {
        let mut v = Vec::new();
        for &m in requested {
            if !v.contains(&m) {
                v.push(m);
            }
        }
        v
    };
    let explicit = !requested.is_empty();
    let (ok, missing): (Vec<Method>, Vec<Method>) = wanted.into_iter().partition(|m| m.available());
    // With the default list, methods that are not built are simply not run.
    (ok, if explicit { missing } else { Vec::new() })
}

fn dedup_backends(b: &[Backend]) -> Vec<Backend> {
    let mut v = Vec::new();
    for &x in if b.is_empty() { &[Backend::Gpu][..] } else { b } {
        if !v.contains(&x) {
            v.push(x);
        }
    }
    v
}

fn check_context(ctx: Option<&Arc<GpuContext>>, backends: &[Backend]) -> Result<()> {
    if backends.contains(&Backend::Gpu) && ctx.is_none() {
        return Err(Error::InvalidArgument(
            "the GPU backend needs a Vulkan context".into(),
        ));
    }
    Ok(())
}

/// The request the benchmarks send: the method's defaults, the error estimate
/// asked for whenever the method can have one (every method but `none`).
fn request(method: Method, backend: Backend) -> DenoiseRequest {
    let mut req = DenoiseRequest::new(method);
    req.backend = backend;
    req.error = method != Method::None;
    req
}

/// Sum of the GPU times in milliseconds; `None` when nothing was timed (the
/// CPU backend, or a method that reports no timings).
fn gpu_ms(t: &[KernelTiming]) -> Option<f64> {
    (!t.is_empty()).then(|| t.iter().map(|k| k.nanoseconds).sum::<f64>() / 1e6)
}

/// The colour layer of a statistics image, as stored (no sanitation).
fn colour_layer(img: &StatsImage) -> Option<RgbImage> {
    let c = img.get(Layer::Color)?;
    Some(RgbImage::from_planes(
        img.width,
        img.height,
        [c[0].clone(), c[1].clone(), c[2].clone()],
    ))
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

// ---------------------------------------------------------------------------
// Error-estimate quality
// ---------------------------------------------------------------------------

/// Side of the square tiles the error correlations average over (pixels).
pub const CORRELATION_TILE: usize = 8;

/// Means of a per-pixel value over non-overlapping `tile × tile` tiles,
/// row-major by tile. Tiles cut by the right or bottom border are kept and
/// averaged over the pixels they hold.
pub fn tile_means(
    width: usize,
    height: usize,
    tile: usize,
    value: impl Fn(usize) -> f64,
) -> Vec<f64> {
    assert!(tile > 0, "tile_means: tile size 0");
    let (tw, th) = (width.div_ceil(tile), height.div_ceil(tile));
    let mut sum = vec![0.0f64; tw * th];
    let mut count = vec![0usize; tw * th];
    for y in 0..height {
        for x in 0..width {
            let t = (y / tile) * tw + x / tile;
            sum[t] += value(y * width + x);
            count[t] += 1;
        }
    }
    sum.iter().zip(&count).map(|(s, &n)| s / n as f64).collect()
}

/// Pearson correlation of two equally long samples, in f64. NaN if there are
/// fewer than two values, if either sample is constant, or if any value is
/// non-finite (a broken map never scores well).
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "pearson: lengths differ");
    let n = a.len();
    if n < 2 || a.iter().chain(b).any(|v| !v.is_finite()) {
        return f64::NAN;
    }
    let ma = a.iter().sum::<f64>() / n as f64;
    let mb = b.iter().sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (dx, dy) = (x - ma, y - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    if saa == 0.0 || sbb == 0.0 {
        return f64::NAN;
    }
    sab / (saa * sbb).sqrt()
}

/// How well an estimated per-pixel MSE map predicts the actual error.
///
/// Per pixel: the estimate is the mean over the three channels of `est`
/// (estimated MSE of `out`), the truth is the mean over the channels of
/// `(out − reference)²`. Both maps are averaged over non-overlapping
/// [`CORRELATION_TILE`]` × `[`CORRELATION_TILE`] tiles (8×8; border tiles
/// partly outside the image are averaged over their pixels inside it), which
/// takes out most of the single-pixel noise of the squared error, and the
/// result is the Pearson correlation ([`pearson`]) of the two tile maps, in
/// [−1, 1]: 1 means the estimate is a perfect linear predictor of where the
/// error is. NaN if the image has fewer than two tiles, either tile map is
/// constant, or any value is non-finite.
///
/// # Panics
/// If the three images differ in size (a programming error; check with
/// [`metrics::check_same_size`] first for user input).
pub fn error_correlation(est: &RgbImage, out: &RgbImage, reference: &RgbImage) -> f64 {
    for (what, img) in [("estimate", est), ("reference", reference)] {
        assert!(
            (img.width, img.height) == (out.width, out.height),
            "error_correlation: {what} is {}x{}, the output {}x{}",
            img.width,
            img.height,
            out.width,
            out.height
        );
    }
    let (w, h) = (out.width, out.height);
    let estimated = tile_means(w, h, CORRELATION_TILE, |i| {
        est.planes.iter().map(|p| p[i] as f64).sum::<f64>() / 3.0
    });
    let actual = tile_means(w, h, CORRELATION_TILE, |i| {
        (0..3)
            .map(|c| {
                let d = out.planes[c][i] as f64 - reference.planes[c][i] as f64;
                d * d
            })
            .sum::<f64>()
            / 3.0
    });
    pearson(&estimated, &actual)
}

/// The baseline for [`error_correlation`]: the same correlation with the
/// input's own variance of the mean (`color_variance`, channel mean) in place
/// of the method's estimate, against the same output's actual error. A method's
/// estimate is worth something where it beats this. `None` if `input` has no
/// `color_variance` layer.
///
/// # Panics
/// If `input`, `out` and `reference` differ in size.
pub fn naive_correlation(input: &StatsImage, out: &RgbImage, reference: &RgbImage) -> Option<f64> {
    let v = input.get(Layer::ColorVariance)?;
    let var = RgbImage::from_planes(
        input.width,
        input.height,
        [v[0].clone(), v[1].clone(), v[2].clone()],
    );
    Some(error_correlation(&var, out, reference))
}

// ---------------------------------------------------------------------------
// Synthetic frame
// ---------------------------------------------------------------------------

/// The sample count of the synthetic frame the timing benchmark uses.
pub const SYNTHETIC_SPP: u32 = 16;

/// A generated frame and the noise-free colour it was drawn around.
#[derive(Clone, Debug)]
pub struct Synthetic {
    /// All layers of the input format: colour, albedo, normal, depth,
    /// position (each with its variance), position covariance and spp.
    pub stats: StatsImage,
    /// The expected colour (the noise-free image): a perfect reference.
    pub clean: RgbImage,
}

/// SplitMix64: a tiny deterministic generator, one stream per pixel.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1].
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller, one value per call).
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// A draw of χ²ₖ / k (Wilson–Hilferty: `(1 − 2/(9k) + z·√(2/(9k)))³`,
    /// clamped at 0), the distribution of an unbiased sample variance over σ²
    /// with k = n − 1 degrees of freedom.
    fn chi2_over_k(&mut self, k: f64) -> f64 {
        let a = 2.0 / (9.0 * k);
        (1.0 - a + self.normal() * a.sqrt()).max(0.0).powi(3)
    }
}

type V3 = [f64; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / dot(a, a).sqrt())
}

/// The spheres of the synthetic scene: centre, radius, albedo.
const SPHERES: [(V3, f64, V3); 3] = [
    ([-1.2, -0.2, 0.0], 0.8, [0.80, 0.20, 0.15]),
    ([0.6, -0.4, -0.8], 0.6, [0.20, 0.45, 0.80]),
    ([1.6, -0.65, 0.9], 0.35, [0.90, 0.85, 0.30]),
];
/// The ground: the square `|x|, |z| ≤ GROUND_HALF_SIZE` of the plane `y = GROUND_Y`.
const GROUND_Y: f64 = -1.0;
const GROUND_HALF_SIZE: f64 = 12.0;

/// Nearest sphere hit along `o + t d` (`d` unit) with `t > tmin`: (t, index).
fn hit_sphere(o: V3, d: V3, tmin: f64) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (k, (c, r, _)) in SPHERES.iter().enumerate() {
        let oc = sub(o, *c);
        let b = dot(oc, d);
        let disc = b * b - (dot(oc, oc) - r * r);
        if disc < 0.0 {
            continue;
        }
        let s = disc.sqrt();
        for t in [-b - s, -b + s] {
            if t > tmin && best.map_or(true, |(bt, _)| t < bt) {
                best = Some((t, k));
                break;
            }
        }
    }
    best
}

/// What the camera ray of one pixel sees, noise-free.
struct Hit {
    colour: V3,
    /// `None` for a miss (sky): every feature is then 0.
    surface: Option<Surface>,
}

struct Surface {
    albedo: V3,
    normal: V3,
    depth: f64,
    position: V3,
}

fn trace(o: V3, d: V3) -> Hit {
    let sun_dir = normalize([-0.4, 1.0, 0.5]);
    let sun: V3 = [2.4, 2.2, 1.9];
    let ambient: V3 = [0.25, 0.30, 0.40];
    let sphere = hit_sphere(o, d, 1e-6);
    let ground = (d[1] < 0.0).then(|| (GROUND_Y - o[1]) / d[1]).filter(|&t| {
        let p = add(o, scale(d, t));
        p[0].abs() <= GROUND_HALF_SIZE && p[2].abs() <= GROUND_HALF_SIZE
    });
    let (t, normal, albedo) = match (sphere, ground) {
        (Some((ts, k)), g) if g.map_or(true, |tg| ts < tg) => {
            let p = add(o, scale(d, ts));
            (ts, normalize(sub(p, SPHERES[k].0)), SPHERES[k].2)
        }
        (_, Some(tg)) => {
            let p = add(o, scale(d, tg));
            let checker = (p[0].floor() + p[2].floor()).rem_euclid(2.0) < 1.0;
            let k = if checker { 0.75 } else { 0.15 };
            (tg, [0.0, 1.0, 0.0], [0.8 * k, 0.75 * k, 0.7 * k])
        }
        _ => {
            // Sky: a smooth gradient with the height of the ray.
            let s = 0.5 + 0.5 * d[1];
            let colour = [0.9 - 0.5 * s, 0.9 - 0.35 * s, 1.0 - 0.1 * s];
            return Hit {
                colour,
                surface: None,
            };
        }
    };
    let position = add(o, scale(d, t));
    let lit = dot(normal, sun_dir).max(0.0);
    let shadow = hit_sphere(add(position, scale(normal, 1e-4)), sun_dir, 1e-6).is_some();
    let direct = if shadow { 0.0 } else { lit };
    let sky = 0.5 + 0.5 * normal[1];
    let colour = std::array::from_fn(|c| albedo[c] * (sun[c] * direct + ambient[c] * sky));
    Hit {
        colour,
        surface: Some(Surface {
            albedo,
            normal,
            depth: t,
            position,
        }),
    }
}

/// Per-sample standard deviations of the synthetic noise.
fn colour_sigma(c: f64) -> f64 {
    0.6 * c + 0.02
}
const ALBEDO_SIGMA: f64 = 0.03;
const NORMAL_SIGMA: f64 = 0.05;
/// Depth and position noise relative to the hit distance.
const DISTANCE_SIGMA: f64 = 0.01;

/// A deterministic render-statistics frame of `width × height` pixels at
/// `spp` samples per pixel (≥ 1), for benchmarks and tests.
///
/// The scene: a pinhole camera over a checkered ground square with three
/// spheres, lit by a sun (with shadows) and a sky term; rays that miss see a
/// smooth sky gradient and have all features 0 (as in the input format).
///
/// The noise is what `spp` independent Gaussian samples per pixel would give,
/// drawn in closed form: each mean is `μ + σ/√spp · z`, and its variance
/// layer is the unbiased sample variance over spp, `σ²/spp · χ²ₙ₋₁/(n−1)`
/// (drawn independently of the mean, as for Gaussian samples; Wilson–Hilferty
/// approximation of χ²; 0 when spp = 1). Per-sample σ: colour `0.6·c + 0.02`
/// per channel (Monte-Carlo-like: noisier where brighter), albedo 0.03,
/// normal 0.05, depth and position `0.01 × distance`; features of misses are
/// noise-free zeros. So the mean of `color_variance` over an image equals the
/// mean of `(color − clean)²` up to sampling error. `position_covariance` is
/// the sample covariance divided by spp (diagonal `(n−1)/n · s²`, off-diagonal
/// 0, the axes being independent).
///
/// Every pixel has its own random stream derived from `seed` and the pixel
/// index, so the frame depends only on `(width, height, spp, seed)`.
///
/// # Panics
/// If `spp` is 0 or the image is empty.
pub fn synthetic(width: usize, height: usize, spp: u32, seed: u64) -> Synthetic {
    assert!(spp >= 1, "synthetic: spp must be at least 1");
    assert!(width * height > 0, "synthetic: empty image");
    let n = width * height;
    let nf = spp as f64;
    let origin: V3 = [0.0, 0.6, 4.0];
    let forward = normalize(sub([0.0, -0.4, 0.0], origin));
    let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    let tan_half = (45f64.to_radians() / 2.0).tan();
    let aspect = width as f64 / height as f64;

    let planes = |k: usize| vec![vec![0.0f32; n]; k];
    let (mut color, mut color_var) = (planes(3), planes(3));
    let (mut albedo, mut albedo_var) = (planes(3), planes(3));
    let (mut normal, mut normal_var) = (planes(3), planes(3));
    let (mut depth, mut depth_var) = (planes(1), planes(1));
    let (mut position, mut position_var) = (planes(3), planes(3));
    let mut covariance = planes(6);
    let mut clean = RgbImage::new(width, height);

    for i in 0..n {
        let (x, y) = (i % width, i / width);
        let mut rng = Rng(seed ^ (i as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
        rng.next_u64();
        let u = (2.0 * (x as f64 + 0.5) / width as f64 - 1.0) * tan_half * aspect;
        let v = (1.0 - 2.0 * (y as f64 + 0.5) / height as f64) * tan_half;
        let dir = normalize(add(forward, add(scale(right, u), scale(up, v))));
        let hit = trace(origin, dir);
        // One noisy mean and its variance layer, for per-sample σ.
        let mut draw = |mu: f64, sigma: f64| -> (f32, f32, f64) {
            let mean = mu + sigma / nf.sqrt() * rng.normal();
            let s2 = if spp >= 2 {
                sigma * sigma * rng.chi2_over_k(nf - 1.0)
            } else {
                0.0
            };
            (mean as f32, (s2 / nf) as f32, s2)
        };
        for c in 0..3 {
            clean.planes[c][i] = hit.colour[c] as f32;
            let (m, var, _) = draw(hit.colour[c], colour_sigma(hit.colour[c]));
            color[c][i] = m;
            color_var[c][i] = var;
        }
        let Some(s) = hit.surface else {
            continue; // a miss: every feature and its variance stays 0
        };
        for c in 0..3 {
            (albedo[c][i], albedo_var[c][i], _) = draw(s.albedo[c], ALBEDO_SIGMA);
            (normal[c][i], normal_var[c][i], _) = draw(s.normal[c], NORMAL_SIGMA);
            let s2;
            (position[c][i], position_var[c][i], s2) =
                draw(s.position[c], DISTANCE_SIGMA * s.depth);
            // XX, YY, ZZ are entries 0, 3, 5 of (XX XY XZ YY YZ ZZ).
            covariance[[0, 3, 5][c]][i] = (s2 * (nf - 1.0) / nf) as f32;
        }
        (depth[0][i], depth_var[0][i], _) = draw(s.depth, DISTANCE_SIGMA * s.depth);
    }

    let mut stats = StatsImage::new(width, height);
    stats.set(Layer::Color, color);
    stats.set(Layer::ColorVariance, color_var);
    stats.set(Layer::Albedo, albedo);
    stats.set(Layer::AlbedoVariance, albedo_var);
    stats.set(Layer::Normal, normal);
    stats.set(Layer::NormalVariance, normal_var);
    stats.set(Layer::Depth, depth);
    stats.set(Layer::DepthVariance, depth_var);
    stats.set(Layer::Position, position);
    stats.set(Layer::PositionVariance, position_var);
    stats.set(Layer::PositionCovariance, covariance);
    stats.set(Layer::Spp, vec![vec![spp as f32; n]]);
    Synthetic { stats, clean }
}

// ---------------------------------------------------------------------------
// Quality benchmark
// ---------------------------------------------------------------------------

/// One scene folder: its inputs by spp and its reference.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The folder's name (the `scene` of the case names).
    pub name: String,
    /// `(N, path)` of every `sppN.exr`, by increasing N.
    pub inputs: Vec<(u32, PathBuf)>,
    /// `reference.exr` in the folder (it may be missing: checked when read).
    pub reference: PathBuf,
}

/// The N of a file named `sppN.exr`.
fn spp_of_file_name(name: &str) -> Option<u32> {
    let n = name.strip_prefix("spp")?.strip_suffix(".exr")?;
    if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    n.parse().ok()
}

fn spp_files(dir: &Path) -> Result<Vec<(u32, PathBuf)>> {
    let io_err = |source| Error::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut v = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let entry = entry.map_err(io_err)?;
        if let Some(n) = entry.file_name().to_str().and_then(spp_of_file_name) {
            v.push((n, entry.path()));
        }
    }
    v.sort();
    Ok(v)
}

/// The scenes of a benchmark folder: each subfolder holding at least one
/// `sppN.exr`, sorted by name; or, if `dir` itself holds `sppN.exr` files,
/// `dir` as the only scene. Other subfolders and files are ignored.
///
/// # Errors
/// [`Error::Io`] if `dir` cannot be listed; [`Error::InvalidArgument`] if it
/// holds no scene.
pub fn discover_scenes(dir: &Path) -> Result<Vec<Scene>> {
    let scene = |name: String, path: &Path, inputs| Scene {
        name,
        inputs,
        reference: path.join("reference.exr"),
    };
    let own = spp_files(dir)?;
    if !own.is_empty() {
        let name = dir
            .canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "scene".into());
        return Ok(vec![scene(name, dir, own)]);
    }
    let io_err = |source| Error::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut scenes = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let path = entry.map_err(io_err)?.path();
        if !path.is_dir() {
            continue;
        }
        let inputs = spp_files(&path)?;
        if inputs.is_empty() {
            continue;
        }
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        scenes.push(scene(name, &path, inputs));
    }
    scenes.sort_by(|a, b| a.name.cmp(&b.name));
    if scenes.is_empty() {
        return Err(Error::InvalidArgument(format!(
            "{}: no scene found (expected subfolders holding sppN.exr files and a reference.exr)",
            dir.display()
        )));
    }
    Ok(scenes)
}

/// What the quality benchmark runs.
#[derive(Clone, Debug)]
pub struct QualityConfig {
    /// The scenes folder ([`discover_scenes`]).
    pub dir: PathBuf,
    /// Methods to run; empty = every method built into this version.
    /// Requested methods that are not built are reported once and skipped.
    pub methods: Vec<Method>,
    /// Backends to run each method on; empty = the GPU.
    pub backends: Vec<Backend>,
    /// Case filter ([`case_matches`]) on `method.scene.sppN`. The `input` row
    /// of a scene × spp is kept when its own name or any of that scene × spp's
    /// method cases matches.
    pub filter: Option<String>,
}

/// One row of the quality table.
#[derive(Clone, Debug, PartialEq)]
pub struct QualityRow {
    /// `method.scene.sppN`.
    pub case: String,
    pub scene: String,
    pub spp: u32,
    /// A [`Method::name`], or `"input"` for the noisy input's own colour.
    pub method: String,
    /// `None` for the input row.
    pub backend: Option<Backend>,
    /// Of the method's colour (the raw input colour for `input`) against the reference.
    pub metrics: Metrics,
    /// Wall-clock seconds of the [`methods::denoise`] call (not the file
    /// reading or the metrics).
    pub wall_s: Option<f64>,
    /// Sum of the call's kernel timings (ms); `None` if none were reported.
    pub gpu_ms: Option<f64>,
    /// [`error_correlation`] of the method's error estimate, if it returned one.
    pub err_corr: Option<f64>,
    /// [`naive_correlation`] for the same output (only alongside `err_corr`).
    pub naive_corr: Option<f64>,
    /// `gpu_ms` per megapixel of the input.
    pub gpu_ms_per_mp: Option<f64>,
    /// Fraction of the pixels that became centres (LP).
    pub centres: Option<f64>,
}

/// Per method × backend × spp: how much the method improves on the input.
#[derive(Clone, Debug, PartialEq)]
pub struct QualitySummary {
    pub method: String,
    pub backend: Backend,
    pub spp: u32,
    /// Scenes that had both an input row and a method row at this spp.
    pub scenes: usize,
    /// Mean over those scenes of rMSE(input) / rMSE(method): > 1 is better
    /// than the noisy input.
    pub mean_rmse_ratio: f64,
    /// Mean [`error_correlation`] over the scenes that had one.
    pub mean_err_corr: Option<f64>,
}

/// One method against WLR on the same scene, spp and backend.
#[derive(Clone, Debug, PartialEq)]
pub struct VsWlr {
    pub scene: String,
    pub spp: u32,
    pub method: String,
    pub backend: Backend,
    /// rMSE(method) / rMSE(wlr): < 1 is better than WLR.
    pub rmse_ratio: f64,
    /// GPU time of WLR / GPU time of the method (> 1: the method is faster).
    pub speedup: Option<f64>,
}

/// The result of [`run_quality`].
#[derive(Clone, Debug, Default)]
pub struct QualityReport {
    pub dir: PathBuf,
    /// Name of the Vulkan device, when the GPU backend was used.
    pub device: Option<String>,
    /// Table rows, by scene, spp, then input first and methods in order.
    pub rows: Vec<QualityRow>,
    /// Requested methods that are not in this build (skipped).
    pub unavailable: Vec<Method>,
    /// Skipped cases: each message names the case or scene and the file.
    pub warnings: Vec<String>,
}

/// Runs the quality benchmark described by `cfg` (module docs). `ctx` is
/// needed when `cfg.backends` holds the GPU. Progress and warnings go to
/// `note` as they happen; warnings are also kept in the report.
///
/// # Errors
/// Only for what stops the whole benchmark: the folder cannot be listed or
/// holds no scene, or the GPU backend is asked for without a context. A
/// missing or unreadable file, a size mismatch or a failing method call skips
/// the affected cases with a warning.
pub fn run_quality(
    ctx: Option<&Arc<GpuContext>>,
    cfg: &QualityConfig,
    note: &mut dyn FnMut(Note),
) -> Result<QualityReport> {
    let backends = dedup_backends(&cfg.backends);
    check_context(ctx, &backends)?;
    let scenes = discover_scenes(&cfg.dir)?;
    let (methods, unavailable) = select_methods(&cfg.methods);
    let mut report = QualityReport {
        dir: cfg.dir.clone(),
        device: backends
            .contains(&Backend::Gpu)
            .then(|| ctx.map(|c| c.info().name.clone()))
            .flatten(),
        unavailable: unavailable.clone(),
        ..Default::default()
    };
    let warn = |report: &mut QualityReport, note: &mut dyn FnMut(Note), msg: String| {
        note(Note::Warning(&msg));
        report.warnings.push(msg);
    };
    for m in &unavailable {
        warn(
            &mut report,
            note,
            format!("method {} is not in this build: skipped", m.name()),
        );
    }
    let filter = cfg.filter.as_deref();
    // GPU method × backend pairs already warmed up (pipelines built).
    let mut warmed: BTreeSet<(&'static str, &'static str)> = BTreeSet::new();

    for scene in &scenes {
        let case_name = |method: &str, spp: u32| format!("{method}.{}.spp{spp}", scene.name);
        let selected = |spp: u32| -> (bool, Vec<Method>) {
            let ms: Vec<Method> = methods
                .iter()
                .copied()
                .filter(|m| case_matches(&case_name(m.name(), spp), filter))
                .collect();
            let input = case_matches(&case_name("input", spp), filter) || !ms.is_empty();
            (input, ms)
        };
        if !scene.inputs.iter().any(|(spp, _)| selected(*spp).0) {
            continue;
        }
        let reference = match io::read_rgb(&scene.reference) {
            Ok(r) => r,
            Err(e) => {
                warn(
                    &mut report,
                    note,
                    format!(
                        "scene {} skipped: cannot read its reference: {e}",
                        scene.name
                    ),
                );
                continue;
            }
        };
        for (spp, path) in &scene.inputs {
            let (want_input, ms) = selected(*spp);
            if !want_input {
                continue;
            }
            let img = match io::read_stats(path) {
                Ok(img) => img,
                Err(e) => {
                    warn(
                        &mut report,
                        note,
                        format!("{}.spp{spp} skipped: {e}", scene.name),
                    );
                    continue;
                }
            };
            let input_colour = colour_layer(&img).expect("read_stats requires the colour layer");
            let input_metrics = match metrics::compare(&input_colour, &reference) {
                Ok(m) => m,
                Err(e) => {
                    warn(
                        &mut report,
                        note,
                        format!(
                            "{}.spp{spp} skipped: {} vs {}: {e}",
                            scene.name,
                            path.display(),
                            scene.reference.display()
                        ),
                    );
                    continue;
                }
            };
            report.rows.push(QualityRow {
                case: case_name("input", *spp),
                scene: scene.name.clone(),
                spp: *spp,
                method: "input".into(),
                backend: None,
                metrics: input_metrics,
                wall_s: None,
                gpu_ms: None,
                err_corr: None,
                naive_corr: None,
                gpu_ms_per_mp: None,
                centres: None,
            });
            for &method in &ms {
                for &backend in &backends {
                    let case = case_name(method.name(), *spp);
                    note(Note::Progress(&format!(
                        "{case} ({})",
                        backend_name(backend)
                    )));
                    let req = request(method, backend);
                    if backend == Backend::Gpu
                        && warmed.insert((method.name(), backend_name(backend)))
                    {
                        // Untimed warm-up on a corner crop (builds the pipelines
                        // at a fraction of the cost); a failure shows in the timed call.
                        let (cw, ch) = (img.width.min(32), img.height.min(32));
                        let _ = methods::denoise(ctx, &img.crop(0, 0, cw, ch), &req);
                    }
                    let t0 = Instant::now();
                    let result = methods::denoise(ctx, &img, &req);
                    let wall = t0.elapsed().as_secs_f64();
                    let out = match result {
                        Ok(out) => out,
                        Err(e) => {
                            warn(
                                &mut report,
                                note,
                                format!(
                                    "{case} ({}) skipped: {}: {e}",
                                    backend_name(backend),
                                    path.display()
                                ),
                            );
                            continue;
                        }
                    };
                    match quality_row(
                        &case, scene, *spp, method, backend, &img, &out, &reference, wall,
                    ) {
                        Ok(row) => report.rows.push(row),
                        Err(msg) => warn(&mut report, note, msg),
                    }
                }
            }
        }
    }
    Ok(report)
}

/// Scores one method's output; `Err` holds the warning if it cannot be scored.
fn quality_row(
    case: &str,
    scene: &Scene,
    spp: u32,
    method: Method,
    backend: Backend,
    img: &StatsImage,
    out: &DenoiseOutput,
    reference: &RgbImage,
    wall_s: f64,
) -> std::result::Result<QualityRow, String> {
    let skipped = |e: &dyn std::fmt::Display| {
        format!(
            "{case} ({}) skipped: output vs {}: {e}",
            backend_name(backend),
            scene.reference.display()
        )
    };
    let m = metrics::compare(&out.color, reference).map_err(|e| skipped(&e))?;
    let (err_corr, naive_corr) = match &out.error {
        Some(est) => {
            metrics::check_same_size(est, &out.color).map_err(|e| skipped(&e))?;
            (
                Some(error_correlation(est, &out.color, reference)),
                naive_correlation(img, &out.color, reference),
            )
        }
        None => (None, None),
    };
    Ok(QualityRow {
        case: case.to_string(),
        scene: scene.name.clone(),
        spp,
        method: method.name().into(),
        backend: Some(backend),
        metrics: m,
        wall_s: Some(wall_s),
        gpu_ms: gpu_ms(&out.timings),
        err_corr,
        naive_corr,
        gpu_ms_per_mp: gpu_ms(&out.timings).map(|t| t / (img.width * img.height) as f64 * 1e6),
        centres: out
            .stats
            .iter()
            .find(|(k, _)| k == "centre_fraction")
            .map(|(_, v)| *v),
    })
}

impl QualityReport {
    /// Every non-WLR method row (not `input`, not `none`) that has a WLR row
    /// of the same scene, spp and backend, in table order.
    pub fn vs_wlr(&self) -> Vec<VsWlr> {
        let mut v = Vec::new();
        for r in &self.rows {
            let Some(backend) = r.backend else { continue };
            if r.method == "wlr" || r.method == "none" {
                continue;
            }
            let Some(w) = self.rows.iter().find(|w| {
                w.method == "wlr" && w.scene == r.scene && w.spp == r.spp && w.backend == r.backend
            }) else {
                continue;
            };
            v.push(VsWlr {
                scene: r.scene.clone(),
                spp: r.spp,
                method: r.method.clone(),
                backend,
                rmse_ratio: r.metrics.rmse / w.metrics.rmse,
                speedup: match (w.gpu_ms, r.gpu_ms) {
                    (Some(a), Some(b)) if b > 0.0 => Some(a / b),
                    _ => None,
                },
            });
        }
        v
    }

    /// Per method × backend × spp (in table order): the mean over scenes of
    /// rMSE(input) / rMSE(method), and the mean error correlation.
    pub fn summary(&self) -> Vec<QualitySummary> {
        // (method, backend) in order of first appearance, then spp ascending.
        let mut groups: Vec<(String, Backend)> = Vec::new();
        for r in &self.rows {
            if let Some(b) = r.backend {
                if !groups.iter().any(|g| g.0 == r.method && g.1 == b) {
                    groups.push((r.method.clone(), b));
                }
            }
        }
        let spps: BTreeSet<u32> = self.rows.iter().map(|r| r.spp).collect();
        let mut keys = Vec::new();
        for (method, backend) in groups {
            for &spp in &spps {
                if self
                    .rows
                    .iter()
                    .any(|r| r.method == method && r.backend == Some(backend) && r.spp == spp)
                {
                    keys.push((method.clone(), backend, spp));
                }
            }
        }
        keys.into_iter()
            .map(|(method, backend, spp)| {
                let (mut ratios, mut corrs) = (Vec::new(), Vec::new());
                for r in self
                    .rows
                    .iter()
                    .filter(|r| r.method == method && r.backend == Some(backend) && r.spp == spp)
                {
                    let input = self
                        .rows
                        .iter()
                        .find(|i| i.backend.is_none() && i.scene == r.scene && i.spp == spp);
                    if let Some(i) = input {
                        ratios.push(i.metrics.rmse / r.metrics.rmse);
                    }
                    corrs.extend(r.err_corr);
                }
                let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
                QualitySummary {
                    scenes: ratios.len(),
                    mean_rmse_ratio: mean(&ratios),
                    mean_err_corr: (!corrs.is_empty()).then(|| mean(&corrs)),
                    method,
                    backend,
                    spp,
                }
            })
            .collect()
    }

    /// The report as Markdown: the table, the summary lines, and the skipped
    /// cases. The `err corr` / `naive corr` columns appear when any row has
    /// an error estimate (blank in the rows without one).
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "Quality benchmark: {}", self.dir.display());
        if let Some(d) = &self.device {
            let _ = writeln!(s, "Device: {d}");
        }
        s.push('\n');
        let corr = self.rows.iter().any(|r| r.err_corr.is_some());
        let centres = self.rows.iter().any(|r| r.centres.is_some());
        let mut header = vec![
            "scene",
            "spp",
            "method",
            "backend",
            "rMSE",
            "relMSE",
            "PSNR",
            "SSIM",
            "wall s",
            "GPU ms",
            "GPU ms/MP",
        ];
        let mut align = vec![
            "---", "---:", "---", "---", "---:", "---:", "---:", "---:", "---:", "---:", "---:",
        ];
        if centres {
            header.push("centres");
            align.push("---:");
        }
        if corr {
            header.extend(["err corr", "naive corr"]);
            align.extend(["---:", "---:"]);
        }
        let mut rows: Vec<Vec<String>> = vec![
            header.iter().map(|h| h.to_string()).collect(),
            align.iter().map(|a| a.to_string()).collect(),
        ];
        for r in &self.rows {
            let mut cells = vec![
                r.scene.clone(),
                r.spp.to_string(),
                r.method.clone(),
                r.backend.map_or("-".into(), |b| backend_name(b).into()),
                fmt_error(r.metrics.rmse),
                fmt_error(r.metrics.relmse),
                fmt_fixed(r.metrics.psnr, 2),
                fmt_fixed(r.metrics.ssim, 4),
                r.wall_s.map_or(String::new(), |t| format!("{t:.3}")),
                r.gpu_ms.map_or(String::new(), |t| format!("{t:.2}")),
                r.gpu_ms_per_mp.map_or(String::new(), |t| format!("{t:.0}")),
            ];
            if centres {
                cells.push(
                    r.centres
                        .map_or(String::new(), |c| format!("{:.2}%", 100.0 * c)),
                );
            }
            if corr {
                cells.push(r.err_corr.map_or(String::new(), |c| fmt_fixed(c, 3)));
                cells.push(r.naive_corr.map_or(String::new(), |c| fmt_fixed(c, 3)));
            }
            rows.push(cells);
        }
        s.push_str(&markdown_table(&rows));
        let summary = self.summary();
        if !summary.is_empty() {
            s.push_str(
                "\nMean over scenes of rMSE(input) / rMSE(method) (> 1: better than the input):\n",
            );
            for q in &summary {
                let _ = write!(
                    s,
                    "- {} ({}), spp {}: {:.2} over {} scene{}",
                    q.method,
                    backend_name(q.backend),
                    q.spp,
                    q.mean_rmse_ratio,
                    q.scenes,
                    if q.scenes == 1 { "" } else { "s" }
                );
                if let Some(c) = q.mean_err_corr {
                    let _ = write!(s, "; mean err corr {c:.3}");
                }
                s.push('\n');
            }
        }
        let vs = self.vs_wlr();
        if !vs.is_empty() {
            s.push_str("\nAgainst WLR (same scene, spp and backend):\n\n");
            let mut rows: Vec<Vec<String>> = vec![
                [
                    "scene",
                    "spp",
                    "method",
                    "backend",
                    "rMSE / WLR",
                    "WLR GPU time / GPU time",
                ]
                .map(String::from)
                .to_vec(),
                ["---", "---:", "---", "---", "---:", "---:"]
                    .map(String::from)
                    .to_vec(),
            ];
            for c in &vs {
                rows.push(vec![
                    c.scene.clone(),
                    c.spp.to_string(),
                    c.method.clone(),
                    backend_name(c.backend).into(),
                    format!("{:.3}", c.rmse_ratio),
                    c.speedup.map_or(String::new(), |x| format!("{x:.1}")),
                ]);
            }
            s.push_str(&markdown_table(&rows));
        }
        push_warnings(&mut s, &self.warnings);
        s
    }

    /// The report as JSON: `{"kind": "quality", "dir", "device", "rows": [...],
    /// "summary": [...], "vs_wlr": [...], "unavailable_methods": [...],
    /// "warnings": [...]}`.
    /// Each row has `case scene spp method backend rmse relmse psnr ssim
    /// wall_s gpu_ms err_corr naive_corr gpu_ms_per_mp centres` (`null` where absent or
    /// non-finite); numbers at full precision.
    pub fn to_json(&self) -> String {
        let rows = self
            .rows
            .iter()
            .map(|r| {
                Json::Obj(vec![
                    ("case".into(), Json::Str(r.case.clone())),
                    ("scene".into(), Json::Str(r.scene.clone())),
                    ("spp".into(), Json::Int(r.spp as i64)),
                    ("method".into(), Json::Str(r.method.clone())),
                    (
                        "backend".into(),
                        r.backend
                            .map_or(Json::Null, |b| Json::Str(backend_name(b).into())),
                    ),
                    ("rmse".into(), Json::Num(r.metrics.rmse)),
                    ("relmse".into(), Json::Num(r.metrics.relmse)),
                    ("psnr".into(), Json::Num(r.metrics.psnr)),
                    ("ssim".into(), Json::Num(r.metrics.ssim)),
                    ("wall_s".into(), Json::opt(r.wall_s)),
                    ("gpu_ms".into(), Json::opt(r.gpu_ms)),
                    ("err_corr".into(), Json::opt(r.err_corr)),
                    ("naive_corr".into(), Json::opt(r.naive_corr)),
                    ("gpu_ms_per_mp".into(), Json::opt(r.gpu_ms_per_mp)),
                    ("centres".into(), Json::opt(r.centres)),
                ])
            })
            .collect();
        let summary = self
            .summary()
            .into_iter()
            .map(|q| {
                Json::Obj(vec![
                    ("method".into(), Json::Str(q.method)),
                    ("backend".into(), Json::Str(backend_name(q.backend).into())),
                    ("spp".into(), Json::Int(q.spp as i64)),
                    ("scenes".into(), Json::Int(q.scenes as i64)),
                    ("mean_rmse_ratio".into(), Json::Num(q.mean_rmse_ratio)),
                    ("mean_err_corr".into(), Json::opt(q.mean_err_corr)),
                ])
            })
            .collect();
        Json::Obj(vec![
            ("kind".into(), Json::Str("quality".into())),
            ("dir".into(), Json::Str(self.dir.display().to_string())),
            (
                "device".into(),
                self.device.clone().map_or(Json::Null, Json::Str),
            ),
            ("rows".into(), Json::Arr(rows)),
            ("summary".into(), Json::Arr(summary)),
            (
                "vs_wlr".into(),
                Json::Arr(
                    self.vs_wlr()
                        .into_iter()
                        .map(|c| {
                            Json::Obj(vec![
                                ("scene".into(), Json::Str(c.scene)),
                                ("spp".into(), Json::Int(c.spp as i64)),
                                ("method".into(), Json::Str(c.method)),
                                ("backend".into(), Json::Str(backend_name(c.backend).into())),
                                ("rmse_ratio".into(), Json::Num(c.rmse_ratio)),
                                ("speedup".into(), Json::opt(c.speedup)),
                            ])
                        })
                        .collect(),
                ),
            ),
            (
                "unavailable_methods".into(),
                Json::Arr(
                    self.unavailable
                        .iter()
                        .map(|m| Json::Str(m.name().into()))
                        .collect(),
                ),
            ),
            (
                "warnings".into(),
                Json::Arr(self.warnings.iter().cloned().map(Json::Str).collect()),
            ),
        ])
        .render()
    }
}

// ---------------------------------------------------------------------------
// Timing benchmark
// ---------------------------------------------------------------------------

/// The frame the timing benchmark denoises.
#[derive(Clone, Debug, PartialEq)]
pub enum TimingInput {
    /// [`synthetic`] at [`SYNTHETIC_SPP`] spp, seed 1; `inputs` = `synthetic`.
    Synthetic,
    /// A render-statistics file; `inputs` = its stem (a `sppN` stem is
    /// prefixed with its folder's name: `dof_checker-spp16`), with every
    /// character other than letters, digits, `_` and `-` replaced by `_`.
    File(PathBuf),
}

/// What the timing benchmark runs.
#[derive(Clone, Debug)]
pub struct TimingConfig {
    /// Methods to run; empty = every method built into this version.
    pub methods: Vec<Method>,
    /// Backends; empty = the GPU.
    pub backends: Vec<Backend>,
    pub input: TimingInput,
    /// Synthetic: the frame size (default 256×256). File: a centred crop of
    /// this size (default: the whole file).
    pub size: Option<(usize, usize)>,
    /// Timed calls per case (≥ 1), after one untimed warm-up call.
    pub runs: usize,
    /// Case filter ([`case_matches`]) on `method.inputs.WxH`.
    pub filter: Option<String>,
}

/// GPU time of one kernel in one case.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelRow {
    /// The kernel's name (as in `spirv/<name>.comp`; `_f64` for the f64 variant).
    pub kernel: String,
    /// Median over the runs of the kernel's total GPU time in one call (ms).
    pub ms: f64,
    /// Dispatches (bands) of the kernel in one call.
    pub dispatches: usize,
}

/// One case of the timing benchmark.
#[derive(Clone, Debug, PartialEq)]
pub struct TimingRow {
    /// `method.inputs.WxH`.
    pub case: String,
    pub method: Method,
    pub backend: Backend,
    pub width: usize,
    pub height: usize,
    /// Wall-clock milliseconds of each timed call.
    pub wall_ms: Vec<f64>,
    pub median_wall_ms: f64,
    /// `median_wall_ms` per million pixels.
    pub ms_per_megapixel: f64,
    /// Median over the runs of the summed kernel times (ms); `None` if the
    /// call reported no timings (CPU backend, or a method without them).
    pub gpu_ms: Option<f64>,
    pub kernels: Vec<KernelRow>,
}

/// The result of [`run_timing`].
#[derive(Clone, Debug, Default)]
pub struct TimingReport {
    /// Name of the Vulkan device, when the GPU backend was used.
    pub device: Option<String>,
    /// The `inputs` part of the case names.
    pub inputs: String,
    /// Where the input came from (a path, or `synthetic ...`).
    pub source: String,
    pub runs: usize,
    pub rows: Vec<TimingRow>,
    pub unavailable: Vec<Method>,
    /// Cases whose calls failed (skipped).
    pub warnings: Vec<String>,
}

/// The `inputs` name of a file (see [`TimingInput::File`]).
pub fn inputs_name(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "input".into());
    let name = match (spp_of_file_name(&format!("{stem}.exr")), path.parent()) {
        (Some(_), Some(parent)) => match parent
            .canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        {
            Some(dir) => format!("{dir}-{stem}"),
            None => stem,
        },
        _ => stem,
    };
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Runs the timing benchmark described by `cfg` (module docs). `ctx` is
/// needed when `cfg.backends` holds the GPU.
///
/// # Errors
/// `runs` is 0, the GPU backend is asked for without a context, the input
/// file cannot be read, or the crop is larger than the file. A method call
/// that fails skips its case with a warning.
pub fn run_timing(
    ctx: Option<&Arc<GpuContext>>,
    cfg: &TimingConfig,
    note: &mut dyn FnMut(Note),
) -> Result<TimingReport> {
    if cfg.runs == 0 {
        return Err(Error::InvalidArgument("--runs must be at least 1".into()));
    }
    let backends = dedup_backends(&cfg.backends);
    check_context(ctx, &backends)?;
    let (methods, unavailable) = select_methods(&cfg.methods);
    let (img, inputs, source) = match &cfg.input {
        TimingInput::Synthetic => {
            let (w, h) = cfg.size.unwrap_or((256, 256));
            let s = synthetic(w, h, SYNTHETIC_SPP, 1);
            (
                s.stats,
                "synthetic".to_string(),
                format!("synthetic frame, {SYNTHETIC_SPP} spp, seed 1"),
            )
        }
        TimingInput::File(path) => {
            let full = io::read_stats(path)?;
            let img = match cfg.size {
                None => full,
                Some((w, h)) => {
                    if w > full.width || h > full.height {
                        return Err(Error::InvalidArgument(format!(
                            "{}: is {}x{}, smaller than --size {w}x{h}",
                            path.display(),
                            full.width,
                            full.height
                        )));
                    }
                    full.crop((full.width - w) / 2, (full.height - h) / 2, w, h)
                }
            };
            (img, inputs_name(path), path.display().to_string())
        }
    };
    let (w, h) = (img.width, img.height);
    let mut report = TimingReport {
        device: backends
            .contains(&Backend::Gpu)
            .then(|| ctx.map(|c| c.info().name.clone()))
            .flatten(),
        inputs: inputs.clone(),
        source,
        runs: cfg.runs,
        unavailable: unavailable.clone(),
        ..Default::default()
    };
    for m in &unavailable {
        let msg = format!("method {} is not in this build: skipped", m.name());
        note(Note::Warning(&msg));
        report.warnings.push(msg);
    }
    for &method in &methods {
        let case = format!("{}.{inputs}.{w}x{h}", method.name());
        if !case_matches(&case, cfg.filter.as_deref()) {
            continue;
        }
        for &backend in &backends {
            note(Note::Progress(&format!(
                "{case} ({})",
                backend_name(backend)
            )));
            match time_case(ctx, &img, method, backend, cfg.runs) {
                Ok((wall_ms, timings)) => {
                    let med = median(&wall_ms);
                    let sums: Vec<f64> = timings.iter().filter_map(|t| gpu_ms(t)).collect();
                    let kernels = timings
                        .last()
                        .map(|t| timings_per_kernel(t))
                        .unwrap_or_default()
                        .into_iter()
                        .map(|(kernel, _, dispatches)| {
                            let per_run: Vec<f64> = timings
                                .iter()
                                .map(|t| {
                                    t.iter()
                                        .filter(|k| k.kernel == kernel)
                                        .map(|k| k.nanoseconds)
                                        .sum::<f64>()
                                        / 1e6
                                })
                                .collect();
                            KernelRow {
                                ms: median(&per_run),
                                kernel,
                                dispatches,
                            }
                        })
                        .collect();
                    report.rows.push(TimingRow {
                        case: case.clone(),
                        method,
                        backend,
                        width: w,
                        height: h,
                        median_wall_ms: med,
                        ms_per_megapixel: med / ((w * h) as f64 / 1e6),
                        wall_ms,
                        gpu_ms: (!sums.is_empty()).then(|| median(&sums)),
                        kernels,
                    });
                }
                Err(e) => {
                    let msg = format!(
                        "{case} ({}) skipped: {}: {e}",
                        backend_name(backend),
                        report.source
                    );
                    note(Note::Warning(&msg));
                    report.warnings.push(msg);
                }
            }
        }
    }
    Ok(report)
}

/// One warm-up call, then `runs` timed calls: wall ms and timings per run.
fn time_case(
    ctx: Option<&Arc<GpuContext>>,
    img: &StatsImage,
    method: Method,
    backend: Backend,
    runs: usize,
) -> Result<(Vec<f64>, Vec<Vec<KernelTiming>>)> {
    let req = request(method, backend);
    methods::denoise(ctx, img, &req)?;
    let (mut wall, mut timings) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let t0 = Instant::now();
        let out = methods::denoise(ctx, img, &req)?;
        wall.push(t0.elapsed().as_secs_f64() * 1e3);
        timings.push(out.timings);
    }
    Ok((wall, timings))
}

impl TimingReport {
    /// The report as Markdown: one row per case, then the per-kernel GPU times.
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Timing benchmark: {} ({} timed run{} per case after 1 warm-up)",
            self.source,
            self.runs,
            if self.runs == 1 { "" } else { "s" }
        );
        if let Some(d) = &self.device {
            let _ = writeln!(s, "Device: {d}");
        }
        s.push('\n');
        let mut rows: Vec<Vec<String>> = vec![
            ["case", "backend", "median wall ms", "ms/MP", "GPU ms"]
                .map(String::from)
                .to_vec(),
            ["---", "---", "---:", "---:", "---:"]
                .map(String::from)
                .to_vec(),
        ];
        for r in &self.rows {
            rows.push(vec![
                r.case.clone(),
                backend_name(r.backend).into(),
                format!("{:.2}", r.median_wall_ms),
                format!("{:.2}", r.ms_per_megapixel),
                r.gpu_ms.map_or(String::new(), |t| format!("{t:.2}")),
            ]);
        }
        s.push_str(&markdown_table(&rows));
        let with_kernels: Vec<&TimingRow> =
            self.rows.iter().filter(|r| !r.kernels.is_empty()).collect();
        s.push('\n');
        if with_kernels.is_empty() {
            s.push_str("Per-kernel GPU times: none reported by these cases.\n");
        } else {
            s.push_str("Per-kernel GPU times (median over the runs):\n\n");
            let mut rows: Vec<Vec<String>> = vec![
                ["case", "backend", "kernel", "GPU ms", "dispatches"]
                    .map(String::from)
                    .to_vec(),
                ["---", "---", "---", "---:", "---:"]
                    .map(String::from)
                    .to_vec(),
            ];
            for r in with_kernels {
                for k in &r.kernels {
                    rows.push(vec![
                        r.case.clone(),
                        backend_name(r.backend).into(),
                        k.kernel.clone(),
                        format!("{:.3}", k.ms),
                        k.dispatches.to_string(),
                    ]);
                }
            }
            s.push_str(&markdown_table(&rows));
        }
        push_warnings(&mut s, &self.warnings);
        s
    }

    /// The report as JSON: `{"kind": "timing", "device", "inputs", "source",
    /// "runs", "rows": [...], "unavailable_methods", "warnings"}`; each row
    /// has `case method backend width height wall_ms median_wall_ms
    /// ms_per_megapixel gpu_ms kernels` and each kernel `kernel gpu_ms
    /// dispatches`.
    pub fn to_json(&self) -> String {
        let rows = self
            .rows
            .iter()
            .map(|r| {
                Json::Obj(vec![
                    ("case".into(), Json::Str(r.case.clone())),
                    ("method".into(), Json::Str(r.method.name().into())),
                    ("backend".into(), Json::Str(backend_name(r.backend).into())),
                    ("width".into(), Json::Int(r.width as i64)),
                    ("height".into(), Json::Int(r.height as i64)),
                    (
                        "wall_ms".into(),
                        Json::Arr(r.wall_ms.iter().map(|&t| Json::Num(t)).collect()),
                    ),
                    ("median_wall_ms".into(), Json::Num(r.median_wall_ms)),
                    ("ms_per_megapixel".into(), Json::Num(r.ms_per_megapixel)),
                    ("gpu_ms".into(), Json::opt(r.gpu_ms)),
                    (
                        "kernels".into(),
                        Json::Arr(
                            r.kernels
                                .iter()
                                .map(|k| {
                                    Json::Obj(vec![
                                        ("kernel".into(), Json::Str(k.kernel.clone())),
                                        ("gpu_ms".into(), Json::Num(k.ms)),
                                        ("dispatches".into(), Json::Int(k.dispatches as i64)),
                                    ])
                                })
                                .collect(),
                        ),
                    ),
                ])
            })
            .collect();
        Json::Obj(vec![
            ("kind".into(), Json::Str("timing".into())),
            (
                "device".into(),
                self.device.clone().map_or(Json::Null, Json::Str),
            ),
            ("inputs".into(), Json::Str(self.inputs.clone())),
            ("source".into(), Json::Str(self.source.clone())),
            ("runs".into(), Json::Int(self.runs as i64)),
            ("rows".into(), Json::Arr(rows)),
            (
                "unavailable_methods".into(),
                Json::Arr(
                    self.unavailable
                        .iter()
                        .map(|m| Json::Str(m.name().into()))
                        .collect(),
                ),
            ),
            (
                "warnings".into(),
                Json::Arr(self.warnings.iter().cloned().map(Json::Str).collect()),
            ),
        ])
        .render()
    }
}

// ---------------------------------------------------------------------------
// Output helpers
// ---------------------------------------------------------------------------

/// Writes `text` to `path` atomically ([`io::write_atomic`]).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    io::write_atomic(path, |w| {
        w.write_all(text.as_bytes()).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// An error metric: 5 decimals (as in `BASELINES.md`) down to 0.001, then
/// 3 significant digits in scientific notation.
fn fmt_error(v: f64) -> String {
    if !v.is_finite() {
        format!("{v}")
    } else if v == 0.0 || v.abs() >= 1e-3 {
        format!("{v:.5}")
    } else {
        format!("{v:.2e}")
    }
}

fn fmt_fixed(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        format!("{v}")
    }
}

/// A Markdown table from rows of cells (header, alignment row, body), padded
/// so the columns line up in a terminal.
fn markdown_table(rows: &[Vec<String>]) -> String {
    let cols = rows.iter().map(|r| r.len()).max().unwrap_or(0);
    let width: Vec<usize> = (0..cols)
        .map(|c| {
            rows.iter()
                .filter_map(|r| r.get(c))
                .map(|s| s.chars().count())
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut s = String::new();
    for (i, r) in rows.iter().enumerate() {
        s.push('|');
        for (c, w) in width.iter().enumerate() {
            let cell = r.get(c).map(String::as_str).unwrap_or("");
            if i == 1 {
                // The alignment row: dashes to the column width, keep the colon.
                let colon = cell.ends_with(':');
                let dashes = "-".repeat(w.saturating_sub(colon as usize).max(3));
                let _ = write!(s, " {dashes}{} |", if colon { ":" } else { "" });
            } else {
                let right = rows
                    .get(1)
                    .and_then(|a| a.get(c))
                    .is_some_and(|a| a.ends_with(':'));
                if right {
                    let _ = write!(s, " {cell:>w$} |");
                } else {
                    let _ = write!(s, " {cell:<w$} |");
                }
            }
        }
        s.push('\n');
    }
    s
}

/// A JSON value, rendered by hand (no serialisation dependency).
#[derive(Clone, Debug)]
enum Json {
    Null,
    Int(i64),
    /// Non-finite numbers render as `null`.
    Num(f64),
    Str(String),
    Arr(Vec<Json>),
    Obj(Vec<(String, Json)>),
}

impl Json {
    fn opt(v: Option<f64>) -> Json {
        v.map_or(Json::Null, Json::Num)
    }

    fn is_scalar(&self) -> bool {
        !matches!(self, Json::Arr(_) | Json::Obj(_))
    }

    /// Pretty-printed with two-space indents; an object or array holding only
    /// scalars goes on one line (one table row per line).
    fn render(&self) -> String {
        let mut s = String::new();
        self.write(&mut s, 0);
        s.push('\n');
        s
    }

    fn write(&self, s: &mut String, indent: usize) {
        match self {
            Json::Null => s.push_str("null"),
            Json::Int(i) => {
                let _ = write!(s, "{i}");
            }
            // `{:?}` is the shortest representation that reads back to the
            // same f64, and is valid JSON (`1.0`, `1e-7`, `0.036870001`).
            Json::Num(v) if v.is_finite() => {
                let _ = write!(s, "{v:?}");
            }
            Json::Num(_) => s.push_str("null"),
            Json::Str(t) => write_json_string(s, t),
            Json::Arr(items) => {
                if items.is_empty() {
                    s.push_str("[]");
                } else if items.iter().all(Json::is_scalar) {
                    s.push('[');
                    for (i, v) in items.iter().enumerate() {
                        if i > 0 {
                            s.push_str(", ");
                        }
                        v.write(s, indent);
                    }
                    s.push(']');
                } else {
                    s.push_str("[\n");
                    for (i, v) in items.iter().enumerate() {
                        s.push_str(&"  ".repeat(indent + 1));
                        v.write(s, indent + 1);
                        s.push_str(if i + 1 < items.len() { ",\n" } else { "\n" });
                    }
                    s.push_str(&"  ".repeat(indent));
                    s.push(']');
                }
            }
            Json::Obj(fields) => {
                if fields.is_empty() {
                    s.push_str("{}");
                } else if fields.iter().all(|(_, v)| v.is_scalar()) {
                    s.push('{');
                    for (i, (k, v)) in fields.iter().enumerate() {
                        if i > 0 {
                            s.push_str(", ");
                        }
                        write_json_string(s, k);
                        s.push_str(": ");
                        v.write(s, indent);
                    }
                    s.push('}');
                } else {
                    s.push_str("{\n");
                    for (i, (k, v)) in fields.iter().enumerate() {
                        s.push_str(&"  ".repeat(indent + 1));
                        write_json_string(s, k);
                        s.push_str(": ");
                        v.write(s, indent + 1);
                        s.push_str(if i + 1 < fields.len() { ",\n" } else { "\n" });
                    }
                    s.push_str(&"  ".repeat(indent));
                    s.push('}');
                }
            }
        }
    }
}

fn write_json_string(s: &mut String, t: &str) {
    s.push('"');
    for c in t.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\r' => s.push_str("\\r"),
            '\t' => s.push_str("\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(s, "\\u{:04x}", c as u32);
            }
            c => s.push(c),
        }
    }
    s.push('"');
}

/// Appends the Markdown "Warnings:" section (nothing when there are none).
fn push_warnings(s: &mut String, warnings: &[String]) {
    if !warnings.is_empty() {
        s.push_str("\nWarnings:\n");
        for w in warnings {
            let _ = writeln!(s, "- {w}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filters_and_sizes() {
        assert!(case_matches("none.dof_checker.spp16", None));
        assert!(case_matches("none.dof_checker.spp16", Some("")));
        assert!(case_matches("none.dof_checker.spp16", Some("spp16")));
        assert!(case_matches("none.dof_checker.spp16", Some("wlr|dof")));
        assert!(!case_matches("none.dof_checker.spp16", Some("spp4")));
        assert_eq!(parse_size("256x128").unwrap(), (256, 128));
        assert_eq!(parse_size(" 3X5 ").unwrap(), (3, 5));
        for bad in ["256", "0x4", "ax4", "4x", "99999999x1"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(spp_of_file_name("spp16.exr"), Some(16));
        assert_eq!(spp_of_file_name("spp.exr"), None);
        assert_eq!(spp_of_file_name("spp1a.exr"), None);
        assert_eq!(spp_of_file_name("reference.exr"), None);
        assert_eq!(method_from_name("WLR"), Some(Method::Wlr));
        assert_eq!(method_from_name("x"), None);
    }

    #[test]
    fn tile_means_keep_partial_tiles() {
        // 10 x 9: tiles of 8 give 2 x 2, the border ones partial.
        let m = tile_means(10, 9, 8, |i| (i % 10) as f64);
        assert_eq!(m.len(), 4);
        assert!((m[0] - 3.5).abs() < 1e-12); // x = 0..8
        assert!((m[1] - 8.5).abs() < 1e-12); // x = 8, 9
        assert!((m[2] - 3.5).abs() < 1e-12);
        assert!((m[3] - 8.5).abs() < 1e-12);
    }

    #[test]
    fn pearson_edge_cases() {
        assert!((pearson(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.5]) - 0.9986).abs() < 1e-3);
        assert!((pearson(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert!(pearson(&[1.0], &[1.0]).is_nan());
        assert!(pearson(&[1.0, 1.0], &[1.0, 2.0]).is_nan());
        assert!(pearson(&[1.0, f64::NAN], &[1.0, 2.0]).is_nan());
    }

    #[test]
    fn json_rendering() {
        let j = Json::Obj(vec![
            ("a".into(), Json::Num(f64::NAN)),
            ("b".into(), Json::Str("q\"\\\n\u{1}".into())),
            (
                "c".into(),
                Json::Arr(vec![Json::Num(1.0), Json::Num(1e-7), Json::Int(3)]),
            ),
            ("d".into(), Json::Arr(vec![])),
        ]);
        let s = j.render();
        assert!(s.contains(r#""a": null"#), "{s}");
        assert!(s.contains(r#""b": "q\"\\\n\u0001""#), "{s}");
        assert!(s.contains("[1.0, 1e-7, 3]"), "{s}");
        assert!(s.contains(r#""d": []"#), "{s}");
    }

    fn row(method: &str, backend: Option<Backend>, rmse: f64, corr: Option<f64>) -> QualityRow {
        QualityRow {
            case: format!("{method}.s.spp4"),
            scene: "s".into(),
            spp: 4,
            method: method.into(),
            backend,
            metrics: Metrics {
                rmse,
                relmse: rmse,
                psnr: 30.0,
                ssim: 0.9,
            },
            wall_s: backend.map(|_| 0.5),
            gpu_ms: None,
            err_corr: corr,
            naive_corr: corr.map(|c| c / 2.0),
            gpu_ms_per_mp: None,
            centres: None,
        }
    }

    #[test]
    fn methods_against_wlr() {
        let mut wlr = row("wlr", Some(Backend::Gpu), 0.01, None);
        wlr.gpu_ms = Some(1000.0);
        let mut lp = row("lp", Some(Backend::Gpu), 0.012, None);
        lp.gpu_ms = Some(100.0);
        lp.centres = Some(0.05);
        let cpu_lp = row("lp", Some(Backend::Cpu), 0.012, None);
        let report = QualityReport {
            dir: "scenes".into(),
            rows: vec![row("input", None, 0.2, None), wlr, lp, cpu_lp],
            ..Default::default()
        };
        let vs = report.vs_wlr();
        assert_eq!(vs.len(), 1, "{vs:?}");
        assert!((vs[0].rmse_ratio - 1.2).abs() < 1e-12);
        assert_eq!(vs[0].speedup, Some(10.0));
        let md = report.to_markdown();
        assert!(
            md.contains(
                "| s     |    4 | lp     | gpu     |      1.200 |                    10.0 |"
            ),
            "{md}"
        );
        assert!(md.contains("5.00%"), "{md}");
        assert!(report.to_json().contains(r#""rmse_ratio": 1.2"#));
    }

    #[test]
    fn quality_report_with_error_estimates() {
        let report = QualityReport {
            dir: "scenes".into(),
            rows: vec![
                row("input", None, 0.2, None),
                row("wlr", Some(Backend::Gpu), 0.01, Some(0.8)),
                row("none", Some(Backend::Gpu), 0.2, None),
            ],
            ..Default::default()
        };
        let md = report.to_markdown();
        assert!(md.contains("| err corr | naive corr |"), "{md}");
        assert!(md.contains("|    0.800 |      0.400 |"), "{md}");
        // Rows without an estimate have blank correlation cells.
        let none = md.lines().find(|l| l.contains("| none ")).unwrap();
        assert!(none.ends_with("|          |            |"), "{none}");
        let summary = report.summary();
        assert_eq!(summary.len(), 2);
        assert_eq!(summary[0].method, "wlr");
        assert!((summary[0].mean_rmse_ratio - 20.0).abs() < 1e-9);
        assert_eq!(summary[0].mean_err_corr, Some(0.8));
        assert!((summary[1].mean_rmse_ratio - 1.0).abs() < 1e-12);
        assert!(
            md.contains("- wlr (gpu), spp 4: 20.00 over 1 scene; mean err corr 0.800"),
            "{md}"
        );
        assert!(report.to_json().contains(
            r#""err_corr": 0.8, "naive_corr": 0.4, "gpu_ms_per_mp": null, "centres": null}"#
        ));
    }

    #[test]
    fn markdown_table_aligns() {
        let rows = vec![
            vec!["a".to_string(), "bb".to_string()],
            vec!["---".to_string(), "---:".to_string()],
            vec!["long".to_string(), "1".to_string()],
        ];
        let t = markdown_table(&rows);
        assert_eq!(t, "| a    |   bb |\n| ---- | ---: |\n| long |    1 |\n");
    }
}
