//! Reading render-statistics and reference EXR files.
//!
//! The file is read into memory and decoded with the `exr` crate's block
//! reader, so only the one part and the channels we need are converted, each
//! straight into its f32 plane. The decoder runs on the calling thread inside
//! `catch_unwind`: a malformed file that trips a panic in the decoder becomes
//! an [`Error::BadInput`] like any other corrupt file (this relies on the
//! default `panic = "unwind"`). The blocks are decompressed on scoped threads
//! of our own ([`decompress_blocks`]), each under `catch_unwind` too; the
//! `exr` crate's parallel decoder is not used because a panic on its worker
//! threads would abort the process.

use std::collections::HashSet;
use std::io::Cursor;
use std::panic::{self, AssertUnwindSafe};
use std::path::Path;
use std::sync::{mpsc, Arc, Mutex};

use exr::block::reader::ChunksReader;
use exr::block::UncompressedBlock;
use exr::compression::Compression;
use exr::math::Vec2;
use exr::meta::attribute::SampleType;
use exr::meta::header::Header;
use exr::prelude::f16;

use crate::error::{Error, Result};
use crate::image::{Layer, Requirement, RgbImage, StatsImage};

/// Largest accepted width or height (pixels). Larger data windows are rejected
/// before any pixel memory is allocated, so a corrupt header cannot ask for
/// terabytes.
pub const MAX_DIMENSION: usize = 1 << 16;

/// Largest accepted pixel count (`width * height`, 16384 x 16384).
pub const MAX_PIXELS: usize = 1 << 28;

/// Largest accepted number of pixel blocks (chunks) in the part that is read.
const MAX_CHUNKS: usize = 1 << 22;

/// The four bytes every OpenEXR file starts with.
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// The remedy appended to every unsupported-compression message.
const RESAVE_HINT: &str = "re-save with ZIP, PIZ, RLE or no compression";

/// Reads a render-statistics EXR (`docs/input-format.md`).
///
/// - Part: in a multi-part file, the first part with a `color.R` channel;
///   otherwise the only (or first) part.
/// - Channels `layer.channel` of every [`Layer`] are read and converted to f32
///   (half and uint channels too). Unknown channels are ignored.
/// - The data window is the image: its size is the result's size, wherever it
///   starts; the display window is ignored.
/// - Scanline or tiled (largest resolution level), any compression the `exr`
///   crate decodes.
/// - Values are returned as stored: NaN, Inf and negative variances are kept
///   (sanitation is the caller's business, see [`crate::io::inspect::validate`]).
///
/// # Errors
/// [`Error::Io`] if the file cannot be read; [`Error::BadInput`] naming the
/// file and the problem if it is empty, not an EXR, truncated or corrupt,
/// uses an unsupported compression (HTJ2K, ZSTD) or subsampled channels, has
/// an empty or oversized ([`MAX_DIMENSION`], [`MAX_PIXELS`]) data window, lacks
/// a [`Requirement::Required`] layer, holds only some channels of a layer, or
/// (multi-part) has statistics channels in a part other than the one with
/// `color.R`. Missing variance layers are not an error: they are absent from
/// the result.
pub fn read_stats(path: &Path) -> Result<StatsImage> {
    let bytes = read_file(path)?;
    let part = decode_part(
        path,
        &bytes,
        &|headers| find_part(headers, &["color.R"]),
        &|name| stats_channel(name).is_some(),
        true,
    )?;
    assemble_stats(path, part)
}

/// The size and the complete layers of a render-statistics EXR, from its
/// headers alone (the part [`read_stats`] would read): what a caller needs
/// to prepare for the file (for example [`crate::Denoiser::warm_up`]) while
/// its pixels are still being read. Checks nothing else: [`read_stats`]
/// decides whether the file is usable.
///
/// # Errors
/// [`Error::Io`] if the file cannot be opened; [`Error::BadInput`] if its
/// headers cannot be parsed.
pub fn read_stats_layers(path: &Path) -> Result<(usize, usize, Vec<Layer>)> {
    let file = std::fs::File::open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let meta = panic::catch_unwind(AssertUnwindSafe(|| {
        exr::meta::MetaData::read_from_buffered(std::io::BufReader::new(file), false)
    }))
    .map_err(|_| Error::bad_input(path, "unreadable headers"))?
    .map_err(|e| Error::bad_input(path, format!("unreadable headers: {e}")))?;
    let headers = &meta.headers[..];
    let header = headers
        .get(find_part(headers, &["color.R"]))
        .ok_or_else(|| Error::bad_input(path, "no part"))?;
    // The complete layers, as assemble_stats keeps them.
    let present: HashSet<String> = part_channel_names(header).into_iter().collect();
    let layers = Layer::ALL
        .into_iter()
        .filter(|l| l.channel_names().iter().all(|n| present.contains(n)))
        .collect();
    Ok((
        header.layer_size.width(),
        header.layer_size.height(),
        layers,
    ))
}

