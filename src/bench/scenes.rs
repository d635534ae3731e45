//! Scene discovery: the scenes of a quality-benchmark folder
//! ([`discover_scenes`]).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// One scene folder: its inputs by spp and its reference.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The folder's name (the `scene` of the case names).
    pub name: String,
    /// `(N, path)` of every `sppN.exr`, by increasing N.
    pub inputs: Vec<(u32, PathBuf)>,
    /// `reference.exr` in the folder (it may be missing: checked when read).
    pub reference: PathBuf,
}

/// The N of a file named `sppN.exr`.
pub(super) fn spp_of_file_name(name: &str) -> Option<u32> {
    let n = name.strip_prefix("spp")?.strip_suffix(".exr")?;
    if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    n.parse().ok()
}

fn spp_files(dir: &Path) -> Result<Vec<(u32, PathBuf)>> {
    let io_err = |source| Error::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut v = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let entry = entry.map_err(io_err)?;
        if let Some(n) = entry.file_name().to_str().and_then(spp_of_file_name) {
            v.push((n, entry.path()));
        }
    }
    v.sort();
    Ok(v)
}

/// The scenes of a benchmark folder: each subfolder holding at least one
/// `sppN.exr`, sorted by name; or, if `dir` itself holds `sppN.exr` files,
/// `dir` as the only scene. Other subfolders and files are ignored.
///
/// # Errors
/// [`Error::Io`] if `dir` cannot be listed; [`Error::InvalidArgument`] if it
/// holds no scene.
pub fn discover_scenes(dir: &Path) -> Result<Vec<Scene>> {
    let scene = |name: String, path: &Path, inputs| Scene {
        name,
        inputs,
        reference: path.join("reference.exr"),
    };
    let own = spp_files(dir)?;
    if !own.is_empty() {
        let name = dir
            .canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "scene".into());
        return Ok(vec![scene(name, dir, own)]);
    }
    let io_err = |source| Error::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut scenes = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let path = entry.map_err(io_err)?.path();
        if !path.is_dir() {
            continue;
        }
        let inputs = spp_files(&path)?;
        if inputs.is_empty() {
            continue;
        }
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        scenes.push(scene(name, &path, inputs));
    }
    scenes.sort_by(|a, b| a.name.cmp(&b.name));
    if scenes.is_empty() {
        return Err(Error::InvalidArgument(format!(
            "{}: no scene found (expected subfolders holding sppN.exr files and a reference.exr)",
            dir.display()
        )));
    }
    Ok(scenes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spp_file_names() {
        assert_eq!(spp_of_file_name("spp16.exr"), Some(16));
        assert_eq!(spp_of_file_name("spp.exr"), None);
        assert_eq!(spp_of_file_name("spp1a.exr"), None);
        assert_eq!(spp_of_file_name("reference.exr"), None);
    }
}
