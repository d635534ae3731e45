//! The rMSE of the noisy inputs against the references must reproduce the
//! "input" column of `../shared/data/scenes/BASELINES.md` to the precision the
//! table prints (5 decimal places: 4 significant digits from 0.01 up, 3 below):
//! this pins down both the EXR reader and the metric definition.
//! Fails when the scenes directory is absent (CI puts `../shared` beside the
//! checkout).

mod common;

use mcdenoise::image::{Layer, RgbImage};
use mcdenoise::io::{read_rgb, read_stats};
use mcdenoise::metrics::{compare, rmse};

/// (scene, spp, rMSE of the input) from BASELINES.md.
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

/// Equal as printed in BASELINES.md: both round to the same 5 decimal places.
fn same_as_printed(measured: f64, table: f64) -> bool {
    (measured * 1e5).round() == (table * 1e5).round()
}

#[test]
fn input_rmse_matches_baselines() {
    let dir = common::scenes_dir();
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
        println!(
            "{scene:<15} spp{spp:<3} rMSE {:.6} (BASELINES.md {expected:.5})  relMSE {:.6}  PSNR {:.3} dB  SSIM {:.5}",
            m.rmse, m.relmse, m.psnr, m.ssim
        );
        if !same_as_printed(m.rmse, expected) {
            failures.push(format!("{scene} spp{spp}: rMSE {} != {expected}", m.rmse));
        }
        assert!(m.psnr.is_finite() && m.ssim > 0.0 && m.ssim < 1.0);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