/// Reads a reference (or any colour) image: channels `color.R/G/B`, or bare
/// `R/G/B` when there is no `color` layer. In a multi-part file the first part
/// with `color.R`, else the first with `R`, is used. Everything else about the
/// file is accepted and rejected as in [`read_stats`].
///
/// # Errors
/// As [`read_stats`]; a file with neither colour layer, or with only some of
/// its three channels, is an [`Error::BadInput`] naming the missing channels.
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    let bytes = read_file(path)?;
    let mut part = decode_part(
        path,
        &bytes,
        &|headers| find_part(headers, &["color.R", "R"]),
        &|name| matches!(name, "color.R" | "color.G" | "color.B" | "R" | "G" | "B"),
        false,
    )?;
    for prefix in ["color.", ""] {
        let names = ["R", "G", "B"].map(|c| format!("{prefix}{c}"));
        let found = names.clone().map(|n| part.take(&n));
        match found {
            [Some(r), Some(g), Some(b)] => {
                return Ok(RgbImage::from_planes(part.width, part.height, [r, g, b]))
            }
            [None, None, None] => continue,
            found => {
                let missing: Vec<&str> = names
                    .iter()
                    .zip(&found)
                    .filter(|(_, f)| f.is_none())
                    .map(|(n, _)| n.as_str())
                    .collect();
                return Err(Error::bad_input(
                    path,
                    format!(
                        "colour is incomplete: channel(s) {} missing{}",
                        missing.join(", "),
                        part.context()
                    ),
                ));
            }
        }
    }
    Err(Error::bad_input(
        path,
        format!(
            "no colour channels: expected color.R, color.G, color.B (or R, G, B){}",
            part.context()
        ),
    ))
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// `"normal.Z"` → `(Layer::Normal, 2)`.
fn stats_channel(name: &str) -> Option<(Layer, usize)> {
    let (layer, channel) = name.split_once('.')?;
    let layer = Layer::from_name(layer)?;
    let index = layer.channels().iter().position(|c| *c == channel)?;
    Some((layer, index))
}

/// The names of a part's channels, in the order of its channel list.
fn part_channel_names(header: &Header) -> Vec<String> {
    header
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect()
}

/// The first part holding one of `channel_names` (tried in order), else part 0.
fn find_part(headers: &[Header], channel_names: &[&str]) -> usize {
    channel_names
        .iter()
        .find_map(|wanted| {
            headers
                .iter()
                .position(|h| h.channels.list.iter().any(|c| c.name.eq(wanted)))
        })
        .unwrap_or(0)
}

/// The wanted channels of one part, as f32 planes.
struct DecodedPart {
    width: usize,
    height: usize,
    part_index: usize,
    part_count: usize,
    /// Every channel name of the part, in file (alphabetical) order.
    all_names: Vec<String>,
    /// The wanted channels, converted; `None` once taken.
    planes: Vec<(String, Option<Vec<f32>>)>,
}

impl DecodedPart {
    fn take(&mut self, name: &str) -> Option<Vec<f32>> {
        self.planes
            .iter_mut()
            .find(|(n, _)| n == name)
            .and_then(|(_, p)| p.take())
    }

    fn has(&self, name: &str) -> bool {
        self.planes.iter().any(|(n, _)| n == name)
    }

    /// `"; the file has channels: ..."`, with the part for multi-part files.
    fn context(&self) -> String {
        const SHOWN: usize = 40;
        let mut list = self
            .all_names
            .iter()
            .take(SHOWN)
            .cloned()
            .collect::<Vec<_>>()
            .join(", ");
        if self.all_names.len() > SHOWN {
            list.push_str(&format!(", ... ({} channels)", self.all_names.len()));
        }
        if self.all_names.is_empty() {
            list = "(none)".into();
        }
        if self.part_count > 1 {
            format!(
                "; part {} of {} has channels: {list}",
                self.part_index, self.part_count
            )
        } else {
            format!("; the file has channels: {list}")
        }
    }
}

