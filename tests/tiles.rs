//! Issue #14's tiling, through the public facade: an image denoised in
//! tiles with their halos (`methods::tiles`) gives output bit-identical to
//! the whole image's — colour, error, local dimension, the sample map, the
//! sanitation report and LP's centre fraction — for every method with its
//! defaults (outlier stage and G-buffer prefilter included; the whole
//! image's outlier spread with `outliers.wide=0`, as tiles run it), with
//! tiles cut along x and along y. The images are strips (480×32, 32×480: ≤ 128²
//! pixels) so that tiles are narrower than the image by more than twice the
//! largest halo (APR's 242 px) while the suite stays small. The input has
//! what the halo must carry across a cut: fireflies (the outlier stage)
//! next to tile borders, non-finite values and negative variances
//! (sanitation step 1–2), one-sample and empty pixels (step 3, §0.2).
//! The 4096² and 4099×2053 runs are the ignored
//! `large_images_through_every_method`.

mod common;

use common::{check_validation, gpu, own_gpu};
use mcdenoise::gpu::Precision;
use mcdenoise::image::Layer;
use mcdenoise::{
    Config, Denoiser, Error, Frame, Method, Outliers, Prefilter, Pyramid, Source, StatsImage,
};

/// The committed 64² fixture (with positions: the prefilter runs) repeated
/// over `w × h`, with the hazards of the module documentation planted at
/// columns (or rows) near the cuts of 60-pixel tiles.
fn strip(w: usize, h: usize) -> StatsImage {
    let src = mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap();
    let mut img = StatsImage::new(w, h);
    for (layer, planes) in src.layers() {
        let tiled = planes
            .iter()
            .map(|p| {
                (0..w * h)
                    .map(|i| p[(i / w % 64) * 64 + i % w % 64])
                    .collect()
            })
            .collect();
        img.set(layer, tiled);
    }
    let along = |t: usize| {
        if w >= h {
            (t % w, h / 2)
        } else {
            (w / 2, t % h)
        }
    };
    let at = |t: usize| {
        let (x, y) = along(t);
        y * w + x
    };
    // Fireflies on both sides of cuts and deep inside halos.
    for (k, t) in [59, 60, 61, 119, 180, 241, 300, 361, 420]
        .into_iter()
        .enumerate()
    {
        let i = at(t) + k % 3;
        for c in 0..3 {
            img.get_mut(Layer::Color).unwrap()[c][i] *= 1000.0;
            img.get_mut(Layer::ColorVariance).unwrap()[c][i] *= 1e6;
        }
    }
    // A band of pixels with four times the samples, as a sample map leaves
    // them, across the cut at 120 (APR-COUNT-CAP takes the whole image's
    // mean count).
    for t in 100..140 {
        for d in 0..3 {
            let i = at(t) + d * if w >= h { w } else { 1 };
            img.get_mut(Layer::Spp).unwrap()[0][i] *= 4.0;
            for c in 0..3 {
                img.get_mut(Layer::ColorVariance).unwrap()[c][i] /= 4.0;
            }
        }
    }
    img.get_mut(Layer::Color).unwrap()[1][at(62)] = f32::NAN;
    img.get_mut(Layer::Color).unwrap()[0][at(238)] = f32::INFINITY;
    img.get_mut(Layer::ColorVariance).unwrap()[2][at(121)] = -1.0;
    img.get_mut(Layer::Spp).unwrap()[0][at(179)] = 0.0;
    img.get_mut(Layer::Spp).unwrap()[0][at(299)] = 1.0;
    img.get_mut(Layer::Spp).unwrap()[0][at(302)] = 1.0;
    img
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn assert_identical(what: &str, a: &Frame, b: &Frame) {
    let w = a.color.width;
    for c in 0..3 {
        let (pa, pb) = (&a.color.planes[c], &b.color.planes[c]);
        let diff: Vec<usize> = (0..pa.len())
            .filter(|&i| pa[i].to_bits() != pb[i].to_bits())
            .collect();
        if let Some(&i) = diff.first() {
            panic!(
                "{what}: colour {c} differs at {} pixels, first ({}, {}): {} against {}",
                diff.len(),
                i % w,
                i / w,
                pa[i],
                pb[i]
            );
        }
        assert_eq!(
            bits(&a.color.planes[c]),
            bits(&b.color.planes[c]),
            "{what}: colour {c}"
        );
        assert_eq!(
            bits(&a.error.planes[c]),
            bits(&b.error.planes[c]),
            "{what}: error {c}"
        );
    }
    assert_eq!(bits(&a.dim), bits(&b.dim), "{what}: local dimension");
    assert_eq!(a.samples, b.samples, "{what}: sample map");
    assert_eq!(a.report.counters, b.report.counters, "{what}: repairs");
    assert_eq!(
        a.report.invalid_pixels, b.report.invalid_pixels,
        "{what}: invalid pixels"
    );
    assert_eq!(a.stats, b.stats, "{what}: statistics");
    assert_eq!(a.debug.len(), b.debug.len(), "{what}: debug layers");
    for ((na, pa), (nb, pb)) in a.debug.iter().zip(&b.debug) {
        assert_eq!(na, nb, "{what}: debug layer names");
        assert_eq!(bits(pa), bits(pb), "{what}: debug layer {na}");
    }
}

/// `config` with the outlier stage's spec window (`outliers.wide=0`), which
/// is what tiles run (OUTLIER-WIDE: `outlier_wide_is_not_tiled`).
fn one_spread_window(mut config: Config) -> Config {
    config.options = mcdenoise::methods::outliers::one_window(&config.options).unwrap();
    config
}

/// Runs `config` on `img` whole and in tiles of `tile` px, both with
/// [`one_spread_window`]; checks that the tiles really cut the image (some
/// tile reads less than all of it) and that the outputs are bit-identical.
fn check(img: &StatsImage, config: Config, tile: usize, what: &str) {
    let config = one_spread_window(config);
    let ctx = gpu();
    let budget = Some((img.width * img.height * 3) as u32);
    let whole = Denoiser::new(&ctx, Source::of_image(img), config.clone()).unwrap();
    assert!(whole.tiles().is_none(), "{what}: a small image runs whole");
    let a = whole.denoise(img, budget).unwrap();
    drop(whole);
    let tiled = Denoiser::new(
        &ctx,
        Source::of_image(img),
        Config {
            tile: Some(tile),
            ..config
        },
    )
    .unwrap();
    let (tiles, halo) = tiled.tiles().expect("tiles were asked for");
    let (w, h) = (img.width, img.height);
    assert!(tiles.len() > 1, "{what}: {} tile", tiles.len());
    assert!(
        tiles.iter().any(|t| t.outer.pixels() < w * h),
        "{what}: every tile reads the whole image (halo {halo})"
    );
    let b = tiled.denoise(img, budget).unwrap();
    assert_eq!(
        b.samples
            .as_ref()
            .map(|s| s.iter().map(|&v| v as u64).sum::<u64>()),
        budget.map(u64::from),
        "{what}: the budget"
    );
    println!("{what}: {} tiles, halo {halo}: identical", tiles.len());
    assert_identical(what, &a, &b);
}

#[test]
fn every_method_tiled_along_x_is_bit_identical() {
    let img = strip(480, 32);
    // AOS, the slowest per pixel, reaches 159-183 px: half the strip still
    // has tiles that read less than the whole (its hazards wrap into it),
    // and half its height, as every case with AOS below: each of its tiles
    // reads nearly the whole strip.
    let short = strip(240, 16);
    for method in Method::all().filter(|&m| m != Method::None) {
        // `auto`'s default pyramid doubles a halo of ~200 px: wider than
        // this strip (the pyramid in tiles is the next test's).
        let mut c = Config::new(method);
        c.pyramid = Pyramid::Off;
        let img = match method {
            Method::Aos => &short,
            _ => &img,
        };
        let what = format!("{} {}x{}", method.name(), img.width, img.height);
        check(img, c, 60, &what);
    }
    // AOS with the G-buffer prefilter (not its default since AOS-NO-GBF):
    // its NL-means then filters only visibility (PREFILTER-STACK).
    // Its halo, 183, needs a strip wider than 60 + 183 px.
    let mut aos_gbf = Config::new(Method::Aos);
    aos_gbf.prefilter = Prefilter::On;
    check(&strip(272, 16), aos_gbf, 60, "aos --prefilter gbf 272x16");
    // `auto` with AOS as a fourth member (AUTO-AOS): recorded before the
    // prefilter the others read, in every tile.
    let mut auto_aos = Config::new(Method::Auto);
    auto_aos.pyramid = Pyramid::Off;
    auto_aos.options = mcdenoise::Options::parse(&["auto.aos=on"]).unwrap();
    check(&strip(480, 16), auto_aos, 60, "auto auto.aos=on 480x16");
    check_validation(&gpu());
}

#[test]
fn tiles_along_y_and_the_stages_of_none_are_bit_identical() {
    let img = strip(32, 480);
    let mut lp = Config::new(Method::Lp);
    lp.debug = true;
    check(&img, lp, 60, "lp 32x480 with debug layers");
    // `none` with the outlier stage and the prefilter forced on: the stages
    // around the method, cheaply, along both axes.
    let mut none = Config::new(Method::None);
    none.outliers = Outliers::On;
    none.prefilter = Prefilter::On;
    none.debug = true;
    check(&img, none.clone(), 50, "none + outliers + prefilter 32x480");
    check(
        &strip(480, 32),
        none,
        50,
        "none + outliers + prefilter 480x32",
    );
    check_validation(&gpu());
}

/// The pyramid's low band in tiles: the coarse level's halo counts
/// twice and tiles start on twice the alignment (PYRAMID-LOWBAND).
#[test]
fn the_pyramid_tiled_is_bit_identical() {
    // LP's halo with the stage is 417 px (GBF-SECOND's pass counts twice):
    // a strip wide enough that an edge tile reads less than all of it.
    let wide = strip(544, 32);
    for method in [Method::Wlr, Method::Lp] {
        let mut c = Config::new(method);
        c.pyramid = Pyramid::On;
        check(&wide, c, 60, &format!("{} --pyramid 544x32", method.name()));
    }
    let img = strip(480, 32);
    // The tightest halo (an adaptive pass's WLR without the outlier stage
    // and the prefilter: 37 px).
    let mut c = Config::new(Method::Wlr);
    c.pyramid = Pyramid::On;
    c.pass = mcdenoise::Pass::Intermediate;
    c.outliers = Outliers::Off;
    c.prefilter = Prefilter::Off;
    check(&img, c.clone(), 60, "wlr intermediate --pyramid 480x32");
    check(&strip(32, 480), c, 60, "wlr intermediate --pyramid 32x480");
    // APR's coarse level takes the whole coarse image's mean count
    // (APR-COUNT-CAP); one stage, no outlier stage or prefilter keep its
    // halo within the strip.
    let mut c = Config::new(Method::Apr);
    c.pyramid = Pyramid::On;
    c.outliers = Outliers::Off;
    c.prefilter = Prefilter::Off;
    c.options = mcdenoise::Options::parse(&["apr.stages=1".to_string()]).unwrap();
    check(&img, c, 60, "apr one stage --pyramid 480x32");
    // `auto` with its default, the stage (PYRAMID-AUTO): a halo of ~475,
    // so an edge tile of 200 reads 675 px of 1024 (16 rows: 128² pixels).
    check(
        &strip(1024, 16),
        Config::new(Method::Auto),
        200,
        "auto (default pyramid) 1024x16",
    );
    check_validation(&gpu());
}

/// The input blend in tiles (INPUT-BLEND): every method's default but
/// `auto`'s runs it (the tests above); a variance window wider than the
/// method's own reach widens the halo (an adaptive pass's WLR without the
/// outlier stage and the prefilter reaches 8 px, `blend.radius` 16), and
/// so does the residual's window (BLEND-RESIDUAL).
#[test]
fn the_input_blend_tiled_is_bit_identical() {
    let img = strip(480, 32);
    let mut c = Config::new(Method::Wlr);
    c.input_blend = mcdenoise::InputBlend::On;
    c.pass = mcdenoise::Pass::Intermediate;
    c.outliers = Outliers::Off;
    c.prefilter = Prefilter::Off;
    c.options = mcdenoise::Options::parse(&["blend.radius=16".to_string()]).unwrap();
    check(
        &img,
        c.clone(),
        60,
        "wlr intermediate --input-blend r 16 480x32",
    );
    check(
        &strip(32, 480),
        c,
        60,
        "wlr intermediate --input-blend r 16 32x480",
    );
    // The residual's window reads the method's output (BLEND-RESIDUAL):
    // the halo holds the method's reach beyond it. (With k = 0 and z = 0
    // the bound decides every pixel where it is positive.)
    let mut c = Config::new(Method::Wlr);
    c.input_blend = mcdenoise::InputBlend::On;
    c.outliers = Outliers::Off;
    c.prefilter = Prefilter::Off;
    c.options = mcdenoise::Options::parse(&[
        "blend.radius=0".to_string(),
        "blend.k=0".to_string(),
        "blend.z=0".to_string(),
        "blend.residual_radius=16".to_string(),
    ])
    .unwrap();
    check(&img, c, 60, "wlr --input-blend s 16 480x32");
    check_validation(&gpu());
}

#[test]
fn a_memory_cap_tiles_automatically_and_identically() {
    // Its own context: the peak allocation it measures must not count the
    // other tests of this binary, which run beside it.
    let ctx = own_gpu();
    let img = strip(1024, 16);
    let config = one_spread_window(Config::new(Method::Lp));
    let before = ctx.allocated_bytes();
    let whole = Denoiser::new(&ctx, Source::of_image(&img), config.clone()).unwrap();
    let whole_bytes = ctx.allocated_bytes() - before;
    let a = whole.denoise(&img, None).unwrap();
    drop(whole);
    // A cap of 75 % of what the whole chain holds: tiles of ≈ 250 px
    // (plus 2 × 209 of halo and up to 15 of alignment) fit it.
    let cap = whole_bytes * 3 / 4;
    let capped = Config {
        max_memory: Some(cap),
        ..config.clone()
    };
    let d = Denoiser::new(&ctx, Source::of_image(&img), capped).unwrap();
    let (tiles, _) = d.tiles().expect("the cap forces tiles");
    assert!(tiles.len() > 1);
    let before = ctx.allocated_bytes();
    ctx.reset_peak();
    let b = d.denoise(&img, None).unwrap();
    let peak = ctx.peak_allocated_bytes() - before;
    println!(
        "whole chain {:.1} MB; cap {:.1} MB: {} tiles, peak device allocation {:.1} MB",
        whole_bytes as f64 / 1e6,
        cap as f64 / 1e6,
        tiles.len(),
        peak as f64 / 1e6
    );
    assert!(peak <= cap, "peak {peak} bytes over the cap of {cap}");
    assert_identical("lp capped", &a, &b);
    // A cap too small for any tile is a clear error, not a panic.
    let tiny = Config {
        max_memory: Some(whole_bytes / 20),
        ..config
    };
    match Denoiser::new(&ctx, Source::of_image(&img), tiny) {
        Err(Error::Limit(m)) => assert!(m.contains("memory cap"), "{m}"),
        other => panic!("expected a limit error, got {other:?}"),
    }
    check_validation(&ctx);
}

#[test]
fn a_tiled_denoiser_says_what_it_cannot_do() {
    let ctx = gpu();
    let img = strip(128, 32);
    let d = Denoiser::new(
        &ctx,
        Source::of_image(&img),
        Config {
            tile: Some(40),
            ..Config::new(Method::None)
        },
    )
    .unwrap();
    d.denoise(&img, None).unwrap();
    for e in [d.outputs().err(), d.read().err()] {
        match e {
            Some(Error::Limit(m)) => assert!(m.contains("tiles"), "{m}"),
            other => panic!("expected a limit error, got {other:?}"),
        }
    }
    // Tiles read statistics in host memory, not a renderer's accumulation.
    let layout = mcdenoise::AccumLayout::new(128, 32, false, false);
    let r = Denoiser::new(
        &ctx,
        Source::Accum(layout),
        Config {
            tile: Some(40),
            ..Config::new(Method::Lp)
        },
    );
    assert!(matches!(r, Err(Error::InvalidArgument(_))), "{r:?}");
    check_validation(&ctx);
}

/// The large cases of issue #14 (ignored; run with `--ignored --nocapture`):
/// 4096×4096 and 4099×2053 through every method with its defaults, tiled as
/// the default memory cap decides, with a sample map. Prints wall time, the
/// tiles, peak device allocation and peak resident memory per case; checks
/// finite output and the exact budget. `MCDENOISE_LARGE_INPUT`: a statistics
/// EXR, mirrored and repeated to size (default: the built-in `mix` scene
/// rendered at 512², 16 spp, into a temporary directory).
/// `MCDENOISE_LARGE_METHODS` (e.g. `lp,apr`) and `MCDENOISE_LARGE_SIZES`
/// (e.g. `4099x2053`) narrow the run; `MCDENOISE_LARGE_WHOLE=1` also runs
/// each case untiled under a 20 GB cap where its bindings fit, and checks
/// that the tiled output is bit-identical.
#[test]
#[ignore]
fn large_images_through_every_method() {
    let ctx = gpu();
    let dir = std::env::temp_dir().join(format!("mcdenoise-large-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let input = match std::env::var_os("MCDENOISE_LARGE_INPUT") {
        Some(p) => std::path::PathBuf::from(p),
        None => {
            let stats = dir.join("mix_512_16.exr");
            let status = std::process::Command::new(env!("CARGO_BIN_EXE_mcdenoise"))
                .args([
                    "-q", "render", "--scene", "mix", "--spp", "16", "--size", "512x512",
                ])
                .args(["--method", "none", "-o"])
                .arg(dir.join("none.exr"))
                .arg("--save-stats")
                .arg(&stats)
                .status()
                .unwrap();
            assert!(status.success(), "rendering the input");
            stats
        }
    };
    let base = mcdenoise::io::read_stats(&input).unwrap();
    let methods: Vec<Method> = match std::env::var("MCDENOISE_LARGE_METHODS") {
        Ok(list) => list
            .split(',')
            .map(|m| Method::from_name(m).unwrap_or_else(|| panic!("unknown method {m}")))
            .collect(),
        Err(_) => Method::all().collect(),
    };
    let sizes: Vec<(usize, usize)> = match std::env::var("MCDENOISE_LARGE_SIZES") {
        Ok(list) => list
            .split(',')
            .map(|s| {
                let (w, h) = s.trim().split_once('x').expect("WxH");
                (w.parse().unwrap(), h.parse().unwrap())
            })
            .collect(),
        Err(_) => vec![(4099, 2053), (4096, 4096)],
    };
    let whole = std::env::var("MCDENOISE_LARGE_WHOLE").is_ok_and(|v| v == "1");
    println!(
        "| size | method | tiles | halo | tile interior | wall s | peak device MB | peak RSS MB | whole run |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for &(w, h) in &sizes {
        let img = mirrored(&base, w, h);
        let budget = Some((w * h * 4) as u32);
        for &method in &methods {
            let mut config = Config::new(method);
            config.low_spp = mcdenoise::has_low_spp(&img);
            let run = |config: Config| -> Option<Run> {
                let before = ctx.allocated_bytes();
                ctx.reset_peak();
                mcdenoise::bench::reset_peak_rss();
                let t0 = std::time::Instant::now();
                let d = match Denoiser::new(&ctx, Source::of_image(&img), config) {
                    Ok(d) => d,
                    Err(Error::Limit(m)) => {
                        println!("{w}x{h} {}: {m}", method.name());
                        return None;
                    }
                    Err(e) => panic!("{e}"),
                };
                let tiles = d.tiles().map(|(t, halo)| {
                    let side = t
                        .iter()
                        .map(|t| t.inner.width().max(t.inner.height()))
                        .max();
                    (t.len(), halo, side.unwrap_or(0))
                });
                let f = d.denoise(&img, budget).unwrap();
                let secs = t0.elapsed().as_secs_f64();
                let peak = ctx.peak_allocated_bytes().saturating_sub(before);
                Some((
                    f,
                    tiles,
                    secs,
                    peak,
                    mcdenoise::bench::peak_rss_bytes().unwrap_or(0),
                ))
            };
            let (f, tiles, secs, peak, rss) = run(config.clone()).expect("the default cap tiles");
            let sum: u64 = f.samples.as_ref().unwrap().iter().map(|&v| v as u64).sum();
            assert_eq!(
                Some(sum),
                budget.map(u64::from),
                "{w}x{h} {}: budget",
                method.name()
            );
            for c in 0..3 {
                assert!(
                    f.color.planes[c].iter().all(|v| v.is_finite() && *v >= 0.0),
                    "{w}x{h} {}: colour",
                    method.name()
                );
            }
            let whole_note = if whole && tiles.is_some() {
                let big = Config {
                    max_memory: Some(20_000 << 20),
                    ..config.clone()
                };
                match run(big) {
                    Some((g, None, s, p, r)) => {
                        assert_identical(&format!("{w}x{h} {}", method.name()), &g, &f);
                        format!(
                            "identical; whole: {s:.1} s, {:.0} MB device, {:.0} MB RSS",
                            p as f64 / 1e6,
                            r as f64 / 1e6
                        )
                    }
                    Some(_) => "whole run tiled as well".into(),
                    None => "does not fit one chain".into(),
                }
            } else {
                "—".into()
            };
            let (n, halo, side) = tiles.unwrap_or((1, 0, w.max(h)));
            println!(
                "| {w}×{h} | {} | {n} | {halo} | {side} | {secs:.1} | {:.0} | {:.0} | {whole_note} |",
                method.name(),
                peak as f64 / 1e6,
                rss as f64 / 1e6
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    check_validation(&ctx);
}

/// One large run: the frame, (tiles, halo, largest interior side) when
/// tiled, wall seconds, peak device bytes, peak resident bytes.
type Run = (Frame, Option<(usize, usize, usize)>, f64, u64, u64);

/// `base` mirrored and repeated over `w × h` (no seams).
fn mirrored(base: &StatsImage, w: usize, h: usize) -> StatsImage {
    let (bw, bh) = (base.width, base.height);
    let fold = |i: usize, n: usize| {
        let k = i % (2 * n);
        if k < n {
            k
        } else {
            2 * n - 1 - k
        }
    };
    let mut img = StatsImage::new(w, h);
    for (layer, planes) in base.layers() {
        let out = planes
            .iter()
            .map(|p| {
                let mut v = Vec::with_capacity(w * h);
                for y in 0..h {
                    let row = fold(y, bh) * bw;
                    v.extend((0..w).map(|x| p[row + fold(x, bw)]));
                }
                v
            })
            .collect();
        img.set(layer, out);
    }
    img
}

/// WLR's centre-state ring (16 rows of the image's width, one binding) of
/// a wide, short image that runs whole exceeds `maxStorageBufferRange` in
/// f64: a limit error that names it and the way out, raised before any
/// work; in tiles the same image is accepted.
#[test]
fn a_wlr_ring_wider_than_a_binding_is_a_limit_error() {
    let ctx = gpu();
    if !ctx.supports_f64() {
        return;
    }
    let limit = ctx.info().max_storage_buffer_range as usize;
    // 16 rows × width × 92 f64 words over the limit, in at most 512² pixels.
    let w = limit / (16 * 92 * 8) + 8;
    if w * 16 > 512 * 512 {
        return; // a device whose binding is this large tiles such images anyway
    }
    let img = strip(w, 16);
    let config = Config {
        precision: Precision::F64,
        ..Config::new(Method::Wlr)
    };
    match Denoiser::new(&ctx, Source::of_image(&img), config.clone()) {
        Err(Error::Limit(m)) => {
            assert!(
                m.contains("centre-state ring") && m.contains("--tile"),
                "{m}"
            )
        }
        other => panic!("expected a limit error, got {other:?}"),
    }
    let tiled = Config {
        tile: Some(4096),
        ..config
    };
    assert!(Denoiser::new(&ctx, Source::of_image(&img), tiled).is_ok());
    check_validation(&ctx);
}

/// What `mcdenoise prefilter` writes, tiled: the sanitised, prefiltered
/// statistics gathered from the tiles' interiors equal, bit for bit, those
/// of one chain over the whole image (every layer, along both axes), with
/// and without GBF-SECOND's pass (`gbf.second_below=32` filters the 16-spp
/// fixture's pixels twice; its default, 8, once).
#[test]
fn tiled_statistics_are_those_of_one_chain() {
    let ctx = gpu();
    for (w, h, second) in [
        (160, 24, "8"),
        (24, 160, "8"),
        (160, 24, "32"),
        (24, 160, "32"),
    ] {
        let img = strip(w, h);
        let mut config = Config::new(Method::None);
        config.prefilter = Prefilter::On;
        config.options =
            mcdenoise::Options::parse(&[format!("gbf.second_below={second}")]).unwrap();
        let whole = Denoiser::new(&ctx, Source::of_image(&img), config.clone()).unwrap();
        assert!(whole.tiles().is_none());
        let (_, a) = whole.denoise_with_statistics(&img, None).unwrap();
        let tiled = Denoiser::new(
            &ctx,
            Source::of_image(&img),
            Config {
                tile: Some(40),
                ..config
            },
        )
        .unwrap();
        assert!(tiled.tiles().is_some_and(|(t, _)| t.len() > 1));
        let (_, b) = tiled.denoise_with_statistics(&img, None).unwrap();
        let la: Vec<Layer> = a.layers().map(|(l, _)| l).collect();
        let lb: Vec<Layer> = b.layers().map(|(l, _)| l).collect();
        assert_eq!(la, lb, "{w}x{h}: layers");
        assert!(la.contains(&Layer::Normal) && la.contains(&Layer::ColorVariance));
        for (layer, planes) in a.layers() {
            for (c, (pa, pb)) in planes.iter().zip(b.get(layer).unwrap()).enumerate() {
                let diff = pa
                    .iter()
                    .zip(pb)
                    .position(|(x, y)| x.to_bits() != y.to_bits());
                assert!(
                    diff.is_none(),
                    "{w}x{h} {}[{c}]: pixel {diff:?}",
                    layer.name()
                );
            }
        }
    }
    check_validation(&ctx);
}

/// OUTLIER-CLIP: round r keeps a pixel by what round r − 1 kept within the
/// detection radius (14), so each round widens the halo by 14; WLR's halo
/// with the defaults (two rounds) is the documented 175.
#[test]
fn each_clip_round_widens_the_halo_by_the_detection_radius() {
    let ctx = gpu();
    let img = strip(480, 32);
    // WLR's halo with these options (none: the defaults).
    let halo = |opts: &[String]| {
        let mut c = Config::new(Method::Wlr);
        c.tile = Some(60);
        c.options = mcdenoise::Options::parse(opts).unwrap();
        let d = Denoiser::new(&ctx, Source::of_image(&img), c).unwrap();
        d.tiles().expect("tiles were asked for").1
    };
    let rounds = |r: u32| halo(&[format!("outliers.clip={r}")]);
    let (h0, h1, h2) = (rounds(0), rounds(1), rounds(2));
    assert_eq!((h1 - h0, h2 - h0), (14, 28));
    assert_eq!(h2, halo(&[]));
    assert_eq!(h2, 175);
    check_validation(&ctx);
}

/// The documented halos with the defaults (`src/methods/tiles.rs`): WLR
/// 175, LP 209, APR 242, AOS with the prefilter 183. GBF-NLM's search and
/// patch radii (8 px) count where `gbf.albedo_nlm=auto` turns it on (not
/// for LP) and only after the prefilter (not AOS's default).
/// WLR-VIS (`wlr.extra_features=visibility`) in tiles, with the default
/// stages and without them (then the halo is WLR's own, which the
/// visibility's NL-means widens by its search and patch radii).
#[test]
fn the_visibility_feature_tiled_is_bit_identical() {
    // (Wider than 60 px plus the default stages' halo, 183 px.)
    let mut img = strip(480, 16);
    let (w, n) = (img.width, img.width * img.height);
    // A soft shadow edge every 40 columns, and noise of known variance.
    let mut rng = common::Rng(11);
    let vis: Vec<f32> = (0..n)
        .map(|i| {
            let x = (i % w) as f64;
            let v = 0.5 + 0.5 * ((x % 40.0 - 20.0) / 4.0).tanh();
            (v + 0.05 * rng.normal()) as f32
        })
        .collect();
    img.set(Layer::Visibility, vec![vis]);
    img.set(Layer::VisibilityVariance, vec![vec![0.0025; n]]);
    let mut c = Config::new(Method::Wlr);
    c.options = mcdenoise::Options::parse(&["wlr.extra_features=visibility"]).unwrap();
    check(&img, c.clone(), 60, "wlr wlr.extra_features=visibility");
    c.outliers = Outliers::Off;
    c.prefilter = Prefilter::Off;
    c.input_blend = mcdenoise::InputBlend::Off;
    check(&img, c, 60, "wlr wlr.extra_features=visibility, no stage");
    // APR-VIS: APR filters the visibility by default.
    check(
        &img,
        Config::new(Method::Apr),
        60,
        "apr apr.visibility=filtered",
    );
    check_validation(&gpu());
}

#[test]
fn the_documented_halos_and_gbf_nlm_reach() {
    let ctx = gpu();
    let img = strip(480, 32);
    let halo = |method: Method, prefilter: Prefilter, opts: &[&str]| {
        let mut c = Config::new(method);
        c.tile = Some(60);
        c.prefilter = prefilter;
        c.options = mcdenoise::Options::parse(opts).unwrap();
        let d = Denoiser::new(&ctx, Source::of_image(&img), c).unwrap();
        d.tiles().expect("tiles were asked for").1
    };
    let cases = [
        (Method::Wlr, Prefilter::Auto, 175, 167),
        (Method::Lp, Prefilter::Auto, 209, 209),
        (Method::Apr, Prefilter::Auto, 251, 243),
        (Method::Aos, Prefilter::On, 184, 176),
    ];
    for (m, pf, default, off) in cases {
        assert_eq!(halo(m, pf, &[]), default, "{m:?}");
        let without = halo(m, pf, &["gbf.albedo_nlm=off"]);
        assert_eq!(without, off, "{m:?} without GBF-NLM");
        let with = halo(m, pf, &["gbf.albedo_nlm=on"]);
        assert_eq!(with, off + 8, "{m:?} with GBF-NLM");
    }
    let aos = halo(Method::Aos, Prefilter::Auto, &[]);
    assert_eq!(
        halo(Method::Aos, Prefilter::Auto, &["gbf.albedo_nlm=on"]),
        aos
    );
    assert!(aos < 175, "AOS without the prefilter: {aos}");
    check_validation(&ctx);
}

/// OUTLIER-WIDE does not run in tiles: its 431×431 window would add 430 px
/// to every halo. A tiled run with the default options has the halo and the
/// output of a whole run with `outliers.wide=0`, and differs from the whole
/// run with the default where fireflies far brighter than their windows
/// (each sent wide there) stand.
#[test]
fn outlier_wide_is_not_tiled() {
    let ctx = gpu();
    let mut none = Config::new(Method::None);
    none.outliers = Outliers::On;
    let img = strip(480, 32);
    let halo = |c: &Config| {
        let c = Config {
            tile: Some(60),
            ..c.clone()
        };
        let d = Denoiser::new(&ctx, Source::of_image(&img), c).unwrap();
        d.tiles().expect("tiles were asked for").1
    };
    assert_eq!(halo(&none), halo(&one_spread_window(none.clone())));
    // Fireflies of 1e4 (one sample among n: standard error = value).
    let mut planted = img.clone();
    let mut color = planted.get(Layer::Color).unwrap().to_vec();
    let mut var = planted.get(Layer::ColorVariance).unwrap().to_vec();
    for x in [70, 200, 333] {
        let i = (x % 32) * 480 + x;
        for c in 0..3 {
            color[c][i] = 1.0e4;
            var[c][i] = 1.0e8;
        }
    }
    planted.set(Layer::Color, color);
    planted.set(Layer::ColorVariance, var);
    let run = |c: &Config, tile: Option<usize>| {
        let c = Config { tile, ..c.clone() };
        let d = Denoiser::new(&ctx, Source::of_image(&planted), c).unwrap();
        d.denoise(&planted, None).unwrap().color
    };
    let tiled = run(&none, Some(60));
    assert_eq!(tiled, run(&one_spread_window(none.clone()), None));
    assert_ne!(tiled, run(&none, None), "no outlier was sent wide");
    check_validation(&ctx);
}
