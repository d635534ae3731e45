//! The built-in synthetic scene: a deterministic render-statistics frame
//! ([`synthetic`]) for the timing benchmark and the tests.

use crate::image::{Layer, RgbImage, StatsImage};

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