/// Builds the [`StatsImage`], checking required and complete layers.
fn assemble_stats(path: &Path, mut part: DecodedPart) -> Result<StatsImage> {
    let mut img = StatsImage::new(part.width, part.height);
    let mut problems = Vec::new();
    for layer in Layer::ALL {
        let names = layer.channel_names();
        let present: Vec<bool> = names.iter().map(|n| part.has(n)).collect();
        let count = present.iter().filter(|p| **p).count();
        if count == 0 {
            if layer.requirement() == Requirement::Required {
                problems.push(format!(
                    "missing required layer `{}` (channel{} {})",
                    layer.name(),
                    if names.len() > 1 { "s" } else { "" },
                    names.join(", ")
                ));
            }
            continue;
        }
        if count < names.len() {
            let missing: Vec<&str> = names
                .iter()
                .zip(&present)
                .filter(|(_, p)| !**p)
                .map(|(n, _)| n.as_str())
                .collect();
            problems.push(format!(
                "layer `{}` is incomplete: channel{} {} missing",
                layer.name(),
                if missing.len() > 1 { "s" } else { "" },
                missing.join(", ")
            ));
            continue;
        }
        let planes: Option<Vec<Vec<f32>>> = names.iter().map(|n| part.take(n)).collect();
        if let Some(planes) = planes {
            img.set(layer, planes);
        }
    }
    if problems.is_empty() {
        Ok(img)
    } else {
        Err(Error::bad_input(
            path,
            format!("{}{}", problems.join("; "), part.context()),
        ))
    }
}

/// Checks the container, then decodes under `catch_unwind`. With
/// `one_part`, wanted channels that only another part has are refused
/// before any pixel is decoded ([`refuse_split`]).
fn decode_part(
    path: &Path,
    bytes: &[u8],
    select: &dyn Fn(&[Header]) -> usize,
    wanted: &dyn Fn(&str) -> bool,
    one_part: bool,
) -> Result<DecodedPart> {
    if bytes.is_empty() {
        return Err(Error::bad_input(
            path,
            "empty file (0 bytes): not an OpenEXR file",
        ));
    }
    if bytes.len() < 4 || bytes[..4] != EXR_MAGIC {
        return Err(Error::bad_input(
            path,
            "not an OpenEXR file (it does not start with the EXR magic number 76 2f 31 01)",
        ));
    }
    match panic::catch_unwind(AssertUnwindSafe(|| {
        decode_unguarded(path, bytes, select, wanted, one_part)
    })) {
        Ok(result) => result,
        Err(payload) => Err(Error::bad_input(
            path,
            format!(
                "truncated or corrupt EXR: the decoder failed ({})",
                panic_detail(payload.as_ref())
            ),
        )),
    }
}

/// The message of a caught panic.
fn panic_detail(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "decoder panicked".into())
}

/// The `exr` error a caught panic of the decoder becomes.
fn decoder_failed(payload: &(dyn std::any::Any + Send)) -> exr::error::Error {
    let detail = panic_detail(payload);
    exr::error::Error::Invalid(format!("the decoder failed ({detail})").into())
}

/// Most threads [`decompress_blocks`] decompresses on.
const DECODE_THREADS: usize = 4;

