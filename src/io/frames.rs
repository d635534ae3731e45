//! Frame sequences for batch denoising: `dir/frame_####.exr` patterns.
//!
//! A pattern's file name holds exactly one run of `#`, the frame number
//! zero-padded to the run's length (`####`: 0007, 0123, 12345), as render
//! farm managers and compositors write sequences. [`FramePattern::list`]
//! finds the existing frames in the pattern's folder in frame order;
//! [`FramePattern::path`] gives the path of a frame number, so an output
//! pattern names each input frame's output.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// A parsed `dir/prefix####suffix` pattern.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FramePattern {
    dir: PathBuf,
    prefix: String,
    suffix: String,
    digits: usize,
}

/// One frame of a sequence: its number and path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The frame number.
    pub number: u64,
    /// The file.
    pub path: PathBuf,
}

impl FramePattern {
    /// Parses `pattern`. Errors unless its file name (not the folders) holds
    /// exactly one run of `#` of length 1 to 18.
    pub fn parse(pattern: &Path) -> Result<FramePattern> {
        let bad = |why: &str| {
            Error::InvalidArgument(format!(
                "{}: a frame pattern needs {why} (for example frame_####.exr)",
                pattern.display()
            ))
        };
        let name = pattern
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| bad("a file name in UTF-8"))?;
        let start = name
            .find('#')
            .ok_or_else(|| bad("a run of # in its file name"))?;
        let digits = name[start..].chars().take_while(|&c| c == '#').count();
        let suffix = &name[start + digits..];
        if suffix.contains('#') {
            return Err(bad("exactly one run of # in its file name"));
        }
        if digits > 18 {
            return Err(bad("at most 18 #"));
        }
        let dir = match pattern.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        Ok(FramePattern {
            dir,
            prefix: name[..start].to_string(),
            suffix: suffix.to_string(),
            digits,
        })
    }

    /// The folder the frames are in.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The path of frame `number`: zero-padded to the run's length, wider
    /// when the number needs more digits.
    pub fn path(&self, number: u64) -> PathBuf {
        self.dir.join(format!(
            "{}{:0width$}{}",
            self.prefix,
            number,
            self.suffix,
            width = self.digits
        ))
    }

    /// The frame number a file name stands for, if it matches: the prefix,
    /// at least as many ASCII digits as the run (more only without a leading
    /// zero, as [`FramePattern::path`] writes them), the suffix.
    pub fn number_of(&self, name: &str) -> Option<u64> {
        let mid = name
            .strip_prefix(&self.prefix)?
            .strip_suffix(&self.suffix)?;
        let ok = mid.len() == self.digits || (mid.len() > self.digits && !mid.starts_with('0'));
        if !ok || !mid.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        mid.parse().ok()
    }

    /// The existing frames, in frame order. An error if the folder cannot be
    /// read or holds no frame.
    pub fn list(&self) -> Result<Vec<Frame>> {
        let entries = std::fs::read_dir(&self.dir).map_err(|e| {
            Error::InvalidArgument(format!("{}: cannot list frames: {e}", self.dir.display()))
        })?;
        let mut frames: Vec<Frame> = entries
            .filter_map(|e| e.ok())
            .filter(|e| e.file_type().map(|t| !t.is_dir()).unwrap_or(false))
            .filter_map(|e| {
                let name = e.file_name();
                let number = self.number_of(name.to_str()?)?;
                Some(Frame {
                    number,
                    path: e.path(),
                })
            })
            .collect();
        frames.sort_by_key(|f| f.number);
        if frames.is_empty() {
            return Err(Error::InvalidArgument(format!(
                "{}: no file matches {}{}{}",
                self.dir.display(),
                self.prefix,
                "#".repeat(self.digits),
                self.suffix
            )));
        }
        Ok(frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_path_and_match() {
        let p = FramePattern::parse(Path::new("renders/shot_####.exr")).unwrap();
        assert_eq!(p.path(7), Path::new("renders/shot_0007.exr"));
        assert_eq!(p.path(12345), Path::new("renders/shot_12345.exr"));
        assert_eq!(p.number_of("shot_0007.exr"), Some(7));
        assert_eq!(p.number_of("shot_12345.exr"), Some(12345));
        assert_eq!(p.number_of("shot_007.exr"), None);
        assert_eq!(p.number_of("shot_00007.exr"), None);
        assert_eq!(p.number_of("shot_00a7.exr"), None);
        assert_eq!(p.number_of("shot_0007.exr.tmp"), None);
        let bare = FramePattern::parse(Path::new("f#.exr")).unwrap();
        assert_eq!(bare.dir(), Path::new("."));
        assert_eq!(bare.path(3), Path::new("./f3.exr"));
        for bad in ["shot.exr", "a##b##.exr", "x/####/y.exr"] {
            assert!(FramePattern::parse(Path::new(bad)).is_err(), "{bad}");
        }
    }

    #[test]
    fn lists_in_frame_order() {
        let dir = std::env::temp_dir().join(format!("mcdenoise-frames-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("f_0005.exr.d")).unwrap();
        for n in [
            "f_0010.exr",
            "f_0002.exr",
            "f_10000.exr",
            "g_0001.exr",
            "f_01.exr",
        ] {
            std::fs::write(dir.join(n), b"x").unwrap();
        }
        let p = FramePattern::parse(&dir.join("f_####.exr")).unwrap();
        let numbers: Vec<u64> = p.list().unwrap().iter().map(|f| f.number).collect();
        assert_eq!(numbers, vec![2, 10, 10000]);
        let none = FramePattern::parse(&dir.join("h_####.exr")).unwrap();
        assert!(none.list().is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
