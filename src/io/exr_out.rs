//! Writing EXR files: the denoiser's output, statistics (fixtures, crops) and
//! plain colour images. Always single-part, scanline, 32-bit float, ZIP
//! (16-line blocks) compression, data window at (0, 0), written atomically.

use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, Blocks, Compression, Encoding, FlatSamples, Image, LayerAttributes,
    LineOrder, SmallVec, Text, Vec2, WritableImage,
};

use crate::error::{Error, Result};
use crate::image::{RgbImage, StatsImage};

use super::{write_atomic, write_error};

/// What the denoiser writes (see [`write_output`]). All planes are
/// `color.width * color.height` values, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputImage {
    /// The denoised colour, linear radiance: channels `color.R/G/B`.
    pub color: RgbImage,
    /// The estimated remaining error per pixel and channel, if computed:
    /// channels `error.R/G/B`.
    pub error: Option<RgbImage>,
    /// Samples per pixel requested by adaptive sampling, if computed: channel
    /// `samples.Y`.
    pub samples: Option<Vec<f32>>,
    /// Extra planes for debugging, written as `debug.<name>`. Names must be
    /// unique, non-empty, Latin-1 and free of NUL.
    pub debug: Vec<(String, Vec<f32>)>,
}

/// Writes `img` as a single-part f32 EXR with ZIP compression: `color.R/G/B`,
/// then `error.R/G/B`, `samples.Y` and `debug.<name>` for what is present.
/// Atomic (see [`write_atomic`]).
///
/// # Errors
/// [`Error::InvalidArgument`] if a plane's size differs from the colour's, a
/// debug name is invalid or repeated, or the image is empty; [`Error::Io`]
/// naming `path` if writing fails.
pub fn write_output(path: &Path, img: &OutputImage) -> Result<()> {
    let (w, h) = (img.color.width, img.color.height);
    let n = w * h;
    let mut channels: Vec<(String, &[f32])> = Vec::new();
    push_rgb(&mut channels, "color", &img.color);
    if let Some(error) = &img.error {
        if (error.width, error.height) != (w, h) {
            return Err(Error::InvalidArgument(format!(
                "{}: the error image is {}x{} but the colour is {w}x{h}",
                path.display(),
                error.width,
                error.height
            )));
        }
        push_rgb(&mut channels, "error", error);
    }
    if let Some(samples) = &img.samples {
        channels.push(("samples.Y".into(), samples));
    }
    for (name, plane) in &img.debug {
        if name.is_empty() || name.contains('\0') {
            return Err(Error::InvalidArgument(format!(
                "{}: invalid debug plane name {name:?}",
                path.display()
            )));
        }
        let full = format!("debug.{name}");
        if channels.iter().any(|(n, _)| *n == full) {
            return Err(Error::InvalidArgument(format!(
                "{}: debug plane {name:?} is given twice",
                path.display()
            )));
        }
        channels.push((full, plane));
    }
    for (name, plane) in &channels {
        if plane.len() != n {
            return Err(Error::InvalidArgument(format!(
                "{}: plane {name} has {} values, expected {w}x{h} = {n}",
                path.display(),
                plane.len()
            )));
        }
    }
    let refs: Vec<(&str, &[f32])> = channels.iter().map(|(n, p)| (n.as_str(), *p)).collect();
    write_channels(path, w, h, &refs)
}

/// Writes every present layer of `img` with its channel names
/// (`color.R`, ..., `position_covariance.ZZ`, `spp.Y`), f32, ZIP. Reading the
/// file back with [`read_stats`](super::read_stats) gives `img` exactly
/// (bit-identical values, NaN payloads aside). Atomic.
///
/// # Errors
/// [`Error::InvalidArgument`] for an empty image, [`Error::Io`] if writing fails.
pub fn write_stats(path: &Path, img: &StatsImage) -> Result<()> {
    let names: Vec<(String, &[f32])> = img
        .layers()
        .flat_map(|(layer, planes)| {
            layer
                .channels()
                .iter()
                .zip(planes)
                .map(move |(c, p)| (format!("{}.{c}", layer.name()), p.as_slice()))
        })
        .collect();
    let refs: Vec<(&str, &[f32])> = names.iter().map(|(n, p)| (n.as_str(), *p)).collect();
    write_channels(path, img.width, img.height, &refs)
}