/// Reads the chunks of `chunks` on one thread, decompresses them on up to
/// [`DECODE_THREADS`] (one per core), and hands each block to `each` on the
/// calling thread, in the order they finish. The first error `each` returns
/// stops the work and is returned. A panic while reading or decompressing
/// becomes that chunk's error. With several corrupt blocks, which one is
/// reported depends on which thread gets there first. A thread that cannot
/// be started is an [`Error::Io`] on `path`.
fn decompress_blocks<C: ChunksReader + Send>(
    path: &Path,
    chunks: C,
    each: &mut dyn FnMut(exr::error::Result<UncompressedBlock>) -> Result<()>,
) -> Result<()> {
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(DECODE_THREADS);
    if workers <= 1 {
        let mut decompressor = chunks.sequential_decompressor(false);
        while let Some(block) = decompressor.decompress_next_block() {
            each(block)?;
        }
        return Ok(());
    }
    let meta = chunks.meta_data().clone();
    std::thread::scope(|scope| {
        let (chunk_tx, chunk_rx) = mpsc::sync_channel(2 * workers);
        let (block_tx, block_rx) = mpsc::sync_channel(2 * workers);
        // Every thread stops when the other end of its channel is gone: the
        // reader once every worker has dropped its handle on the chunks,
        // the workers once this thread drops the blocks' receiver.
        let spawn_failed = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        std::thread::Builder::new()
            .spawn_scoped(scope, move || {
                // A panic while reading becomes the next chunk's error.
                let mut chunks = chunks;
                loop {
                    let next = panic::catch_unwind(AssertUnwindSafe(|| chunks.next()))
                        .unwrap_or_else(|p| Some(Err(decoder_failed(p.as_ref()))));
                    let Some(chunk) = next else { break };
                    let failed = chunk.is_err();
                    if chunk_tx.send(chunk).is_err() || failed {
                        break;
                    }
                }
            })
            .map_err(spawn_failed)?;
        let chunk_rx = Arc::new(Mutex::new(chunk_rx));
        for _ in 0..workers {
            let (rx, tx, meta) = (Arc::clone(&chunk_rx), block_tx.clone(), &meta);
            std::thread::Builder::new()
                .spawn_scoped(scope, move || loop {
                    let next = match rx.lock() {
                        Ok(rx) => rx.recv(),
                        Err(_) => break,
                    };
                    let Ok(chunk) = next else { break };
                    let block = chunk.and_then(|c| {
                        panic::catch_unwind(AssertUnwindSafe(|| {
                            UncompressedBlock::decompress_chunk(c, meta, false)
                        }))
                        .unwrap_or_else(|p| Err(decoder_failed(p.as_ref())))
                    });
                    if tx.send(block).is_err() {
                        break;
                    }
                })
                .map_err(spawn_failed)?;
        }
        drop((chunk_rx, block_tx));
        for block in block_rx {
            each(block)?;
        }
        Ok(())
    })
}

/// Statistics are read from one part: wanted channels that part lacks and
/// another part has would be left out without a word (an estimated
/// variance, no prefilter), so they are an error naming that part.
fn refuse_split(
    path: &Path,
    headers: &[Header],
    part_index: usize,
    all_names: &[String],
    wanted: &dyn Fn(&str) -> bool,
) -> Result<()> {
    for (other, h) in headers.iter().enumerate().filter(|&(i, _)| i != part_index) {
        let names: Vec<String> = part_channel_names(h)
            .into_iter()
            .filter(|n| wanted(n) && !all_names.contains(n))
            .collect();
        if names.is_empty() {
            continue;
        }
        const SHOWN: usize = 8;
        let mut list = names
            .iter()
            .take(SHOWN)
            .cloned()
            .collect::<Vec<_>>()
            .join(", ");
        if names.len() > SHOWN {
            list.push_str(&format!(", ... ({} channels)", names.len()));
        }
        return Err(Error::bad_input(
            path,
            format!(
                "the statistics are split over parts: part {other} has {list}, which part \
                 {part_index} (the one with color.R) lacks; the statistics are read from one \
                 part: write every layer into it"
            ),
        ));
    }
    Ok(())
}

