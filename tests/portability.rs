//! A GPU without 64-bit types (`shaderFloat64`, `shaderInt64`), simulated
//! on any device by a context that leaves them disabled (NO-64BIT): every
//! method runs and gives the same image and sample map as on a context
//! with them (WLR and `auto`, whose f64 steps run in double-float there,
//! within §0.3's tolerance; AOS, whose fits run in f32 there, within the
//! bounds NO-64BIT records). A limit would be an `Error::Limit` of
//! `Denoiser::new`, never part-way through a recording.

mod common;

use mcdenoise::{io, AccumLayout, Config, Denoiser, Method, Source};

fn fixture() -> mcdenoise::StatsImage {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/dof_checker_64_spp16.exr"
    );
    io::read_stats(std::path::Path::new(path)).unwrap()
}

#[test]
fn without_64bit_types_every_method_runs() {
    let small = common::gpu_without_64bit();
    assert!(!small.supports_f64() && !small.supports_int64());
    let full = common::gpu();
    let img = fixture();
    let layout = AccumLayout::new(32, 24, true, false);
    for method in Method::all() {
        let config = Config::new(method);
        let on_stats = Denoiser::new(&small, Source::of_image(&img), config.clone());
        let on_accum = Denoiser::new(&small, Source::Accum(layout), config.clone());
        match (&on_stats, &on_accum) {
            (Ok(d), Ok(a)) => {
                let got = d.denoise(&img, None).unwrap();
                let want = Denoiser::new(&full, Source::of_image(&img), config)
                    .unwrap()
                    .denoise(&img, None)
                    .unwrap();
                if matches!(method, Method::Wlr | Method::Auto | Method::Aos) {
                    // WLR's steps 6-7 in double-float instead of double:
                    // the same image within §0.3's f32 tolerance. AOS's
                    // fits in f32 flip the order of a few pixels, and its
                    // input blend's residual window (BLEND-AOS: 9×9)
                    // carries each one's difference to the 81 pixels
                    // around it: colour within it on 93 %, error on 85 %
                    // (measured 94.6 % and 86.3 % in the worst channels;
                    // 95.9 % and 91.1 % with BLEND-RESIDUAL's 7×7).
                    let (colour, error) = match method {
                        Method::Aos => (0.93, 0.85),
                        _ => (0.999, 0.99),
                    };
                    for c in 0..3 {
                        let what = format!("{method:?} colour {c}");
                        common::assert_close(
                            &what,
                            &got.color.planes[c],
                            &want.color.planes[c],
                            colour,
                        );
                        let what = format!("{method:?} error {c}");
                        common::assert_close(
                            &what,
                            &got.error.planes[c],
                            &want.error.planes[c],
                            error,
                        );
                    }
                } else {
                    // The same image: these kernels never use 64-bit types.
                    assert_eq!(got.color.planes, want.color.planes, "{method:?}");
                    assert_eq!(got.error.planes, want.error.planes, "{method:?}");
                }
                // The sample map needs no shaderInt64: the same map, the
                // exact budget.
                assert!(a.outputs().unwrap().samples.is_some(), "{method:?}");
                let got = d.denoise(&img, Some(1000)).unwrap().samples.unwrap();
                let want = Denoiser::new(&full, Source::of_image(&img), Config::new(method))
                    .unwrap()
                    .denoise(&img, Some(1000))
                    .unwrap()
                    .samples
                    .unwrap();
                if !matches!(method, Method::Wlr | Method::Auto | Method::Aos) {
                    assert_eq!(got, want, "{method:?}");
                }
                assert_eq!(got.iter().map(|&s| s as u64).sum::<u64>(), 1000);
            }
            _ => panic!(
                "{method:?}: stats {:?}, accumulation {:?}",
                on_stats.err(),
                on_accum.err()
            ),
        }
    }
    common::check_validation(&small);
}

/// What such a device cannot run — the `_f64` kernel variants — is an
/// error of `Denoiser::new`, for statistics and accumulation
/// sources alike, never part-way through a recording.
#[test]
fn f64_kernels_without_shader_float64_fail_at_new() {
    let small = common::gpu_without_64bit();
    let img = fixture();
    let layout = AccumLayout::new(32, 24, true, false);
    for method in [Method::Lp, Method::Aos] {
        let mut config = Config::new(method);
        config.precision = mcdenoise::gpu::Precision::F64;
        for source in [Source::of_image(&img), Source::Accum(layout)] {
            let e = Denoiser::new(&small, source, config.clone()).err().unwrap();
            assert!(e.to_string().contains("shaderFloat64"), "{method:?}: {e}");
        }
    }
    common::check_validation(&small);
}
