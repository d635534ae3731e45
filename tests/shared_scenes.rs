//! Tests on the public Mitsuba scenes of `../shared/data/scenes`, which a
//! plain clone does not have. Not part of `cargo test`'s default run
//! (`test = false` in Cargo.toml): CI runs them after the README's suite
//! with `cargo test --test shared_scenes` (`.ci/run`). Every test fails when
//! the folder is absent, rather than pass unchecked.

use std::path::PathBuf;

use mcdenoise::image::{Layer, RgbImage, StatsImage};
use mcdenoise::io::{read_rgb, read_stats, spp_range, validate};
use mcdenoise::metrics::{compare, rmse};

/// `../shared/data/scenes` beside the checkout.
fn scenes_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/scenes");
    assert!(
        dir.is_dir(),
        "{} is absent: these tests need the public scenes beside the checkout (../shared)",
        dir.display()
    );
    dir
}

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// Bitwise equality of two statistics images.
fn assert_bit_identical(a: &StatsImage, b: &StatsImage) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    for ((layer, pa), (_, pb)) in a.layers().zip(b.layers()) {
        for (c, (x, y)) in pa.iter().zip(pb).enumerate() {
            let xb: Vec<u32> = x.iter().map(|v| v.to_bits()).collect();
            let yb: Vec<u32> = y.iter().map(|v| v.to_bits()).collect();
            assert!(xb == yb, "{}.{} differs", layer.name(), layer.channels()[c]);
        }
    }
}

/// The committed 64×64 fixture is the crop of `dof_checker` at (120, 104).
#[test]
fn fixture_is_the_scene_crop() {
    let scenes = scenes_dir();
    let stats = read_stats(&fixture("dof_checker_64_spp16.exr")).unwrap();
    let reference = read_rgb(&fixture("dof_checker_64_ref.exr")).unwrap();
    let full = read_stats(&scenes.join("dof_checker/spp16.exr")).unwrap();
    assert_bit_identical(&full.crop(120, 104, 64, 64), &stats);
    let full_ref = read_rgb(&scenes.join("dof_checker/reference.exr")).unwrap();
    assert_eq!(full_ref.crop(120, 104, 64, 64), reference);
}

#[test]
fn public_scene_files_read() {
    let scenes = scenes_dir();
    for scene in ["dof_checker", "glossy_cornell", "indirect_room"] {
        for spp in [4.0f32, 16.0, 64.0] {
            let path = scenes.join(scene).join(format!("spp{spp}.exr"));
            let img = read_stats(&path).unwrap();
            assert_eq!((img.width, img.height), (256, 256), "{}", path.display());
            let layers: Vec<Layer> = img.layers().map(|(l, _)| l).collect();
            assert_eq!(
                layers,
                Layer::ALL[..11]
                    .iter()
                    .copied()
                    .chain([Layer::Spp])
                    .collect::<Vec<_>>()
            );
            assert_eq!(spp_range(&img), Some((spp, spp)));
            let warnings = validate(&img);
            assert!(warnings.is_empty(), "{}: {warnings:?}", path.display());
        }
        let reference = read_rgb(&scenes.join(scene).join("reference.exr")).unwrap();
        assert_eq!((reference.width, reference.height), (256, 256));
        assert!(reference
            .planes
            .iter()
            .flatten()
            .all(|v| v.is_finite() && *v >= 0.0));
    }
}

/// (scene, spp, rMSE of the input) from `BASELINES.md`.
const BASELINES: [(&str, u32, f64); 9] = [
    ("dof_checker", 4, 0.14581),
    ("dof_checker", 16, 0.03687),
    ("dof_checker", 64, 0.00931),
    ("glossy_cornell", 4, 0.27157),
    ("glossy_cornell", 16, 0.07294),
    ("glossy_cornell", 64, 0.02218),
    ("indirect_room", 4, 0.31371),
    ("indirect_room", 16, 0.07701),
    ("indirect_room", 64, 0.01946),
];

/// The rMSE of the noisy inputs against the references reproduces the
/// "input" column of `BASELINES.md` to the precision the table prints (5
/// decimal places): this pins down both the EXR reader and the metric.
#[test]
fn input_rmse_matches_baselines() {
    let dir = scenes_dir();
    let same_as_printed = |m: f64, t: f64| (m * 1e5).round() == (t * 1e5).round();
    let mut failures = Vec::new();
    for (scene, spp, expected) in BASELINES {
        let stats = read_stats(&dir.join(scene).join(format!("spp{spp}.exr"))).unwrap();
        let reference = read_rgb(&dir.join(scene).join("reference.exr")).unwrap();
        let color = stats.get(Layer::Color).unwrap();
        let x = RgbImage::from_planes(
            stats.width,
            stats.height,
            [color[0].clone(), color[1].clone(), color[2].clone()],
        );
        let m = compare(&x, &reference).unwrap();
        assert_eq!(m.rmse, rmse(&x, &reference));
        if !same_as_printed(m.rmse, expected) {
            failures.push(format!("{scene} spp{spp}: rMSE {} != {expected}", m.rmse));
        }
        assert!(m.psnr.is_finite() && m.ssim > 0.0 && m.ssim < 1.0);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