fn decode_unguarded(
    path: &Path,
    bytes: &[u8],
    select: &dyn Fn(&[Header]) -> usize,
    wanted: &dyn Fn(&str) -> bool,
    one_part: bool,
) -> Result<DecodedPart> {
    let bad_exr = |e: exr::error::Error| Error::bad_input(path, describe_exr_error(bytes, e));

    let reader = exr::block::read(Cursor::new(bytes), false).map_err(bad_exr)?;
    let part_count = reader.headers().len();
    let part_index = select(reader.headers());
    let header: Header =
        reader.headers().get(part_index).cloned().ok_or_else(|| {
            Error::bad_input(path, "truncated or corrupt EXR: the file has no parts")
        })?;
    check_header(path, &header, part_index, part_count)?;

    let (width, height) = (header.layer_size.width(), header.layer_size.height());
    let pixels = width * height;
    let all_names = part_channel_names(&header);
    if one_part {
        refuse_split(path, reader.headers(), part_index, &all_names, wanted)?;
    }

    // One output slot per wanted channel, indexed by the channel's position in
    // the part's channel list (the order of the lines in a block).
    let mut planes: Vec<(String, Option<Vec<f32>>)> = Vec::new();
    let mut slot_of_channel: Vec<Option<usize>> = Vec::with_capacity(all_names.len());
    for name in &all_names {
        if wanted(name) && !planes.iter().any(|(n, _)| n == name) {
            let mut plane = Vec::new();
            plane.try_reserve_exact(pixels).map_err(|_| {
                Error::bad_input(
                    path,
                    format!("image too large: cannot allocate {width}x{height} pixels for {name}"),
                )
            })?;
            plane.resize(pixels, 0.0f32);
            slot_of_channel.push(Some(planes.len()));
            planes.push((name.clone(), Some(plane)));
        } else {
            slot_of_channel.push(None);
        }
    }

    let base_level = Vec2(0, 0);
    let expected_blocks = header
        .blocks_increasing_y_order()
        .filter(|tile| tile.location.level_index == base_level)
        .count();
    let chunks = reader
        .filter_chunks(false, |_meta, tile, block| {
            block.layer == part_index && tile.level_index == base_level
        })
        .map_err(bad_exr)?;
    let mut seen = HashSet::with_capacity(expected_blocks);
    decompress_blocks(path, chunks, &mut |block| {
        let block = block.map_err(bad_exr)?;
        let index = block.index;
        if index.layer != part_index || index.level != base_level {
            // A corrupt offset table pointing elsewhere; coverage is checked below.
            return Ok(());
        }
        let (bx, by) = (index.pixel_position.x(), index.pixel_position.y());
        let (bw, bh) = (index.pixel_size.width(), index.pixel_size.height());
        if bx + bw > width || by + bh > height {
            return Err(Error::bad_input(
                path,
                format!("truncated or corrupt EXR: a pixel block at ({bx}, {by}) lies outside the {width}x{height} image"),
            ));
        }
        if !seen.insert((bx, by)) {
            return Err(Error::bad_input(
                path,
                format!(
                    "truncated or corrupt EXR: two pixel blocks claim the pixels at ({bx}, {by})"
                ),
            ));
        }
        let expected_len = header.channels.bytes_per_pixel * bw * bh;
        if block.data.len() != expected_len {
            return Err(Error::bad_input(
                path,
                format!(
                    "truncated or corrupt EXR: the pixel block at ({bx}, {by}) decodes to {} bytes, expected {expected_len}",
                    block.data.len()
                ),
            ));
        }
        for line in block.lines(&header.channels) {
            let loc = line.location;
            let Some(slot) = slot_of_channel.get(loc.channel).copied().flatten() else {
                continue;
            };
            let sample_type = header.channels.list[loc.channel].sample_type;
            let start = loc.position.y() * width + loc.position.x();
            let Some(plane) = planes[slot].1.as_mut() else {
                continue;
            };
            let dst = &mut plane[start..start + loc.sample_count];
            if line.value.len() != loc.sample_count * sample_type.bytes_per_sample() {
                return Err(Error::bad_input(
                    path,
                    format!(
                        "truncated or corrupt EXR: a line of channel {} has the wrong length",
                        all_names[loc.channel]
                    ),
                ));
            }
            convert_samples(line.value, sample_type, dst);
        }
        Ok(())
    })?;
    if seen.len() != expected_blocks {
        return Err(Error::bad_input(
            path,
            format!(
                "truncated or corrupt EXR: only {} of the {expected_blocks} pixel blocks could be read",
                seen.len()
            ),
        ));
    }

    Ok(DecodedPart {
        width,
        height,
        part_index,
        part_count,
        all_names,
        planes,
    })
}

