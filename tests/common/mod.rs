//! Shared test helpers: one GPU context per test binary (validation layer on
//! when installed), tolerance checks of spec §0.3, a deterministic PRNG.
#![allow(dead_code)] // each test binary uses a different subset

pub mod apr;

use std::sync::{Arc, OnceLock};

use mcdenoise::gpu::{ContextOptions, GpuContext, Precision, Validation};

/// Set (to 1) by `scripts/test.sh`, the README's test command: the
/// validation layer is then required, and a machine without it fails every
/// GPU test instead of running them unchecked.
pub const REQUIRE_VALIDATION: &str = "MCDENOISE_REQUIRE_VALIDATION";

/// The fence timeout of the tests' contexts: first dispatches include
/// llvmpipe's compile.
pub const TEST_FENCE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(600);

/// The test context. Tests fail if the validation layer reported an error
/// (checked by [`check_validation`]).
pub fn gpu() -> Arc<GpuContext> {
    static CTX: OnceLock<Arc<GpuContext>> = OnceLock::new();
    CTX.get_or_init(own_gpu).clone()
}

/// A context of the test's own (the validation layer as for [`gpu`]): for
/// tests that measure the context's allocations, which the other tests of
/// the binary, running in parallel on the shared context, would add to.
pub fn own_gpu() -> Arc<GpuContext> {
    gpu_with(false)
}

/// A context of the test's own with `shaderFloat64` and `shaderInt64` left
/// disabled: what a GPU without 64-bit types runs.
pub fn gpu_without_64bit() -> Arc<GpuContext> {
    gpu_with(true)
}

fn gpu_with(no_64bit: bool) -> Arc<GpuContext> {
    let required = std::env::var(REQUIRE_VALIDATION).is_ok_and(|v| v == "1");
    let ctx = GpuContext::new(&ContextOptions {
        device: None,
        validation: if required {
            Validation::Required
        } else {
            Validation::IfInstalled
        },
        no_64bit,
    })
    .unwrap_or_else(|e| {
        panic!(
            "{e}\n(a Vulkan device: apt-get install mesa-vulkan-drivers libvulkan1; \
             with {REQUIRE_VALIDATION}=1 also the validation layer: vulkan-validationlayers)"
        )
    });
    // llvmpipe compiles a pipeline at its first dispatch, inside the fence
    // wait; a cold f64 kernel on a loaded 2-core CI machine has taken longer
    // than the 60 s default (apr_block_f64, 2026-12-01).
    ctx.set_fence_timeout(TEST_FENCE_TIMEOUT);
    eprintln!(
        "test device: {} (validation {})",
        ctx.info().name,
        if ctx.validation_enabled() {
            "on"
        } else {
            "not installed"
        }
    );
    Arc::new(ctx)
}

/// Fails the test if the validation layer reported any error so far.
pub fn check_validation(ctx: &GpuContext) {
    assert_eq!(
        ctx.validation_errors(),
        0,
        "validation errors: {:#?}",
        ctx.validation_messages()
    );
}

/// xorshift64* — deterministic, no dependency.
pub struct Rng(pub u64);
impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545F4914F6CDD1D)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Spec §0.3: `|gpu − cpu| ≤ 1e-3·(|cpu| + 1e-3)` on at least `frac` of the
/// values. Returns the fraction that passed; panics with details if too few.
pub fn assert_close(what: &str, gpu: &[f32], cpu: &[f32], frac: f64) -> f64 {
    assert_eq!(gpu.len(), cpu.len(), "{what}: lengths");
    let mut bad = Vec::new();
    for (i, (&g, &c)) in gpu.iter().zip(cpu).enumerate() {
        let ok = (g as f64 - c as f64).abs() <= 1e-3 * ((c as f64).abs() + 1e-3);
        if !ok || !g.is_finite() {
            bad.push((i, g, c));
        }
    }
    let passed = 1.0 - bad.len() as f64 / gpu.len().max(1) as f64;
    assert!(
        passed >= frac,
        "{what}: only {:.4} of values within tolerance (need {frac}); first failures (index, gpu, cpu): {:?}",
        passed,
        &bad[..bad.len().min(8)]
    );
    passed
}

/// Fraction of equal values (for discrete outputs: rank, flags).
pub fn agreement(gpu: &[f32], cpu: &[f32]) -> f64 {
    let eq = gpu.iter().zip(cpu).filter(|(g, c)| g == c).count();
    eq as f64 / gpu.len().max(1) as f64
}

/// The value of `#define NAME value` in a shader's source (a kernel's
/// mirror of a crate constant).
pub fn shader_define<T: std::str::FromStr>(source: &str, name: &str) -> T
where
    T::Err: std::fmt::Debug,
{
    let prefix = format!("#define {name} ");
    let line = source
        .lines()
        .find(|l| l.starts_with(&prefix))
        .unwrap_or_else(|| panic!("no #define {name}"));
    line[prefix.len()..].trim().parse().unwrap()
}

/// The precisions every kernel is tested in: f32, and f64 where the device
/// has it.
pub fn precisions() -> Vec<Precision> {
    let mut v = vec![Precision::F32];
    if gpu().supports_f64() {
        v.push(Precision::F64);
    }
    v
}

/// The sizes every kernel is tested on (issue #2): square, 1x1, 1xN, Nx1, prime.
pub const SIZES: &[(usize, usize)] = &[(64, 64), (1, 1), (1, 17), (23, 1), (37, 23)];

