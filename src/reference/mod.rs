//! Scalar f64 twins of the GLSL kernels (`spirv/<name>.comp` ↔
//! `reference/<name>.rs`) and of the shared GLSL libraries
//! (`spirv/lib/<name>.glsl` ↔ [`linalg`], [`tsvd`], [`wlr`], [`lp`],
//! [`sampling`]).
//!
//! A twin takes the same planes (f32 slices) and push constants as its kernel
//! and loops over the same pixel grid, computing in f64 and storing f32, so
//! any kernel can be replaced by its twin and a GPU/CPU mismatch can be
//! bisected kernel by kernel (spec §0.3 gives the tolerances). The twins of
//! the sampling allocation (`sample_reduce`, `sample_scan`) are exact integer
//! arithmetic and agree with their kernels bit for bit (§9.2).

pub mod aos;
pub mod aos_fit;
pub mod aos_nlm;
pub mod aos_space;
pub mod apr;
pub mod apr_block;
pub mod apr_gather;
pub mod apr_pack;
pub mod auto_blend;
pub mod auto_dis;
pub mod auto_score;
pub mod box_rows;
pub mod channel_mean;
pub mod estimate_variance;
pub mod finalize_covariance;
pub mod finalize_stats;
pub mod gauss_rows;
pub mod gauss_smooth;
pub mod gbf;
pub mod gbf_filter;
pub mod gbf_pack;
pub mod gbf_prepare;
pub mod gbf_sure;
pub mod input_blend;
pub mod linalg;
pub mod lp;
pub mod lp_centres;
pub mod lp_gather;
pub mod lp_reach;
pub mod lp_select;
pub mod lp_smooth;
pub mod lp_temporal;
pub mod lp_temporal_gain;
pub mod outlier_clip;
pub mod outlier_detect;
pub mod outlier_grey;
pub mod outlier_median;
pub mod outlier_rows;
pub mod outlier_spread;
pub mod outlier_weights;
pub mod outliers;
pub mod peak_copy;
pub mod peak_fma;
pub mod pyramid_merge;
pub mod pyramid_pool;
pub mod sample_priority;
pub mod sample_reduce;
pub mod sample_scan;
pub mod sample_upsample;
pub mod sampling;
pub mod sanitize;
pub mod sanitize_low_spp;
pub mod sanitize_quads;
pub mod spp_total;
pub mod temporal_motion;
pub mod tsvd;
pub mod tsvd_debug;
pub mod wlr;
pub mod wlr_final;
pub mod wlr_fit;

/// A 3σ test's threshold for a mean whose variance is estimated from its own
/// `n` samples: the one-sided `Φ(−3)` quantile of Student's t with
/// `ν = max(n − 1, 1)` degrees of freedom, by its Cornish–Fisher expansion
/// to `ν⁻³` (`z + (z³+z)/4ν + (5z⁵+16z³+3z)/96ν² +
/// (3z⁷+19z⁵+17z³−15z)/384ν³`, `z = 3`). The variance the test divides by
/// is itself estimated, so a few samples need a much larger ratio: 8.5 at 4
/// samples, 3.6 at 16, 3.1 at 64, 3 in the limit. AOS-RESIDUAL and
/// LP-PIXEL-TEST; GLSL `t_threshold3` in `spirv/lib/common.glsl`.
pub fn t_threshold3(n: f64) -> f64 {
    let nu = (n - 1.0).max(1.0);
    let z: f64 = 3.0;
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu * nu * nu)
}

/// The smallest variance LP-PIXEL-TEST and APR-PIXEL-TEST divide by.
pub const PIXEL_TEST_VAR_FLOOR: f64 = 1e-20;