/// Rejects what the decoder cannot or should not handle, before allocating.
fn check_header(path: &Path, header: &Header, part: usize, parts: usize) -> Result<()> {
    let which = if parts > 1 {
        format!("part {part} of {parts}")
    } else {
        "the image".to_string()
    };
    if header.deep {
        return Err(Error::bad_input(
            path,
            format!("{which} holds deep data, which is not supported"),
        ));
    }
    if let Compression::HTJ2K32 | Compression::HTJ2K256 = header.compression {
        // The `exr` crate's reading of ids 10 and 11.
        let id = if header.compression == Compression::HTJ2K32 {
            11
        } else {
            10
        };
        return Err(Error::bad_input(
            path,
            format!(
                "compression {} is not supported; {RESAVE_HINT}",
                compression_name(id)
            ),
        ));
    }
    if let Some(c) = header
        .channels
        .list
        .iter()
        .find(|c| c.sampling != Vec2(1, 1))
    {
        return Err(Error::bad_input(
            path,
            format!(
                "channel {} is subsampled ({}x{}); subsampled channels are not supported",
                c.name,
                c.sampling.x(),
                c.sampling.y()
            ),
        ));
    }
    let (w, h) = (header.layer_size.width(), header.layer_size.height());
    if w == 0 || h == 0 {
        return Err(Error::bad_input(
            path,
            format!("{which} is empty (data window {w}x{h})"),
        ));
    }
    if w > MAX_DIMENSION || h > MAX_DIMENSION || w.saturating_mul(h) > MAX_PIXELS {
        return Err(Error::bad_input(
            path,
            format!(
                "{which} is too large: {w}x{h} pixels (limits: {MAX_DIMENSION} per side, {MAX_PIXELS} pixels)"
            ),
        ));
    }
    if header.chunk_count > MAX_CHUNKS {
        return Err(Error::bad_input(
            path,
            format!(
                "{which} has {} pixel blocks (limit {MAX_CHUNKS})",
                header.chunk_count
            ),
        ));
    }
    Ok(())
}

/// Native-endian samples of one line (as the decompressors leave them) to f32.
fn convert_samples(src: &[u8], sample_type: SampleType, dst: &mut [f32]) {
    match sample_type {
        SampleType::F32 => {
            for (d, b) in dst.iter_mut().zip(src.chunks_exact(4)) {
                *d = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
        SampleType::F16 => {
            for (d, b) in dst.iter_mut().zip(src.chunks_exact(2)) {
                *d = f16::from_bits(u16::from_ne_bytes([b[0], b[1]])).to_f32();
            }
        }
        SampleType::U32 => {
            for (d, b) in dst.iter_mut().zip(src.chunks_exact(4)) {
                *d = u32::from_ne_bytes([b[0], b[1], b[2], b[3]]) as f32;
            }
        }
    }
}

/// A human sentence for an `exr` crate error.
///
/// If the raw header names a compression we cannot decode (HTJ2K, ZSTD or an
/// unknown id), or a data window without pixels, that is reported whatever
/// the decoder tripped over first: its geometry checks come before and assume
/// a decodable compression and a non-empty image.
fn describe_exr_error(bytes: &[u8], error: exr::error::Error) -> String {
    use exr::error::Error as E;
    if let Some(id) = unsupported_compression(bytes) {
        return format!(
            "compression {} is not supported; {RESAVE_HINT}",
            compression_name(id)
        );
    }
    if let Some([x0, y0, x1, y1]) = empty_data_window(bytes) {
        return format!(
            "the image is empty (data window ({x0}, {y0}) to ({x1}, {y1}) holds no pixels)"
        );
    }
    match error {
        E::NotSupported(msg) => {
            if msg.contains("compression") {
                format!("unsupported compression method; {RESAVE_HINT}")
            } else if msg.contains("sampling") {
                "subsampled channels are not supported".to_string()
            } else if msg.contains("deep") {
                "deep data is not supported".to_string()
            } else {
                format!("unsupported EXR feature: {msg}")
            }
        }
        E::Invalid(msg) => {
            if msg.contains("sampling") {
                format!("subsampled channels are not supported ({msg})")
            } else if msg.contains("missing bytes") {
                "truncated or corrupt EXR: the file ends before the data it refers to".to_string()
            } else {
                format!("truncated or corrupt EXR: {msg}")
            }
        }
        E::Io(e) => format!("truncated or corrupt EXR: {e}"),
        E::Aborted => "reading the EXR was aborted".to_string(),
    }
}

/// OpenEXR compression ids, including those the `exr` crate does not know.
/// Ids 10 and up are the newer codecs (HTJ2K, ZSTD), which OpenEXR
/// releases and development versions have numbered differently (ZSTD has
/// been 11, 12 and 13), so they are not named by one table.
fn compression_name(id: u8) -> String {
    match id {
        0 => "NONE".into(),
        1 => "RLE".into(),
        2 => "ZIPS".into(),
        3 => "ZIP".into(),
        4 => "PIZ".into(),
        5 => "PXR24".into(),
        6 => "B44".into(),
        7 => "B44A".into(),
        8 => "DWAA".into(),
        9 => "DWAB".into(),
        10..=13 => format!("id {id} (HTJ2K or ZSTD, which OpenEXR versions number differently)"),
        other => format!("UNKNOWN (id {other})"),
    }
}

/// The raw values of every attribute called `name`, over all headers (parts),
/// read without the `exr` crate: used to explain what the decoder rejected.
/// Stops quietly at the first malformed attribute.
fn raw_attributes<'a>(bytes: &'a [u8], name: &[u8]) -> Vec<&'a [u8]> {
    let mut found = Vec::new();
    let multipart = bytes.get(4..8).is_some_and(|v| v[1] & 0x10 != 0);
    let mut pos = 8;
    let cstr = |pos: &mut usize| -> Option<&'a [u8]> {
        let rest = bytes.get(*pos..)?;
        let len = rest.iter().position(|b| *b == 0)?;
        *pos += len + 1;
        Some(&rest[..len])
    };
    let mut scan = || -> Option<()> {
        for _header in 0..1024 {
            loop {
                let attribute = cstr(&mut pos)?;
                if attribute.is_empty() {
                    break;
                }
                let _type_name = cstr(&mut pos)?;
                let size = i32::from_le_bytes(bytes.get(pos..pos + 4)?.try_into().ok()?);
                pos += 4;
                let size = usize::try_from(size).ok()?;
                let value = bytes.get(pos..pos + size)?;
                pos += size;
                if attribute == name {
                    found.push(value);
                }
            }
            if !multipart || bytes.get(pos) == Some(&0) {
                return None;
            }
        }
        None
    };
    scan();
    found
}