/// Issue #11's spike test input: the smooth 64² fixture, and the same with
/// single-pixel spikes of 1000× the local value (with a renderer's
/// variance) at three pixels. Returns `(clean, spiky, excess energy per
/// channel, spike count)`.
pub fn spiky_fixture() -> (
    mcdenoise::StatsImage,
    mcdenoise::StatsImage,
    [f64; 3],
    usize,
) {
    use mcdenoise::Layer;
    let clean = mcdenoise::io::read_stats(std::path::Path::new("tests/fixtures/smooth_64.exr"))
        .expect("tests/fixtures/smooth_64.exr");
    let w = clean.width;
    let spikes = [(20, 30), (45, 10), (50, 52)];
    let mut spiky = clean.clone();
    let mut energy = [0.0f64; 3];
    let color = spiky.get(Layer::Color).unwrap().to_vec();
    let mut var = spiky.get(Layer::ColorVariance).unwrap().to_vec();
    let mut col = color.clone();
    for &(x, y) in &spikes {
        let i = y * w + x;
        for c in 0..3 {
            let s = color[c][i] * 1000.0;
            energy[c] += (s - color[c][i]) as f64;
            col[c][i] = s;
            var[c][i] = s * s;
        }
    }
    spiky.set(Layer::Color, col);
    spiky.set(Layer::ColorVariance, var);
    (clean, spiky, energy, spikes.len())
}

/// The largest change of one pixel between two images' channel `c`, and
/// the change of the channel's sum.
pub fn pixel_and_sum_change(
    a: &mcdenoise::RgbImage,
    b: &mcdenoise::RgbImage,
    c: usize,
) -> (f64, f64) {
    let worst = a.planes[c]
        .iter()
        .zip(&b.planes[c])
        .map(|(&p, &q)| (q as f64 - p as f64).abs())
        .fold(0.0, f64::max);
    let sa: f64 = a.planes[c].iter().map(|&v| v as f64).sum();
    let sb: f64 = b.planes[c].iter().map(|&v| v as f64).sum();
    (worst, sb - sa)
}

/// Sample counts from 1 to 40 with a few invalid pixels (0, NaN, below 1).
#[allow(dead_code)]
pub fn counts_with_invalid(n: usize, rng: &mut Rng) -> Vec<f32> {
    (0..n)
        .map(|i| match i % 11 {
            3 => 0.0,
            7 if i % 2 == 0 => f32::NAN,
            9 => 0.5,
            _ => (1 + (rng.uniform() * 40.0) as u32) as f32,
        })
        .collect()
}

/// `n` values uniform in `[0, scale)`.
#[allow(dead_code)]
pub fn uniform_plane(n: usize, rng: &mut Rng, scale: f64) -> Vec<f32> {
    (0..n).map(|_| (scale * rng.uniform()) as f32).collect()
}

/// A final-pass f32 chain configuration of `method` with every optional
/// stage off (no prefilter, outliers, pyramid, input blend or temporal
/// stage), the error estimate on.
#[allow(dead_code)]
pub fn bare_chain_config(method: mcdenoise::Method) -> mcdenoise::methods::chain::ChainConfig {
    mcdenoise::methods::chain::ChainConfig {
        method,
        pass: mcdenoise::Pass::Final,
        precision: Precision::F32,
        prefilter: mcdenoise::Prefilter::Off,
        outliers: false,
        options: mcdenoise::Options::default(),
        low_spp: true,
        debug: false,
        error: true,
        pyramid: false,
        input_blend: false,
        temporal: mcdenoise::Temporal::Off,
        temporal_state: None,
        coarse_map: false,
    }
}

/// Runs a chain of `config` on `img`; returns its outputs and the
/// statistics its method read (sanitised, and changed in place by the
/// outlier stage and the prefilter when they run).
#[allow(dead_code)]
pub fn run_chain(
    ctx: &Arc<GpuContext>,
    img: &mcdenoise::StatsImage,
    config: mcdenoise::methods::chain::ChainConfig,
) -> (
    mcdenoise::methods::chain::ChainOutput,
    mcdenoise::StatsImage,
) {
    use mcdenoise::methods::chain::{ChainInput, GpuChain};
    let chain = GpuChain::new(ctx, ChainInput::of_image(img), config).unwrap();
    chain.upload(img).unwrap();
    let mut batch = mcdenoise::gpu::Batch::new(ctx).unwrap();
    chain.record(&mut batch, None, None).unwrap();
    batch.finish().unwrap();
    (chain.download().unwrap(), chain.clean().download().unwrap())
}

/// GPU and CPU sample maps: both spend exactly `budget`; their counts agree
/// within 1 sample or 2 % on ≥ 98 % of the pixels (the priorities differ by
/// f32 rounding, so counts may shift by one between neighbours).
pub fn assert_maps_agree(gpu: &[u32], cpu: &[u32], budget: u32) {
    assert_eq!(gpu.iter().map(|&v| v as u64).sum::<u64>(), budget as u64);
    assert_eq!(cpu.iter().map(|&v| v as u64).sum::<u64>(), budget as u64);
    let close = gpu
        .iter()
        .zip(cpu)
        .filter(|(&a, &b)| (a as f64 - b as f64).abs() <= 1.0f64.max(0.02 * b as f64))
        .count();
    assert!(
        close as f64 >= 0.98 * gpu.len() as f64,
        "maps agree on {close} of {}",
        gpu.len()
    );
}
