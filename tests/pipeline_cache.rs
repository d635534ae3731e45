//! The on-disk pipeline cache (`GpuContext::use_pipeline_cache`): written
//! back with the device's header after pipelines were built, loaded by the
//! next context, ignored when it belongs to another device, and refused
//! (never written over) when the file is not a pipeline cache.

mod common;

use mcdenoise::{Config, Denoiser, Method, Source};

/// Builds LP's pipelines on `ctx` by denoising a tiny image.
fn build_some_pipelines(ctx: &std::sync::Arc<mcdenoise::GpuContext>) {
    let layout = mcdenoise::AccumLayout::new(8, 8, false, false);
    let mut acc = mcdenoise::Accumulator::new(layout);
    for p in 0..64 {
        for s in 0..4 {
            let c = 0.5 + 0.1 * s as f64;
            acc.add(p, &[c, c, c, 0.5, 0.5, 0.5, 0.0, 0.0, 1.0, 1.0]);
        }
    }
    let img = layout.finalize(&acc.planes());
    let d = Denoiser::new(ctx, Source::of_image(&img), Config::new(Method::Lp)).unwrap();
    d.denoise(&img, None).unwrap();
}

#[test]
fn pipeline_cache_round_trips_and_rejects_foreign_data() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("pipeline_cache");
    let _ = std::fs::remove_dir_all(&dir);
    let path = dir.join("nested").join("pipelines.bin");

    // A fresh context: no file yet, an empty cache; saved when dropped.
    let ctx = common::own_gpu();
    assert_eq!(ctx.use_pipeline_cache(&path).unwrap(), 0);
    assert!(
        ctx.use_pipeline_cache(&path).is_err(),
        "a second cache on one context must be refused"
    );
    build_some_pipelines(&ctx);
    common::check_validation(&ctx);
    drop(ctx);
    let saved = std::fs::read(&path).expect("the cache is written when the context drops");
    assert!(saved.len() >= 32, "{} bytes: no Vulkan header", saved.len());
    assert_eq!(
        u32::from_le_bytes(saved[4..8].try_into().unwrap()),
        1,
        "header version"
    );

    // The next context loads it whole.
    let ctx = common::own_gpu();
    assert_eq!(ctx.use_pipeline_cache(&path).unwrap(), saved.len());
    build_some_pipelines(&ctx);
    assert_eq!(
        ctx.save_pipeline_cache().unwrap(),
        std::fs::read(&path).unwrap().len()
    );
    common::check_validation(&ctx);
    drop(ctx);

    // Another device's data (a changed UUID) starts empty.
    let mut foreign = saved.clone();
    foreign[16] ^= 0xff;
    let p = dir.join("foreign.bin");
    std::fs::write(&p, &foreign).unwrap();
    let ctx = common::own_gpu();
    assert_eq!(ctx.use_pipeline_cache(&p).unwrap(), 0);
    build_some_pipelines(&ctx);
    common::check_validation(&ctx);
    drop(ctx);

    // A file that is no pipeline cache (a mistyped path naming someone's
    // data) is refused and never written over.
    let mut not_cache = b"not a cache".to_vec();
    not_cache.resize(64, b'.');
    for (name, bytes) in [("short", b"x".to_vec()), ("text", not_cache)] {
        let p = dir.join(format!("{name}.exr"));
        std::fs::write(&p, &bytes).unwrap();
        let ctx = common::own_gpu();
        let err = ctx.use_pipeline_cache(&p).unwrap_err().to_string();
        assert!(
            err.contains("is not a Vulkan pipeline cache"),
            "{name}: {err}"
        );
        build_some_pipelines(&ctx);
        common::check_validation(&ctx);
        drop(ctx);
        assert_eq!(std::fs::read(&p).unwrap(), bytes, "{name}");
    }

    // A context without a cache saves nothing.
    assert_eq!(common::own_gpu().save_pipeline_cache().unwrap(), 0);
}
