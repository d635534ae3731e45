//! EXR and PNG in and out.
//!
//! - [`read_stats`] reads a render-statistics EXR (`docs/input-format.md`)
//!   into a [`StatsImage`](crate::image::StatsImage); [`read_rgb`] reads a
//!   reference image (`color.R/G/B` or bare `R/G/B`).
//! - [`write_output`] writes the denoiser's result; [`write_stats`],
//!   [`write_rgb`] and [`write_channels`] write the other EXR shapes (fixtures,
//!   references, crops).
//! - [`write_png_preview`] and [`write_heatmap_png`] write 8-bit previews.
//! - [`inspect()`](fn@inspect), [`validate`] and [`format_report`] summarise
//!   an input file.
//! - [`frames`] lists the frames of a `frame_####.exr` sequence.
//!
//! Reading never panics on file content: every problem with a file is an
//! [`Error::BadInput`] naming the file and, where it applies, the layer,
//! channel or pixel. Every write is atomic ([`write_atomic`]): a reader of the
//! destination sees either the old file or the complete new one, never a
//! partial file, and a failed write leaves no temporary file behind.
//!
//! The EXR and PNG formats need the `io` feature; [`write_atomic`] is always
//! there (the pipeline cache writes through it).

#[cfg(feature = "io")]
mod exr_in;
#[cfg(feature = "io")]
mod exr_out;
#[cfg(feature = "io")]
pub mod frames;
#[cfg(feature = "io")]
pub mod inspect;
#[cfg(feature = "io")]
mod png_out;

use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};
use crate::fault::{self, Call};

#[cfg(feature = "io")]
pub use exr_in::{read_rgb, read_stats, read_stats_layers, MAX_DIMENSION, MAX_PIXELS};
#[cfg(feature = "io")]
pub use exr_out::{
    write_channels, write_output, write_rgb, write_samples, write_stats, OutputImage,
};
#[cfg(feature = "io")]
pub use inspect::{format_report, inspect, spp_range, validate, ChannelStats, LayerReport};
#[cfg(feature = "io")]
pub use png_out::{
    heat_color, srgb_preview_u8, write_heatmap_png, write_panels, write_png_preview, Panel,
};

/// Distinguishes the temporary files of concurrent writes from one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// The temporary file a write to `path` goes through: `.<name>.tmp-<pid>-<n>`
/// in the destination's directory (same file system, so the final rename is
/// atomic).
fn temp_path(path: &Path) -> Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
    })?;
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp_name = format!(
        ".{}.tmp-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        n
    );
    Ok(match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.join(tmp_name),
        _ => PathBuf::from(tmp_name),
    })
}

/// The writer [`write_atomic`] hands out: a buffered temporary file (or
/// the device or FIFO that `write_atomic` writes in place).
/// (Writes go through the test-only fault hook, which can make them fail
/// like a full disk.)
pub struct TempFile {
    inner: BufWriter<File>,
}

impl Write for TempFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if let Some((allowed, error)) = fault::write_budget(buf.len()) {
            self.inner.write_all(&buf[..allowed])?;
            return Err(error);
        }
        self.inner.write_all(buf)?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for TempFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// The file `path` names once its symbolic links are followed (a relative
/// link from the link's folder), or `path` itself when it is none; at most
/// 40 links deep, as the kernel allows.
fn link_target(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match fs::read_link(&p) {
            Ok(to) => {
                p = match p.parent() {
                    Some(dir) if to.is_relative() => dir.join(to),
                    _ => to,
                }
            }
            Err(_) => break,
        }
    }
    p
}

/// Writes `path` atomically.
///
/// `write` receives a buffered writer on a fresh temporary file next to `path`
/// (`.<name>.tmp-<pid>-<n>`); when it returns `Ok`, the data is flushed,
/// synced to disk and the temporary file is renamed over `path`. If anything
/// fails (including `write` itself), the temporary file is removed and `path`
/// is left untouched. OS errors are reported as [`Error::Io`] naming `path`
/// (a full disk: "No space left on device").
///
/// A directory that does not exist is not created: that is an error.
/// Where `path` is a symbolic link, the file it points to is written (the
/// link stays a link), as a plain write through the link would. Where it
/// is neither a regular file nor a directory (a device such as
/// `/dev/null`, a FIFO), there is no file to replace: it is opened and
/// written in place, and stays what it is.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut TempFile) -> Result<()>) -> Result<()> {
    let target = link_target(path);
    let path = target.as_path();
    let io_err = |source: std::io::Error| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    // A device or FIFO has no file to replace: it is written in place.
    let in_place = fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
    let tmp = if in_place {
        None
    } else {
        Some(temp_path(path)?)
    };
    let file = fault::os(Call::FileCreate)
        .and_then(|()| match &tmp {
            Some(tmp) => OpenOptions::new().write(true).create_new(true).open(tmp),
            None => OpenOptions::new().write(true).open(path),
        })
        .map_err(io_err)?;
    let result = (|| {
        let mut writer = TempFile {
            inner: BufWriter::new(file),
        };
        write(&mut writer)?;
        writer.flush().map_err(io_err)?;
        let Some(tmp) = &tmp else {
            return Ok(());
        };
        let file = writer
            .inner
            .into_inner()
            .map_err(|e| io_err(e.into_error()))?;
        file.sync_all().map_err(io_err)?;
        drop(file);
        fault::os(Call::FileRename)
            .and_then(|()| fs::rename(tmp, path))
            .map_err(io_err)
    })();
    if let (Err(_), Some(tmp)) = (&result, &tmp) {
        // Best effort: the temporary file may already be gone.
        let _ = fs::remove_file(tmp);
    }
    result
}

/// An encoder failure while writing `path`, as an [`Error::Io`].
#[cfg(feature = "io")]
fn write_error(path: &Path, what: &str, detail: impl std::fmt::Display) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(format!("{what}: {detail}")),
    }
}
