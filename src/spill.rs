//! Frames of planes kept in an unnamed temporary file rather than in host
//! memory, for offline sequences whose frames all come out at the end (the
//! two-way temporal filter's [`crate::Smoother`], a renderer's statistics
//! waiting for it): the host's memory then does not grow with the
//! sequence's length.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};

use crate::error::{Error, Result};

/// Frames, each some planes of `f32`, appended in order to an unnamed file
/// in [`std::env::temp_dir`] (`TMPDIR` on Unix) that the OS removes when it
/// is closed, and read back in any order.
pub struct PlaneSpill {
    file: File,
    /// Each frame's byte offset and its planes' lengths.
    frames: Vec<(u64, Vec<usize>)>,
    /// Bytes written.
    end: u64,
    /// What keeps frames here, for errors.
    what: &'static str,
}

impl std::fmt::Debug for PlaneSpill {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlaneSpill")
            .field("what", &self.what)
            .field("frames", &self.frames.len())
            .field("bytes", &self.end)
            .finish()
    }
}

impl PlaneSpill {
    /// An empty spill; `what` names its user in errors ("the two-way
    /// filter's kept frames"). An [`Error::Io`] naming the temporary
    /// directory if it cannot hold a file.
    pub fn new(what: &'static str) -> Result<PlaneSpill> {
        let file = tempfile::tempfile().map_err(|e| Self::error(what, "create", e))?;
        Ok(PlaneSpill {
            file,
            frames: Vec::new(),
            end: 0,
            what,
        })
    }

    fn error(what: &str, doing: &str, source: std::io::Error) -> Error {
        Error::Io {
            path: std::env::temp_dir(),
            source: std::io::Error::new(
                source.kind(),
                format!(
                    "could not {doing} the temporary file of {what} here (TMPDIR chooses the directory): {source}"
                ),
            ),
        }
    }

    /// Appends a frame; returns its index.
    pub fn push<'a>(&mut self, planes: impl IntoIterator<Item = &'a [f32]>) -> Result<usize> {
        let at = self.end;
        let mut lens = Vec::new();
        let write = |file: &mut File| -> std::io::Result<u64> {
            file.seek(SeekFrom::Start(at))?;
            let mut w = BufWriter::new(file);
            let mut bytes = 0u64;
            for p in planes {
                w.write_all(bytemuck::cast_slice(p))?;
                lens.push(p.len());
                bytes += 4 * p.len() as u64;
            }
            w.flush()?;
            Ok(bytes)
        };
        let bytes = write(&mut self.file).map_err(|e| Self::error(self.what, "write", e))?;
        self.end += bytes;
        self.frames.push((at, lens));
        Ok(self.frames.len() - 1)
    }

    /// Frame `k`'s planes. Panics if there is no frame `k`.
    pub fn read(&mut self, k: usize) -> Result<Vec<Vec<f32>>> {
        let (at, lens) = &self.frames[k];
        let mut planes: Vec<Vec<f32>> = lens.iter().map(|&n| vec![0f32; n]).collect();
        let mut read = |file: &mut File| -> std::io::Result<()> {
            file.seek(SeekFrom::Start(*at))?;
            let mut r = BufReader::new(file);
            for p in &mut planes {
                r.read_exact(bytemuck::cast_slice_mut(p))?;
            }
            Ok(())
        };
        read(&mut self.file).map_err(|e| Self::error(self.what, "read", e))?;
        Ok(planes)
    }

    /// Frames kept.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether no frame is kept.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Drops every frame; the file shrinks to nothing.
    pub fn clear(&mut self) -> Result<()> {
        self.frames.clear();
        self.end = 0;
        self.file
            .set_len(0)
            .map_err(|e| Self::error(self.what, "truncate", e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_of_any_planes_read_back_in_any_order() {
        let mut s = PlaneSpill::new("a test's frames").unwrap();
        let frames: Vec<Vec<Vec<f32>>> = (0..4)
            .map(|k| {
                (0..k + 1)
                    .map(|p| (0..5 + p).map(|i| (k * 100 + p * 10 + i) as f32).collect())
                    .collect()
            })
            .collect();
        for f in &frames {
            s.push(f.iter().map(|p| p.as_slice())).unwrap();
        }
        assert_eq!(s.len(), 4);
        for k in (0..4).rev() {
            assert_eq!(s.read(k).unwrap(), frames[k], "frame {k}");
        }
        s.clear().unwrap();
        assert!(s.is_empty());
        assert_eq!(s.push([frames[1][1].as_slice()]).unwrap(), 0);
        assert_eq!(s.read(0).unwrap(), vec![frames[1][1].clone()]);
    }
}
