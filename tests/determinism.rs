//! Issue #14's determinism and edge sizes, through the public facade: the
//! same input, device and options give bit-identical colour, error and
//! sample map run after run (a new denoiser and a reused one), for every
//! method with its defaults (the outlier stage included); and every method
//! with a sample map runs on 1×1, 1×N, N×1 and prime sizes smaller than its
//! windows, with finite output and the exact budget.

mod common;

use common::{check_validation, gpu};
use mcdenoise::image::Layer;
use mcdenoise::{Config, Denoiser, Method, Pyramid, Source, StatsImage};

fn fixture() -> StatsImage {
    mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap()
}

/// Every method of the registry, each on the GPU.
fn methods() -> Vec<(Method, bool)> {
    Method::all().map(|m| (m, true)).collect()
}

fn make(img: &StatsImage, method: Method, on_gpu: bool) -> Denoiser {
    make_with(img, Config::new(method), on_gpu)
}

fn make_with(img: &StatsImage, config: Config, on_gpu: bool) -> Denoiser {
    let src = Source::of_image(img);
    if on_gpu {
        Denoiser::new(&gpu(), src, config).unwrap()
    } else {
        Denoiser::new_cpu(src, config).unwrap()
    }
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Colour, error and sample map bit for bit.
fn same_frame(first: &mcdenoise::Frame, other: &mcdenoise::Frame, method: Method) {
    for c in 0..3 {
        assert_eq!(
            bits(&first.color.planes[c]),
            bits(&other.color.planes[c]),
            "{}: colour",
            method.name()
        );
        assert_eq!(
            bits(&first.error.planes[c]),
            bits(&other.error.planes[c]),
            "{}: error",
            method.name()
        );
    }
    assert_eq!(first.samples, other.samples, "{}: samples", method.name());
}

#[test]
fn every_method_is_bit_identical_run_after_run() {
    let img = fixture();
    for &(method, on_gpu) in &methods() {
        let a = make(&img, method, on_gpu);
        let first = a.denoise(&img, Some(10_000)).unwrap();
        let again = a.denoise(&img, Some(10_000)).unwrap();
        let fresh = make(&img, method, on_gpu)
            .denoise(&img, Some(10_000))
            .unwrap();
        for other in [&again, &fresh] {
            same_frame(&first, other, method);
        }
    }
    check_validation(&gpu());
}

/// `img` mirrored left to right, every layer alike: another image of the
/// same size and kind.
fn mirrored(img: &StatsImage) -> StatsImage {
    let (w, h) = (img.width, img.height);
    let mut out = StatsImage::new(w, h);
    for (layer, planes) in img.layers() {
        let flipped = planes
            .iter()
            .map(|p| (0..w * h).map(|i| p[i - i % w + (w - 1 - i % w)]).collect())
            .collect();
        out.set(layer, flipped);
    }
    out
}

/// A denoiser that has denoised one image gives the next exactly what a
/// new one gives it: nothing of a call outlives it without the temporal
/// stage.
#[test]
fn a_reused_denoiser_forgets_the_previous_image() {
    let img = fixture();
    let other = mirrored(&img);
    for &(method, on_gpu) in &methods() {
        let a = make(&img, method, on_gpu);
        a.denoise(&img, Some(10_000)).unwrap();
        let second = a.denoise(&other, Some(10_000)).unwrap();
        let fresh = make(&other, method, on_gpu)
            .denoise(&other, Some(10_000))
            .unwrap();
        same_frame(&fresh, &second, method);
    }
    check_validation(&gpu());
}

#[test]
fn every_method_runs_on_edge_sizes() {
    let img = fixture();
    for &(w, h) in &[(1, 1), (1, 17), (23, 1), (2, 2), (13, 7), (37, 23)] {
        let crop = img.crop(5, 9, w, h);
        for &(method, on_gpu) in &methods() {
            let budget = 3 * (w * h) as u32 + 1;
            let f = make(&crop, method, on_gpu)
                .denoise(&crop, Some(budget))
                .unwrap_or_else(|e| panic!("{} {w}x{h}: {e}", method.name()));
            let what = format!("{} {w}x{h}", method.name());
            for c in 0..3 {
                assert!(
                    f.color.planes[c].iter().all(|v| v.is_finite() && *v >= 0.0),
                    "{what}: colour"
                );
                assert!(
                    f.error.planes[c].iter().all(|v| v.is_finite()),
                    "{what}: error"
                );
            }
            let s: u64 = f.samples.unwrap().iter().map(|&s| s as u64).sum();
            assert_eq!(s, budget as u64, "{what}: budget");
        }
    }
    check_validation(&gpu());
}

/// `Config::low_spp = false` skips spec §0.4 step 3, which only changes
/// pixels with `1 <= spp < 2`: on the 16-spp fixture the output is
/// bit-identical either way; with some one-sample pixels it is not (their
/// variance then stays 0 instead of coming from the neighbours).
#[test]
fn low_spp_off_is_exact_without_one_sample_pixels() {
    let img = fixture();
    assert!(!mcdenoise::has_low_spp(&img));
    let run = |img: &StatsImage, low_spp: bool| {
        let mut cfg = Config::new(Method::Lp);
        cfg.low_spp = low_spp;
        let d = Denoiser::new(&gpu(), Source::of_image(img), cfg).unwrap();
        bits(&d.denoise(img, None).unwrap().color.planes.concat())
    };
    assert_eq!(run(&img, true), run(&img, false));
    let mut one = img.clone();
    let mut spp = one.get(Layer::Spp).unwrap().to_vec();
    for i in (0..spp[0].len()).step_by(7) {
        spp[0][i] = 1.0;
    }
    one.set(Layer::Spp, spp);
    assert!(mcdenoise::has_low_spp(&one));
    assert_ne!(run(&one, true), run(&one, false));
}

/// Issue #14's numeric range, through the facade on the GPU, every method
/// with its defaults and a sample map: a pixel of colour 1e30 with variance
/// 1e30 (its square overflows f32), one with a denormal variance (1e-40),
/// one with a single sample next to pixels with 5000. The output, the error
/// estimate and the map stay finite, the budget is exact, the huge pixel
/// keeps its value (every method passes it through: its variance gives it no
/// weight in its neighbours' fits) and the pixels away from the changed
/// ones keep the image they have without them.
#[test]
fn huge_tiny_and_mixed_sample_counts_stay_finite() {
    let base = fixture().crop(0, 0, 64, 64);
    let mut img = base.clone();
    let huge = 40 * 64 + 20;
    let mut colour = img.get(Layer::Color).unwrap().to_vec();
    let mut var = img.get(Layer::ColorVariance).unwrap().to_vec();
    let mut spp = img.get(Layer::Spp).unwrap().to_vec();
    for c in 0..3 {
        colour[c][huge] = 1e30;
        var[c][huge] = 1e30;
        var[c][10 * 64 + 50] = 1e-40;
    }
    for i in [30 * 64 + 40, 30 * 64 + 41, 31 * 64 + 40, 31 * 64 + 41] {
        spp[0][i] = 5000.0;
    }
    spp[0][30 * 64 + 42] = 1.0;
    img.set(Layer::Color, colour);
    img.set(Layer::ColorVariance, var);
    img.set(Layer::Spp, spp);
    for &(method, on_gpu) in &methods() {
        let budget = 4 * 64 * 64;
        let f = make(&img, method, on_gpu)
            .denoise(&img, Some(budget))
            .unwrap_or_else(|e| panic!("{}: {e}", method.name()));
        let what = method.name();
        for c in 0..3 {
            let bad = f.color.planes[c].iter().filter(|v| !v.is_finite()).count();
            assert_eq!(bad, 0, "{what}: {bad} non-finite colour values");
            let bad = f.error.planes[c].iter().filter(|v| !v.is_finite()).count();
            assert_eq!(bad, 0, "{what}: {bad} non-finite error values");
        }
        let s: u64 = f.samples.unwrap().iter().map(|&s| s as u64).sum();
        assert_eq!(s, budget as u64, "{what}: budget");
        // The huge pixel keeps its value (no method spreads it), and the
        // pixels more than 28 from every changed pixel (APR's reach: a block
        // centre up to 14 away, its radius 14) keep the unchanged image's
        // output.
        assert_eq!(f.color.planes[0][huge], 1e30, "{what}: the huge pixel");
        // The reach below is the methods' own: `auto`'s default pyramid
        // (PYRAMID-AUTO) doubles it, past this 64×64 image, and GBF-NLM's
        // albedo NL-means adds 8 to the prefilter's (a pixel 29 from a
        // changed one moved in `auto`), so the comparison runs without them.
        let mut local = Config::new(method);
        local.pyramid = Pyramid::Off;
        local.options = mcdenoise::Options::parse(&["gbf.albedo_nlm=off"]).unwrap();
        let f = make_with(&img, local.clone(), on_gpu)
            .denoise(&img, Some(budget))
            .unwrap();
        let plain = make_with(&base, local, on_gpu)
            .denoise(&base, None)
            .unwrap();
        let changed = [
            (20, 40),
            (50, 10),
            (40, 30),
            (41, 30),
            (42, 30),
            (40, 31),
            (41, 31),
        ];
        let mut compared = 0;
        for i in 0..64 * 64 {
            let (x, y) = ((i % 64) as i64, (i / 64) as i64);
            if changed
                .iter()
                .any(|&(cx, cy)| (x - cx).abs().max((y - cy).abs()) <= 28)
            {
                continue;
            }
            compared += 1;
            for c in 0..3 {
                let (a, b) = (f.color.planes[c][i], plain.color.planes[c][i]);
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs().max(1.0),
                    "{what}: pixel ({x}, {y}) {a} against {b} without the changes"
                );
            }
        }
        assert!(compared > 150, "{compared}");
    }
    check_validation(&gpu());
}