/// A `compression` value that cannot be decoded (HTJ2K = 10, 11; ZSTD = 12;
/// unknown ids), from the raw headers.
fn unsupported_compression(bytes: &[u8]) -> Option<u8> {
    raw_attributes(bytes, b"compression")
        .into_iter()
        // Lazy: `then_some(v[0])` would index an empty value (found by tests/fuzz.rs).
        .find_map(|v| (v.len() == 1 && v[0] >= 10).then(|| v[0]))
}

/// A `dataWindow` with no pixels (`max < min`), from the raw headers, as
/// `[x_min, y_min, x_max, y_max]`.
fn empty_data_window(bytes: &[u8]) -> Option<[i32; 4]> {
    raw_attributes(bytes, b"dataWindow")
        .into_iter()
        .find_map(|v| {
            if v.len() != 16 {
                return None;
            }
            let b: [i32; 4] = std::array::from_fn(|k| {
                i32::from_le_bytes([v[4 * k], v[4 * k + 1], v[4 * k + 2], v[4 * k + 3]])
            });
            (b[2] < b[0] || b[3] < b[1]).then_some(b)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A panic inside decoding (standing in for one in the `exr` crate) is
    /// reported as a corrupt file, not propagated.
    #[test]
    fn a_panic_while_decoding_becomes_bad_input() {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/dof_checker_64_ref.exr");
        let bytes = std::fs::read(&path).unwrap();
        let result = decode_part(
            &path,
            &bytes,
            &|_| panic!("simulated decoder bug"),
            &|_| true,
            false,
        );
        match result {
            Err(Error::BadInput { path: p, message }) => {
                assert_eq!(p, path);
                assert!(message.contains("simulated decoder bug"), "{message}");
                assert!(message.contains("truncated or corrupt"), "{message}");
            }
            other => panic!("expected BadInput, got {:?}", other.map(|p| p.width)),
        }
    }

    #[test]
    fn raw_header_scan_finds_attributes() {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/dof_checker_64_ref.exr");
        let bytes = std::fs::read(path).unwrap();
        assert_eq!(raw_attributes(&bytes, b"compression"), [&[3u8][..]]);
        assert_eq!(unsupported_compression(&bytes), None);
        assert_eq!(empty_data_window(&bytes), None);
        assert_eq!(raw_attributes(&bytes[..20], b"compression").len(), 0);
    }

    #[test]
    fn channel_names_parse() {
        assert_eq!(stats_channel("normal.Z"), Some((Layer::Normal, 2)));
        assert_eq!(
            stats_channel("position_covariance.YZ"),
            Some((Layer::PositionCovariance, 4))
        );
        assert_eq!(stats_channel("normal.W"), None);
        assert_eq!(stats_channel("normals.X"), None);
        assert_eq!(stats_channel("spp"), None);
    }
}