/// Writes a colour image as `color.R/G/B` (f32, ZIP). Atomic.
///
/// # Errors
/// As [`write_stats`].
pub fn write_rgb(path: &Path, img: &RgbImage) -> Result<()> {
    let mut channels = Vec::new();
    push_rgb(&mut channels, "color", img);
    let refs: Vec<(&str, &[f32])> = channels.iter().map(|(n, p)| (n.as_str(), *p)).collect();
    write_channels(path, img.width, img.height, &refs)
}

/// Writes arbitrary named f32 planes (`width * height` values each, row-major)
/// as one single-part scanline EXR with ZIP compression, data window at (0, 0).
/// The channels are stored in the alphabetical order EXR requires. Atomic.
///
/// # Errors
/// [`Error::InvalidArgument`] if the image is empty, a plane has the wrong
/// length, a name is empty, repeated or not Latin-1; [`Error::Io`] naming
/// `path` if writing fails.
pub fn write_channels(
    path: &Path,
    width: usize,
    height: usize,
    channels: &[(&str, &[f32])],
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidArgument(format!(
            "{}: cannot write an empty ({width}x{height}) image",
            path.display()
        )));
    }
    let n = width * height;
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (i, (name, plane)) in channels.iter().enumerate() {
        if plane.len() != n {
            return Err(Error::InvalidArgument(format!(
                "{}: channel {name} has {} values, expected {width}x{height} = {n}",
                path.display(),
                plane.len()
            )));
        }
        if channels[..i].iter().any(|(other, _)| other == name) {
            return Err(Error::InvalidArgument(format!(
                "{}: channel {name} is given twice",
                path.display()
            )));
        }
        let text = Text::new_or_none(name)
            .filter(|_| !name.is_empty() && !name.contains('\0') && name.len() < 256)
            .ok_or_else(|| {
                Error::InvalidArgument(format!(
                    "{}: {name:?} is not a valid EXR channel name",
                    path.display()
                ))
            })?;
        list.push(AnyChannel::new(text, FlatSamples::F32(plane.to_vec())));
    }
    write_list(path, width, height, list)
}

/// Writes a sample map (§9.2) as one `samples.Y` channel of 32-bit unsigned
/// integers (exact for any count), `width * height` values, row-major. Atomic.
///
/// # Errors
/// As [`write_channels`].
pub fn write_samples(path: &Path, width: usize, height: usize, counts: &[u32]) -> Result<()> {
    if width == 0 || height == 0 || counts.len() != width * height {
        return Err(Error::InvalidArgument(format!(
            "{}: a sample map of {} values is not {width}x{height}",
            path.display(),
            counts.len()
        )));
    }
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    list.push(AnyChannel::new(
        Text::from("samples.Y"),
        FlatSamples::U32(counts.to_vec()),
    ));
    write_list(path, width, height, list)
}

fn write_list(
    path: &Path,
    width: usize,
    height: usize,
    list: SmallVec<[AnyChannel<FlatSamples>; 4]>,
) -> Result<()> {
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = exr::image::Layer::new(
        Vec2(width, height),
        LayerAttributes::default(),
        encoding,
        AnyChannels::sort(list),
    );
    let image = Image::from_layer(layer);
    write_atomic(path, |writer| {
        image.write().to_buffered(writer).map_err(|e| match e {
            // The OS's error as it is (a full disk, an I/O error).
            exr::error::Error::Io(source) => Error::Io {
                path: path.to_path_buf(),
                source,
            },
            e => write_error(path, "EXR encoding failed", e),
        })
    })
}

fn push_rgb<'a>(channels: &mut Vec<(String, &'a [f32])>, layer: &str, img: &'a RgbImage) {
    for (c, plane) in ["R", "G", "B"].iter().zip(&img.planes) {
        channels.push((format!("{layer}.{c}"), plane.as_slice()));
    }
}