/// The chain sanitises and prefilters the uploaded statistics in place (one
/// copy on the device): every GPU call consumes its upload. A call without a
/// new upload is a clear error, not a second sanitation of sanitised data;
/// `upload` + `run` + `read` and `denoise_owned` give `denoise`'s output bit
/// for bit, and the statistics `statistics()` returns are those of the call.
#[test]
fn a_gpu_call_consumes_its_upload() {
    let img = fixture();
    let ctx = gpu();
    for method in [Method::Lp, Method::None] {
        let d = Denoiser::new(&ctx, Source::of_image(&img), Config::new(method)).unwrap();
        let first = d.denoise(&img, Some(5_000)).unwrap();
        let clean = d.statistics().unwrap();
        let err = d.run(None, Some(5_000)).unwrap_err().to_string();
        assert!(err.contains("upload"), "{}: {err}", method.name());
        d.upload(&img).unwrap();
        d.run(None, Some(5_000)).unwrap();
        let again = d.read().unwrap();
        let owned = d.denoise_owned(img.clone(), Some(5_000)).unwrap();
        for other in [&again, &owned] {
            same_frame(&first, other, method);
            assert_eq!(first.report.counters, other.report.counters);
        }
        let clean_again = d.statistics().unwrap();
        for (l, p) in clean.layers() {
            let q = clean_again.get(l).unwrap();
            for c in 0..p.len() {
                assert_eq!(bits(&p[c]), bits(&q[c]), "{}: {}", method.name(), l.name());
            }
        }
        // An image of another size is refused before anything is written.
        let crop = img.crop(0, 0, 8, 8);
        assert!(d.upload(&crop).is_err());
    }
    check_validation(&ctx);
}

