//! Converged references of scenes: a K-spp uniform render with its own
//! random numbers, cached on disk by the scene's content, the renderer's
//! compiled kernels, the size, K and the seed, so that a changed scene or
//! renderer never reuses a stale image.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use super::{Renderer, Samples, Scene};
use crate::error::{Error, Result};
use crate::{colour_of, io, Batch, GpuContext, RgbImage};

/// Samples per pixel of one submission of a reference render (a pass of
/// a few hundred milliseconds at 256², far from any watchdog).
const PASS_SPP: u32 = 16;

/// The seed a reference of a render with `seed` uses by default: its own
/// random numbers, independent of the render's.
pub fn reference_seed(seed: u64) -> u64 {
    seed ^ 0x5eed_5eed_5eed_5eed
}

/// Where rendered references are cached: `MCDENOISE_CACHE`, else
/// `$XDG_CACHE_HOME/mcdenoise`, else `~/.cache/mcdenoise`, else
/// `target/mcdenoise-cache`.
pub fn cache_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("MCDENOISE_CACHE") {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME") {
        return PathBuf::from(d).join("mcdenoise");
    }
    if let Some(h) = std::env::var_os("HOME") {
        return PathBuf::from(h).join(".cache/mcdenoise");
    }
    PathBuf::from("target/mcdenoise-cache")
}

/// FNV-1a, 64 bits: a stable content key for the cache (not a security
/// hash; the file name also holds the size, K and the seed in clear).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h = 0xcbf29ce484222325u64;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100000001b3);
    }
    h
}

/// The renderer's kernels a reference runs (`render_scene.glsl` is part of
/// `render_trace`): their SPIR-V, which holds no comments, is part of every
/// cache key, so that a changed comment or layout in their sources does not
/// render every reference again.
const RENDERER: [&crate::gpu::KernelDecl; 3] = [&super::TRACE, &super::SCAN, &super::RESOLVE];

/// What a scene renders: its description and its primitives.
fn scene_bytes(scene: &Scene) -> Result<Vec<u8>> {
    Ok(format!("{scene:?}{:?}", scene.primitives()?).into_bytes())
}

/// The content part of a cache key: [`scene_bytes`] and the SPIR-V of
/// [`RENDERER`].
fn content_key(scene: &Scene) -> Result<u64> {
    let mut content = scene_bytes(scene)?;
    for kernel in RENDERER {
        let words = crate::gpu::reflect::spirv(kernel.name, crate::gpu::Precision::F32)
            .ok_or_else(|| Error::Kernel {
                kernel: kernel.name.to_owned(),
                message: "not compiled into the library".into(),
            })?;
        content.extend_from_slice(bytemuck::cast_slice(words));
    }
    Ok(fnv1a(&content))
}

/// The cache file of the `k`-spp reference of `scene` at `size` rendered
/// with `seed`.
pub fn cache_path(scene: &Scene, size: (usize, usize), k: u32, seed: u64) -> Result<PathBuf> {
    Ok(cache_dir().join(format!(
        "ref-{:016x}-{}x{}-k{k}-s{seed}.exr",
        content_key(scene)?,
        size.0,
        size.1
    )))
}

/// A reference image and where it is cached.
#[derive(Debug)]
pub struct Reference {
    /// The colour of the `k`-spp render.
    pub image: RgbImage,
    /// Its cache file.
    pub path: PathBuf,
    /// Whether it came from the cache.
    pub cached: bool,
}

/// The `k`-spp uniform render of `scene` at `size` with `seed`, from the
/// cache when it is there, else rendered in passes of 16 spp and cached (a
/// failure to write the cache is logged, not an error). `stop` is checked
/// between passes ([`Error::Interrupted`]); `progress` gets the passes done
/// and their total.
pub fn reference(
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    size: (usize, usize),
    k: u32,
    seed: u64,
    stop: &AtomicBool,
    mut progress: impl FnMut(u32, u32),
) -> Result<Reference> {
    if k == 0 {
        return Err(Error::InvalidArgument(
            "a reference needs at least 1 spp".into(),
        ));
    }
    let path = cache_path(scene, size, k, seed)?;
    if let Ok(image) = io::read_rgb(&path) {
        if (image.width, image.height) == size {
            return Ok(Reference {
                image,
                path,
                cached: true,
            });
        }
    }
    let renderer = Renderer::new(ctx, scene, size.0, size.1, seed)?;
    let passes = k.div_ceil(PASS_SPP);
    for p in 0..passes {
        if stop.load(Ordering::SeqCst) {
            return Err(Error::Interrupted);
        }
        let spp = PASS_SPP.min(k - p * PASS_SPP);
        let mut batch = Batch::new(ctx)?;
        renderer.record_pass(&mut batch, Samples::Uniform(spp))?;
        batch.finish()?;
        progress(p + 1, passes);
    }
    let image = colour_of(&renderer.statistics()?);
    if let Err(e) = std::fs::create_dir_all(cache_dir())
        .map_err(|e| e.to_string())
        .and_then(|_| io::write_rgb(&path, &image).map_err(|e| e.to_string()))
    {
        log::warn!("could not cache the reference {}: {e}", path.display());
    }
    Ok(Reference {
        image,
        path,
        cached: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cache_key_follows_the_scene_and_the_renderers_kernels() {
        let key = |s: &Scene| {
            let p = cache_path(s, (64, 64), 256, 7).unwrap();
            p.file_name().unwrap().to_string_lossy().into_owned()
        };
        let cornell = Scene::builtin("cornell").unwrap();
        let a = key(&cornell);
        assert_eq!(a, key(&Scene::builtin("cornell").unwrap()));
        assert!(a.ends_with("-64x64-k256-s7.exr"), "{a}");
        assert_ne!(a, key(&Scene::builtin("glossy").unwrap()));
        // The SPIR-V of the three kernels is in the key, not the scene alone.
        assert!(a.starts_with(&format!("ref-{:016x}-", content_key(&cornell).unwrap())));
        assert_ne!(
            content_key(&cornell).unwrap(),
            fnv1a(&scene_bytes(&cornell).unwrap())
        );
        for kernel in RENDERER {
            let words =
                crate::gpu::reflect::spirv(kernel.name, crate::gpu::Precision::F32).unwrap();
            assert!(words.len() > 100, "{}", kernel.name);
        }
    }
}