/// LP-PIXEL-TEST and APR-PIXEL-TEST: the limit on a prediction's squared
/// miss at the valid pixel `i` of a `w × h` image,
/// `t²·max(v(i), v̄_i, PIXEL_TEST_VAR_FLOOR)` with `t` = [`t_threshold3`]`(n_i)`
/// and `v̄_i` the mean of `v` over the neighbours that agree with i in its
/// valid 3×3 neighbourhood (raster order, i included), without its largest
/// value: a pixel whose few samples happen to agree has a variance estimate
/// far below its true one, and the local noise says so. A neighbour agrees
/// when its squared distance from i, `dist2(q)`, is at most `t²·(v(q) +
/// v(i))` (PIXEL-TEST-AGREE): a neighbour on a bright light, whose level
/// differs from i's by many of its standard errors, says nothing of i's
/// noise. `spp` gives `n_i`.
pub fn pixel_test_limit(
    w: usize,
    h: usize,
    v: impl Fn(usize) -> f64,
    dist2: impl Fn(usize) -> f64,
    valid: impl Fn(usize) -> bool,
    spp: &[f32],
    i: usize,
) -> f64 {
    let t = t_threshold3(spp_of(spp[i]));
    let vi = v(i);
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    for q in neighbourhood_3x3(w, h, i).filter(|&q| valid(q)) {
        let vq = v(q);
        if q != i && dist2(q) > t * t * (vq + vi) {
            continue;
        }
        sum += vq;
        max = max.max(vq);
        n += 1;
    }
    let vbar = if n > 1 {
        (sum - max) / (n - 1) as f64
    } else {
        sum
    };
    t * t * vi.max(vbar).max(PIXEL_TEST_VAR_FLOOR)
}

/// The pixels of `i`'s 3×3 neighbourhood in a `w × h` image, `i` among
/// them, clipped at the borders, in raster order.
pub fn neighbourhood_3x3(w: usize, h: usize, i: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % w, i / w);
    (y.saturating_sub(1)..(y + 2).min(h))
        .flat_map(move |qy| (x.saturating_sub(1)..(x + 2).min(w)).map(move |qx| qy * w + qx))
}

/// §0.2: the output of an invalid pixel `i` of a `w × h` image, the mean
/// of `value` over the valid pixels of its 3×3 neighbourhood in raster
/// order (0 if none). Every method's fill (WLR, APR, AOS and their twins).
pub fn valid_mean_3x3(
    w: usize,
    h: usize,
    i: usize,
    valid: impl Fn(usize) -> bool,
    value: impl Fn(usize) -> f64,
) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for q in neighbourhood_3x3(w, h, i).filter(|&q| valid(q)) {
        s += value(q);
        n += 1;
    }
    if n > 0 {
        s / n as f64
    } else {
        0.0
    }
}

/// Maps `f` over `0..n` on all cores and returns the results in index
/// order. Indices are interleaved over `std::thread::scope` threads (thread
/// `t` takes `t, t + T, …`), so uneven costs spread evenly; the result does
/// not depend on the thread count. The twins' CPU paths (WLR's pixels, LP's
/// centres, AOS's pixels) share it.
pub fn par_map<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let threads = std::thread::available_parallelism()
        .map(|t| t.get())
        .unwrap_or(1)
        .clamp(1, n.max(1));
    let parts: Vec<Vec<T>> = std::thread::scope(|scope| {
        let f = &f;
        let handles: Vec<_> = (0..threads)
            .map(|t| scope.spawn(move || (t..n).step_by(threads).map(f).collect::<Vec<T>>()))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("par_map: worker panicked"))
            .collect()
    });
    let mut iters: Vec<_> = parts.into_iter().map(|p| p.into_iter()).collect();
    (0..n)
        .map(|i| {
            iters[i % threads]
                .next()
                .expect("par_map: every index mapped")
        })
        .collect()
}

/// The sample count as every kernel reads it (spec §0.2); a pixel is valid iff
/// `spp_of(n) >= 1`. Mirrors `spp_of` in `spirv/lib/common.glsl`.
pub use finalize_stats::spp_of;