/// `Config::error = false` skips the download of the error estimate and
/// of the local dimension (and LP's gather skips the planes nobody reads):
/// the frame's error and dimension are empty, and the colour and sample map
/// are those of a call that downloads them, on one chain and in tiles,
/// with and without a sample map.
#[test]
fn without_the_error_download_nothing_else_changes() {
    let img = fixture();
    // Tiles of 40 px over a 48×24 crop: two tiles, each with its halo.
    let crop = img.crop(0, 0, 48, 24);
    for (method, _) in &methods() {
        for (img, tile, budget) in [
            (&img, None, None),
            (&img, None, Some(2 * 64 * 64)),
            (&crop, Some(40), Some(4096)),
        ] {
            let run = |error: bool| {
                let mut config = Config::new(*method);
                config.error = error;
                config.tile = tile;
                let d = Denoiser::new(&gpu(), Source::of_image(img), config).unwrap();
                assert_eq!(d.tiles().is_some(), tile.is_some());
                d.denoise(img, budget).unwrap()
            };
            let (with, without) = (run(true), run(false));
            let what = format!("{} tile {tile:?} budget {budget:?}", method.name());
            let (w, h) = (img.width, img.height);
            assert_eq!((with.error.width, with.error.height), (w, h), "{what}");
            assert_eq!(
                (without.error.width, without.error.height),
                (0, 0),
                "{what}"
            );
            for c in 0..3 {
                assert_eq!(
                    bits(&with.color.planes[c]),
                    bits(&without.color.planes[c]),
                    "{what}: colour"
                );
            }
            assert_eq!(with.samples, without.samples, "{what}: samples");
            assert_eq!(with.dim.len(), w * h, "{what}: dimension");
            assert!(without.dim.is_empty(), "{what}: dimension downloaded");
        }
    }
    check_validation(&gpu());
}
