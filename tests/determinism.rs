//! Issue #14's determinism and edge sizes, through the public facade: the
//! same input, device and options give bit-identical colour, error and
//! sample map run after run (a new denoiser and a reused one), for every
//! method with its defaults (the outlier stage included); and every method
//! with a sample map runs on 1×1, 1×N, N×1 and prime sizes smaller than its
//! windows, with finite output and the exact budget.

mod common;

use common::{check_validation, gpu};
use mcdenoise::{Config, Denoiser, Method, Source, StatsImage};

fn fixture() -> StatsImage {
    mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap()
}

/// The methods and whether they run on the GPU in this build.
const METHODS: &[(Method, bool)] = &[
    (Method::Wlr, true),
    (Method::Lp, true),
    (Method::None, true),
    (Method::Apr, true),
];

fn make(img: &StatsImage, method: Method, on_gpu: bool) -> Denoiser {
    let src = Source::of_image(img);
    if on_gpu {
        Denoiser::new(&gpu(), src, Config::new(method)).unwrap()
    } else {
        Denoiser::new_cpu(src, Config::new(method)).unwrap()
    }
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn every_method_is_bit_identical_run_after_run() {
    let img = fixture();
    for &(method, on_gpu) in METHODS {
        let a = make(&img, method, on_gpu);
        let first = a.denoise(&img, Some(10_000)).unwrap();
        let again = a.denoise(&img, Some(10_000)).unwrap();
        let fresh = make(&img, method, on_gpu)
            .denoise(&img, Some(10_000))
            .unwrap();
        for other in [&again, &fresh] {
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
    }
    check_validation(&gpu());
}

#[test]
fn every_method_runs_on_edge_sizes() {
    let img = fixture();
    for &(w, h) in &[(1, 1), (1, 17), (23, 1), (2, 2), (13, 7), (37, 23)] {
        let crop = img.crop(5, 9, w, h);
        for &(method, on_gpu) in METHODS {
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
