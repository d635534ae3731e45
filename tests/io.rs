//! EXR/PNG input and output: round trips, the accepted variations of
//! `docs/input-format.md`, every kind of bad input (an error naming
//! the file and the problem, never a panic) and atomic writes.

mod common;

use std::path::{Path, PathBuf};

use exr::prelude::{
    f16, AnyChannel, AnyChannels, Blocks, Compression, Encoding, FlatSamples, Image,
    ImageAttributes, LayerAttributes, LineOrder, SmallVec, Text, Vec2, WritableImage,
};
use mcdenoise::error::Error;
use mcdenoise::image::{Layer, RgbImage, StatsImage};
use mcdenoise::io::{
    format_report, inspect, read_rgb, read_stats, spp_range, validate, write_atomic,
    write_channels, write_heatmap_png, write_output, write_png_preview, write_rgb, write_stats,
    OutputImage,
};

// ---------------------------------------------------------------------------
// helpers

/// A fresh, empty directory unique to this test, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("mcdenoise-io-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    fn entries(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn fixture(name: &str) -> PathBuf {
    manifest_dir().join("tests/fixtures").join(name)
}

/// A deterministic value for layer `l`, channel `c`, pixel `i`.
fn value(l: usize, c: usize, i: usize) -> f32 {
    let h = (l * 7919 + c * 104_729 + i * 2_654_435_761) % 1_000_003;
    (h as f32 / 1_000_003.0 - 0.25) * (1.0 + l as f32)
}

/// A statistics image with every layer of the format (or only those in `layers`).
fn synthetic_stats(w: usize, h: usize, layers: &[Layer]) -> StatsImage {
    let mut img = StatsImage::new(w, h);
    for (l, layer) in layers.iter().enumerate() {
        let planes = (0..layer.channels().len())
            .map(|c| {
                (0..w * h)
                    .map(|i| {
                        if *layer == Layer::Spp {
                            16.0
                        } else {
                            value(l, c, i)
                        }
                    })
                    .collect()
            })
            .collect();
        img.set(*layer, planes);
    }
    img
}

/// The full channel list of `img` as `(name, plane)`.
fn named_planes(img: &StatsImage) -> Vec<(String, Vec<f32>)> {
    img.layers()
        .flat_map(|(layer, planes)| {
            layer
                .channels()
                .iter()
                .zip(planes)
                .map(move |(c, p)| (format!("{}.{c}", layer.name()), p.clone()))
        })
        .collect()
}

/// Writes channels with the `exr` crate directly, for the variations our own
/// writer never produces.
fn write_exr_raw(
    path: &Path,
    size: (usize, usize),
    position: (i32, i32),
    encoding: Encoding,
    channels: Vec<(String, FlatSamples)>,
) {
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .into_iter()
        .map(|(name, samples)| AnyChannel::new(Text::new_or_panic(name), samples))
        .collect();
    let attributes = LayerAttributes::default().with_position(Vec2(position.0, position.1));
    let layer = exr::image::Layer::new(
        Vec2(size.0, size.1),
        attributes,
        encoding,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

fn encoding(compression: Compression, blocks: Blocks) -> Encoding {
    Encoding {
        compression,
        blocks,
        line_order: LineOrder::Increasing,
    }
}

fn f32_channels(img: &StatsImage) -> Vec<(String, FlatSamples)> {
    named_planes(img)
        .into_iter()
        .map(|(n, p)| (n, FlatSamples::F32(p)))
        .collect()
}

/// Bitwise equality of two statistics images (NaN compares equal to itself).
fn assert_bit_identical(a: &StatsImage, b: &StatsImage) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let la: Vec<Layer> = a.layers().map(|(l, _)| l).collect();
    let lb: Vec<Layer> = b.layers().map(|(l, _)| l).collect();
    assert_eq!(la, lb);
    for ((layer, pa), (_, pb)) in a.layers().zip(b.layers()) {
        for (c, (x, y)) in pa.iter().zip(pb).enumerate() {
            let xb: Vec<u32> = x.iter().map(|v| v.to_bits()).collect();
            let yb: Vec<u32> = y.iter().map(|v| v.to_bits()).collect();
            assert!(xb == yb, "{}.{} differs", layer.name(), layer.channels()[c]);
        }
    }
}

/// Asserts a `BadInput` error naming `path` whose message contains every one
/// of `needles` (case-insensitive).
fn assert_bad_input<T: std::fmt::Debug>(
    result: mcdenoise::error::Result<T>,
    path: &Path,
    needles: &[&str],
) {
    let err = result.expect_err("expected an error");
    let text = err.to_string();
    match &err {
        Error::BadInput { path: p, .. } => assert_eq!(p, path, "{text}"),
        other => panic!("expected BadInput, got {other:?}"),
    }
    let file_name = path.file_name().unwrap().to_string_lossy();
    assert!(
        text.contains(&*file_name),
        "message does not name the file: {text}"
    );
    for needle in needles {
        assert!(
            text.to_lowercase().contains(&needle.to_lowercase()),
            "message lacks {needle:?}: {text}"
        );
    }
}

/// Overwrites the 1-byte value of the first `compression` attribute.
fn patch_compression(bytes: &mut [u8], id: u8) {
    let pattern = b"compression\0compression\0\x01\0\0\0";
    let at = bytes
        .windows(pattern.len())
        .position(|w| w == pattern)
        .unwrap();
    bytes[at + pattern.len()] = id;
}

const REQUIRED: [Layer; 5] = [
    Layer::Color,
    Layer::Albedo,
    Layer::Normal,
    Layer::Depth,
    Layer::Spp,
];

// ---------------------------------------------------------------------------
// round trips and the public data

#[test]
fn write_stats_read_stats_round_trip_is_exact() {
    let dir = TempDir::new("roundtrip");
    let mut img = synthetic_stats(37, 23, &Layer::ALL);
    // Special values must survive bit-exactly.
    let color = img.get_mut(Layer::Color).unwrap();
    color[0][0] = f32::NAN;
    color[1][1] = f32::INFINITY;
    color[2][2] = f32::NEG_INFINITY;
    color[0][3] = f32::from_bits(1); // denormal
    color[1][4] = -0.0;
    let path = dir.path("all_layers.exr");
    write_stats(&path, &img).unwrap();
    let back = read_stats(&path).unwrap();
    assert_bit_identical(&img, &back);
    assert_eq!(back.layers().count(), 14);

    // Required layers only.
    let small = synthetic_stats(5, 3, &REQUIRED);
    let path = dir.path("required_only.exr");
    write_stats(&path, &small).unwrap();
    assert_bit_identical(&small, &read_stats(&path).unwrap());
    assert_eq!(dir.entries(), ["all_layers.exr", "required_only.exr"]);
}

#[test]
fn fixture_reads() {
    let stats = read_stats(&fixture("dof_checker_64_spp16.exr")).unwrap();
    let reference = read_rgb(&fixture("dof_checker_64_ref.exr")).unwrap();
    assert_eq!((stats.width, stats.height), (64, 64));
    assert_eq!((reference.width, reference.height), (64, 64));
    let channels: usize = stats.layers().map(|(l, _)| l.channels().len()).sum();
    assert_eq!(channels, 33);
    assert_eq!(spp_range(&stats), Some((16.0, 16.0)));
    for path in ["dof_checker_64_spp16.exr", "dof_checker_64_ref.exr"] {
        assert!(std::fs::metadata(fixture(path)).unwrap().len() < 1 << 20);
    }
}

// ---------------------------------------------------------------------------
// accepted variations

#[test]
fn half_and_uint_channels_are_converted() {
    let dir = TempDir::new("half");
    let img = synthetic_stats(11, 6, &REQUIRED);
    let channels: Vec<(String, FlatSamples)> = named_planes(&img)
        .into_iter()
        .map(|(n, p)| {
            let samples = if n == "spp.Y" {
                FlatSamples::U32(p.iter().map(|v| *v as u32).collect())
            } else {
                FlatSamples::F16(p.iter().map(|v| f16::from_f32(*v)).collect())
            };
            (n, samples)
        })
        .collect();
    let path = dir.path("half.exr");
    write_exr_raw(
        &path,
        (11, 6),
        (0, 0),
        encoding(Compression::ZIP16, Blocks::ScanLines),
        channels,
    );
    let back = read_stats(&path).unwrap();
    for (layer, planes) in img.layers() {
        for (c, plane) in planes.iter().enumerate() {
            let got = &back.get(layer).unwrap()[c];
            for (v, g) in plane.iter().zip(got) {
                let expected = if layer == Layer::Spp {
                    *v
                } else {
                    f16::from_f32(*v).to_f32()
                };
                assert_eq!(expected.to_bits(), g.to_bits(), "{}", layer.name());
            }
        }
    }
}

#[test]
fn data_window_offset_is_the_image() {
    let dir = TempDir::new("offset");
    let img = synthetic_stats(13, 9, &REQUIRED);
    let path = dir.path("offset.exr");
    write_exr_raw(
        &path,
        (13, 9),
        (5, 7),
        encoding(Compression::RLE, Blocks::ScanLines),
        f32_channels(&img),
    );
    let back = read_stats(&path).unwrap();
    assert_eq!((back.width, back.height), (13, 9));
    assert_bit_identical(&img, &back);

    // A negative origin too.
    let path = dir.path("negative.exr");
    write_exr_raw(
        &path,
        (13, 9),
        (-3, -40),
        encoding(Compression::ZIP1, Blocks::ScanLines),
        f32_channels(&img),
    );
    assert_bit_identical(&img, &read_stats(&path).unwrap());
}

#[test]
fn tiled_files_and_lossless_compressions_read_exactly() {
    let dir = TempDir::new("tiled");
    let img = synthetic_stats(37, 29, &Layer::ALL);
    let compressions = [
        Compression::Uncompressed,
        Compression::RLE,
        Compression::ZIP1,
        Compression::ZIP16,
        Compression::PIZ,
    ];
    for (i, compression) in compressions.into_iter().enumerate() {
        for blocks in [Blocks::ScanLines, Blocks::Tiles(Vec2(16, 8))] {
            let path = dir.path(&format!("c{i}_{}.exr", matches!(blocks, Blocks::Tiles(_))));
            write_exr_raw(
                &path,
                (37, 29),
                (0, 0),
                encoding(compression, blocks),
                f32_channels(&img),
            );
            assert_bit_identical(&img, &read_stats(&path).unwrap());
        }
    }
}

#[test]
fn multi_part_file_uses_the_part_with_the_statistics() {
    let dir = TempDir::new("multipart");
    let img = synthetic_stats(8, 5, &REQUIRED);
    let beauty: SmallVec<[AnyChannel<FlatSamples>; 4]> = ["B", "G", "R"]
        .iter()
        .map(|c| AnyChannel::new(*c, FlatSamples::F32(vec![9.0; 40])))
        .collect();
    let stats: SmallVec<[AnyChannel<FlatSamples>; 4]> = named_planes(&img)
        .into_iter()
        .map(|(n, p)| AnyChannel::new(Text::new_or_panic(n), FlatSamples::F32(p)))
        .collect();
    let enc = encoding(Compression::ZIP16, Blocks::ScanLines);
    let part0 = exr::image::Layer::new(
        Vec2(8, 5),
        LayerAttributes::named("beauty"),
        enc,
        AnyChannels::sort(beauty),
    );
    let part1 = exr::image::Layer::new(
        Vec2(8, 5),
        LayerAttributes::named("stats"),
        enc,
        AnyChannels::sort(stats),
    );
    let path = dir.path("multipart.exr");
    let image = Image::from_layers(
        ImageAttributes::new(exr::prelude::IntegerBounds::from_dimensions(Vec2(8, 5))),
        vec![part0, part1],
    );
    image.write().to_file(&path).unwrap();
    assert_eq!(
        exr::meta::MetaData::read_from_file(&path, false)
            .unwrap()
            .headers
            .len(),
        2
    );

    assert_bit_identical(&img, &read_stats(&path).unwrap());
    // A reference reader prefers `color.*` (part 1) over bare R/G/B (part 0).
    let rgb = read_rgb(&path).unwrap();
    assert_eq!(rgb.planes[0], img.get(Layer::Color).unwrap()[0]);
}

#[test]
fn statistics_split_over_parts_are_refused() {
    let dir = TempDir::new("splitparts");
    let img = synthetic_stats(8, 5, &Layer::ALL);
    let part = |name: &str, keep: &dyn Fn(&str) -> bool| {
        let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = named_planes(&img)
            .into_iter()
            .filter(|(n, _)| keep(n))
            .map(|(n, p)| AnyChannel::new(Text::new_or_panic(n), FlatSamples::F32(p)))
            .collect();
        exr::image::Layer::new(
            Vec2(8, 5),
            LayerAttributes::named(name),
            encoding(Compression::ZIP16, Blocks::ScanLines),
            AnyChannels::sort(channels),
        )
    };
    // The required layers in one part, the variances and the position in
    // another: reading the first alone would estimate the variances and
    // drop the G-buffer prefilter's input without a word.
    let required = |n: &str| {
        REQUIRED
            .iter()
            .any(|l| l.channel_names().iter().any(|c| c == n))
    };
    let path = dir.path("split.exr");
    Image::from_layers(
        ImageAttributes::new(exr::prelude::IntegerBounds::from_dimensions(Vec2(8, 5))),
        vec![part("means", &required), part("rest", &|n| !required(n))],
    )
    .write()
    .to_file(&path)
    .unwrap();
    let err = read_stats(&path).unwrap_err().to_string();
    assert!(err.contains("split.exr"), "{err}");
    assert!(
        err.contains("split over parts")
            && err.contains("part 1 has")
            && err.contains("color_variance.R")
            && err.contains("part 0"),
        "{err}"
    );
}

#[test]
fn missing_variance_layers_are_absent_not_an_error() {
    let dir = TempDir::new("novariance");
    let img = synthetic_stats(6, 4, &REQUIRED);
    let path = dir.path("no_variance.exr");
    write_stats(&path, &img).unwrap();
    let back = read_stats(&path).unwrap();
    for layer in [
        Layer::ColorVariance,
        Layer::AlbedoVariance,
        Layer::NormalVariance,
        Layer::DepthVariance,
    ] {
        assert!(!back.has(layer));
    }
    let warnings = validate(&back).join("\n");
    assert!(
        warnings.contains("color_variance is missing: it will be estimated"),
        "{warnings}"
    );
    assert!(warnings.contains("depth_variance"), "{warnings}");
}

#[test]
fn unknown_channels_are_ignored() {
    let dir = TempDir::new("unknown");
    let img = synthetic_stats(4, 4, &REQUIRED);
    let mut channels = f32_channels(&img);
    for extra in ["A", "Z", "color.A", "diffuse.R", "normal.W", "spp"] {
        channels.push((extra.to_string(), FlatSamples::F32(vec![1.0; 16])));
    }
    let path = dir.path("extra.exr");
    write_exr_raw(
        &path,
        (4, 4),
        (0, 0),
        encoding(Compression::ZIP16, Blocks::ScanLines),
        channels,
    );
    assert_bit_identical(&img, &read_stats(&path).unwrap());
}

#[test]
fn nan_inf_and_negative_variances_survive_reading() {
    let dir = TempDir::new("nan");
    let mut img = synthetic_stats(
        8,
        8,
        &[
            Layer::Color,
            Layer::ColorVariance,
            Layer::Albedo,
            Layer::Normal,
            Layer::Depth,
            Layer::Spp,
        ],
    );
    img.get_mut(Layer::Color).unwrap()[0][9] = f32::NAN;
    img.get_mut(Layer::Color).unwrap()[2][10] = f32::INFINITY;
    for v in img.get_mut(Layer::ColorVariance).unwrap()[1]
        .iter_mut()
        .take(5)
    {
        *v = -0.5;
    }
    img.get_mut(Layer::Spp).unwrap()[0][63] = 0.0;
    img.get_mut(Layer::Spp).unwrap()[0][62] = 1.0;
    let path = dir.path("special.exr");
    write_stats(&path, &img).unwrap();
    let back = read_stats(&path).unwrap();
    assert_bit_identical(&img, &back);

    let report = inspect(&back);
    let color = &report
        .iter()
        .find(|r| r.layer == Layer::Color)
        .unwrap()
        .channels;
    assert_eq!((color[0].nan, color[2].inf), (1, 1));
    assert!(color[0].min.is_finite() && color[2].max.is_finite());
    let var = &report
        .iter()
        .find(|r| r.layer == Layer::ColorVariance)
        .unwrap()
        .channels;
    assert!(var[1].negative >= 5);

    let warnings = validate(&back).join("\n");
    assert!(
        warnings.contains("color.R: 1 NaN and 0 Inf values (first at pixel (1, 1))"),
        "{warnings}"
    );
    assert!(warnings.contains("color.B: 0 NaN and 1 Inf"), "{warnings}");
    assert!(
        warnings.contains("color_variance.G") && warnings.contains("negative variance"),
        "{warnings}"
    );
    assert!(
        warnings.contains("zero samples (first at pixel (7, 7))"),
        "{warnings}"
    );
    assert!(warnings.contains("fewer than 2 samples"), "{warnings}");
    assert_eq!(spp_range(&back), Some((0.0, 16.0)));

    let text = format_report(&path, &back);
    for needle in [
        "special.exr",
        "8 x 8",
        "color_variance.G",
        "NaN",
        "warnings:",
        "0 .. 16",
        "albedo_variance (will be estimated)",
    ] {
        assert!(text.contains(needle), "report lacks {needle:?}:\n{text}");
    }
}

// ---------------------------------------------------------------------------
// bad input: an error naming the file and the problem, never a panic

#[test]
fn missing_required_layer_is_named() {
    let dir = TempDir::new("missing");
    let img = synthetic_stats(
        4,
        3,
        &[Layer::Color, Layer::Albedo, Layer::Depth, Layer::Spp],
    );
    let path = dir.path("no_normal.exr");
    write_stats(&path, &img).unwrap();
    assert_bad_input(
        read_stats(&path),
        &path,
        &[
            "missing required layer `normal`",
            "normal.X, normal.Y, normal.Z",
        ],
    );

    let img = synthetic_stats(4, 3, &[Layer::Albedo, Layer::Normal]);
    let path = dir.path("no_color_depth_spp.exr");
    write_stats(&path, &img).unwrap();
    assert_bad_input(read_stats(&path), &path, &["`color`", "`depth`", "`spp`"]);
}

#[test]
fn incomplete_layer_names_the_missing_channel() {
    let dir = TempDir::new("incomplete");
    let img = synthetic_stats(4, 3, &REQUIRED);
    let planes = named_planes(&img);
    let channels: Vec<(&str, &[f32])> = planes
        .iter()
        .filter(|(n, _)| n != "normal.Z")
        .map(|(n, p)| (n.as_str(), p.as_slice()))
        .collect();
    let path = dir.path("no_normal_z.exr");
    write_channels(&path, 4, 3, &channels).unwrap();
    assert_bad_input(
        read_stats(&path),
        &path,
        &["layer `normal` is incomplete", "normal.Z"],
    );

    // The same holds for an optional layer.
    let mut planes = planes.clone();
    planes.push(("position_covariance.XX".into(), vec![0.0; 12]));
    let channels: Vec<(&str, &[f32])> = planes
        .iter()
        .map(|(n, p)| (n.as_str(), p.as_slice()))
        .collect();
    let path = dir.path("partial_cov.exr");
    write_channels(&path, 4, 3, &channels).unwrap();
    assert_bad_input(
        read_stats(&path),
        &path,
        &["position_covariance", "position_covariance.ZZ"],
    );
}

#[test]
fn non_exr_empty_and_missing_files() {
    let dir = TempDir::new("notexr");
    let text = dir.path("notes.exr");
    std::fs::write(&text, "this is a text file, not an image\n").unwrap();
    assert_bad_input(read_stats(&text), &text, &["not an OpenEXR file"]);
    assert_bad_input(read_rgb(&text), &text, &["not an OpenEXR file"]);

    let empty = dir.path("empty.exr");
    std::fs::write(&empty, b"").unwrap();
    assert_bad_input(read_stats(&empty), &empty, &["empty file"]);

    let short = dir.path("short.exr");
    std::fs::write(&short, [0x76, 0x2f]).unwrap();
    assert_bad_input(read_stats(&short), &short, &["not an OpenEXR file"]);

    let magic_only = dir.path("magic_only.exr");
    std::fs::write(&magic_only, [0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0]).unwrap();
    assert_bad_input(
        read_stats(&magic_only),
        &magic_only,
        &["truncated or corrupt"],
    );

    let absent = dir.path("absent.exr");
    match read_stats(&absent) {
        Err(Error::Io { path, .. }) => assert_eq!(path, absent),
        other => panic!("expected Io error, got {other:?}"),
    }
}

#[test]
fn truncated_file_is_rejected() {
    let dir = TempDir::new("truncated");
    let src = fixture("dof_checker_64_spp16.exr");
    let bytes = std::fs::read(&src).unwrap();
    let path = dir.path("half_of_it.exr");
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    assert_bad_input(read_stats(&path), &path, &["truncated or corrupt"]);
    // Cut inside the header and inside the offset table too.
    for len in [12, 100, 400, 2000] {
        std::fs::write(&path, &bytes[..len]).unwrap();
        assert_bad_input(read_stats(&path), &path, &["truncated or corrupt"]);
    }
}

#[test]
fn unsupported_compressions_are_named() {
    let dir = TempDir::new("compression");
    let img = synthetic_stats(8, 8, &REQUIRED);
    // PIZ: one 32-line block, like HTJ2K32/ZSTD (32 lines) and HTJ2K256 (256 lines)
    // for an 8-line image, so the patched headers stay self-consistent; the
    // uncompressed source (one block per line) is not.
    for source in [Compression::PIZ, Compression::Uncompressed] {
        let path = dir.path("plain.exr");
        write_exr_raw(
            &path,
            (8, 8),
            (0, 0),
            encoding(source, Blocks::ScanLines),
            f32_channels(&img),
        );
        let bytes = std::fs::read(&path).unwrap();
        // Ids 10-13 are HTJ2K and ZSTD, numbered differently by OpenEXR
        // versions: named as both, with the id.
        for (id, name) in [
            (13u8, "id 13 (HTJ2K or ZSTD"),
            (12, "id 12 (HTJ2K or ZSTD"),
            (10, "id 10 (HTJ2K or ZSTD"),
            (11, "id 11 (HTJ2K or ZSTD"),
            (42, "unknown (id 42)"),
        ] {
            let mut patched = bytes.clone();
            patch_compression(&mut patched, id);
            let target = dir.path(&format!("compression_{id}.exr"));
            std::fs::write(&target, &patched).unwrap();
            assert_bad_input(
                read_stats(&target),
                &target,
                &[
                    &format!("compression {name}"),
                    "not supported",
                    "re-save with ZIP",
                ],
            );
            assert!(read_rgb(&target).is_err());
        }
    }
}

#[test]
fn subsampled_channels_are_rejected() {
    let dir = TempDir::new("subsampled");
    let img = synthetic_stats(8, 8, &REQUIRED);
    let path = dir.path("plain.exr");
    write_exr_raw(
        &path,
        (8, 8),
        (0, 0),
        encoding(Compression::Uncompressed, Blocks::ScanLines),
        f32_channels(&img),
    );
    let mut bytes = std::fs::read(&path).unwrap();
    // First channel entry: name\0, pixel type (4), pLinear + reserved (4), xSampling (4), ySampling (4).
    let list = b"channels\0chlist\0";
    let at = bytes.windows(list.len()).position(|w| w == list).unwrap() + list.len() + 4;
    let name_end = at + bytes[at..].iter().position(|b| *b == 0).unwrap() + 1;
    bytes[name_end + 8..name_end + 12].copy_from_slice(&2i32.to_le_bytes());
    bytes[name_end + 12..name_end + 16].copy_from_slice(&2i32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    assert_bad_input(read_stats(&path), &path, &["subsampled"]);
}

#[test]
fn empty_data_window_is_rejected() {
    let dir = TempDir::new("emptywindow");
    let img = synthetic_stats(8, 8, &REQUIRED);
    let path = dir.path("zero.exr");
    write_exr_raw(
        &path,
        (8, 8),
        (0, 0),
        encoding(Compression::Uncompressed, Blocks::ScanLines),
        f32_channels(&img),
    );
    let mut bytes = std::fs::read(&path).unwrap();
    // dataWindow box2i: xMin, yMin, xMax, yMax; make xMax = xMin - 1 (width 0).
    let attr = b"dataWindow\0box2i\0\x10\0\0\0";
    let at = bytes.windows(attr.len()).position(|w| w == attr).unwrap() + attr.len();
    bytes[at + 8..at + 12].copy_from_slice(&(-1i32).to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    assert_bad_input(read_stats(&path), &path, &["image is empty"]);
}

#[test]
fn corrupted_files_never_panic() {
    let dir = TempDir::new("fuzz");
    let img = synthetic_stats(9, 7, &Layer::ALL);
    let mut sources = Vec::new();
    for (i, (compression, blocks)) in [
        (Compression::ZIP16, Blocks::ScanLines),
        (Compression::PIZ, Blocks::Tiles(Vec2(4, 4))),
        (Compression::RLE, Blocks::ScanLines),
        (Compression::Uncompressed, Blocks::Tiles(Vec2(8, 2))),
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.path(&format!("src{i}.exr"));
        write_exr_raw(
            &path,
            (9, 7),
            (0, 0),
            encoding(compression, blocks),
            f32_channels(&img),
        );
        sources.push(std::fs::read(&path).unwrap());
    }
    let target = dir.path("mutant.exr");
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut errors = 0;
    for round in 0..600 {
        let mut bytes = sources[round % sources.len()].clone();
        match round % 3 {
            0 => bytes.truncate(next() as usize % bytes.len()),
            1 => {
                for _ in 0..1 + next() % 4 {
                    let i = next() as usize % bytes.len();
                    bytes[i] = next() as u8;
                }
            }
            _ => {
                let i = 8 + next() as usize % (bytes.len() - 8);
                bytes[i] ^= 1 << (next() % 8);
            }
        }
        std::fs::write(&target, &bytes).unwrap();
        // Either outcome is fine; a panic or abort fails the test.
        if read_stats(&target).is_err() {
            errors += 1;
        }
        let _ = read_rgb(&target);
    }
    assert!(errors > 100, "only {errors} of 600 mutants were rejected");
}

// ---------------------------------------------------------------------------
// reference images

#[test]
fn reference_images_with_color_or_bare_rgb() {
    let dir = TempDir::new("reference");
    let img = RgbImage::from_planes(
        3,
        2,
        std::array::from_fn(|c| (0..6).map(|i| value(9, c, i)).collect()),
    );
    let path = dir.path("color.exr");
    write_rgb(&path, &img).unwrap();
    assert_eq!(read_rgb(&path).unwrap(), img);

    let bare = dir.path("bare.exr");
    write_channels(
        &bare,
        3,
        2,
        &[
            ("R", &img.planes[0]),
            ("G", &img.planes[1]),
            ("B", &img.planes[2]),
            ("A", &[1.0; 6]),
        ],
    )
    .unwrap();
    assert_eq!(read_rgb(&bare).unwrap(), img);

    let partial = dir.path("partial.exr");
    write_channels(
        &partial,
        3,
        2,
        &[("color.R", &img.planes[0]), ("color.B", &img.planes[2])],
    )
    .unwrap();
    assert_bad_input(read_rgb(&partial), &partial, &["color.G"]);

    let none = dir.path("none.exr");
    write_channels(&none, 3, 2, &[("Y", &img.planes[0])]).unwrap();
    assert_bad_input(read_rgb(&none), &none, &["no colour channels", "Y"]);
}

// ---------------------------------------------------------------------------
// writing

#[test]
fn output_image_channels() {
    let dir = TempDir::new("output");
    let color = RgbImage::from_planes(
        4,
        2,
        std::array::from_fn(|c| (0..8).map(|i| value(1, c, i)).collect()),
    );
    let error = RgbImage::from_planes(
        4,
        2,
        std::array::from_fn(|c| (0..8).map(|i| value(2, c, i)).collect()),
    );
    let out = OutputImage {
        color: color.clone(),
        error: Some(error.clone()),
        samples: Some(vec![3.0; 8]),
        debug: vec![
            ("weights".into(), vec![0.5; 8]),
            ("rank".into(), vec![2.0; 8]),
        ],
    };
    let path = dir.path("out.exr");
    write_output(&path, &out).unwrap();
    let meta = exr::meta::MetaData::read_from_file(&path, true).unwrap();
    assert_eq!(meta.headers.len(), 1);
    assert_eq!(meta.headers[0].compression, Compression::ZIP16);
    let names: Vec<String> = meta.headers[0]
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(
        names,
        [
            "color.B",
            "color.G",
            "color.R",
            "debug.rank",
            "debug.weights",
            "error.B",
            "error.G",
            "error.R",
            "samples.Y"
        ]
    );
    assert!(meta.headers[0]
        .channels
        .list
        .iter()
        .all(|c| c.sample_type == exr::prelude::SampleType::F32));
    assert_eq!(read_rgb(&path).unwrap(), color);

    let minimal = OutputImage {
        color: color.clone(),
        error: None,
        samples: None,
        debug: vec![],
    };
    write_output(&dir.path("minimal.exr"), &minimal).unwrap();
    assert_eq!(read_rgb(&dir.path("minimal.exr")).unwrap(), color);

    let wrong = OutputImage {
        color: color.clone(),
        error: None,
        samples: Some(vec![1.0; 7]),
        debug: vec![],
    };
    assert!(matches!(
        write_output(&dir.path("wrong.exr"), &wrong),
        Err(Error::InvalidArgument(_))
    ));
    let twice = OutputImage {
        color,
        error: None,
        samples: None,
        debug: vec![("a".into(), vec![0.0; 8]), ("a".into(), vec![0.0; 8])],
    };
    assert!(matches!(
        write_output(&dir.path("twice.exr"), &twice),
        Err(Error::InvalidArgument(_))
    ));
    assert_eq!(dir.entries(), ["minimal.exr", "out.exr"]);
}

#[test]
fn writes_are_atomic() {
    let dir = TempDir::new("atomic");
    let img = synthetic_stats(4, 4, &REQUIRED);

    // Into a directory that does not exist: an error naming the path, no file anywhere.
    let missing = dir.path("no/such/dir/out.exr");
    match write_stats(&missing, &img) {
        Err(Error::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected Io error, got {other:?}"),
    }
    assert!(dir.entries().is_empty());

    // A successful write leaves exactly the file; overwriting replaces it.
    let path = dir.path("stats.exr");
    write_stats(&path, &img).unwrap();
    write_stats(&path, &synthetic_stats(2, 2, &REQUIRED)).unwrap();
    assert_eq!(read_stats(&path).unwrap().width, 2);
    write_png_preview(&dir.path("p.png"), &RgbImage::new(2, 2)).unwrap();
    assert_eq!(dir.entries(), ["p.png", "stats.exr"]);

    // A failing writer removes its temporary file and leaves the old file alone.
    let before = std::fs::read(&path).unwrap();
    let result = write_atomic(&path, |w| {
        use std::io::Write;
        w.write_all(b"partial").unwrap();
        Err(Error::BadData("simulated failure".into()))
    });
    assert!(result.is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(dir.entries(), ["p.png", "stats.exr"]);

    // Renaming onto a directory fails after the data was written: no temporary file remains.
    std::fs::create_dir(dir.path("a_directory")).unwrap();
    assert!(write_stats(&dir.path("a_directory"), &img).is_err());
    assert_eq!(dir.entries(), ["a_directory", "p.png", "stats.exr"]);

    // Through a symbolic link (relative, two deep) the file it names is
    // written and the links stay links.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("stats.exr", dir.path("link1.exr")).unwrap();
        std::os::unix::fs::symlink("link1.exr", dir.path("link2.exr")).unwrap();
        write_stats(&dir.path("link2.exr"), &synthetic_stats(3, 2, &REQUIRED)).unwrap();
        assert_eq!(read_stats(&path).unwrap().width, 3);
        for l in ["link1.exr", "link2.exr"] {
            assert!(dir.path(l).is_symlink(), "{l}");
        }
        assert_eq!(
            dir.entries(),
            [
                "a_directory",
                "link1.exr",
                "link2.exr",
                "p.png",
                "stats.exr"
            ]
        );
    }

    // A FIFO, like a device such as /dev/null, is not a file to replace:
    // it is written in place and stays a FIFO.
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let fifo = dir.path("pipe");
        let name = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: `name` is a valid NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).unwrap())
        };
        write_atomic(&fifo, |w| {
            use std::io::Write;
            w.write_all(b"through the pipe").unwrap();
            Ok(())
        })
        .unwrap();
        let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
        assert!(kind.is_fifo(), "the FIFO was replaced: {kind:?}");
        assert_eq!(reader.join().unwrap(), b"through the pipe");
        assert!(dir.entries().iter().all(|e| !e.contains(".tmp-")));
    }
}

/// The OS error of an [`Error::Io`] for `path`.
fn os_error(result: mcdenoise::Result<()>, path: &Path) -> (i32, String) {
    match result {
        Err(e @ Error::Io { .. }) => {
            let message = e.to_string();
            let Error::Io { path: p, source } = e else {
                unreachable!()
            };
            assert_eq!(p, path, "{message}");
            (source.raw_os_error().unwrap_or(0), message)
        }
        other => panic!("expected an Io error for {}, got {other:?}", path.display()),
    }
}

/// A full disk (injected: `mcdenoise::fault`), at every point of a write,
/// for each writer: an error naming the destination and "No space left on
/// device", no partial or temporary file, an existing file untouched.
#[test]
fn a_full_disk_leaves_no_partial_file() {
    use mcdenoise::fault::Plan;
    let dir = TempDir::new("full_disk");
    let stats = synthetic_stats(16, 9, &REQUIRED);
    let color = RgbImage::from_planes(
        4,
        3,
        [
            (0..12).map(|i| i as f32).collect(),
            vec![0.5; 12],
            vec![2.0; 12],
        ],
    );
    let output = OutputImage {
        color: color.clone(),
        error: Some(color.clone()),
        samples: Some(vec![3.0; 12]),
        debug: vec![],
    };
    type Writer<'a> = Box<dyn Fn(&Path) -> mcdenoise::Result<()> + 'a>;
    let writers: [(&str, Writer); 3] = [
        ("stats.exr", Box::new(|p| write_stats(p, &stats))),
        ("out.exr", Box::new(|p| write_output(p, &output))),
        ("preview.png", Box::new(|p| write_png_preview(p, &color))),
    ];
    for (name, write) in &writers {
        let path = dir.path(name);
        // The bytes a complete write takes.
        let plan = Plan::new();
        write(&path).unwrap();
        let total = plan.bytes_written();
        drop(plan);
        let complete = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert!(
            total >= complete.len() as u64 && total > 8,
            "{name}: {total}"
        );

        for limit in [0, 1, total / 2, total - 1] {
            for existing in [false, true] {
                if existing {
                    std::fs::write(&path, b"the previous output").unwrap();
                }
                let plan = Plan::new().fail_write_after(limit, libc::ENOSPC);
                let result = write(&path);
                assert_eq!(plan.bytes_written(), limit, "{name}: stops at the limit");
                drop(plan);
                let (errno, message) = os_error(result, &path);
                if !existing {
                    eprintln!("{name}, disk full after {limit} of {total} bytes: {message}");
                }
                assert_eq!(errno, libc::ENOSPC, "{name} at {limit}: {message}");
                assert!(
                    message.contains(name) && message.contains("No space left on device"),
                    "{message}"
                );
                if existing {
                    assert_eq!(std::fs::read(&path).unwrap(), b"the previous output");
                    std::fs::remove_file(&path).unwrap();
                }
                assert!(
                    dir.entries().is_empty(),
                    "{name} at {limit}: {:?}",
                    dir.entries()
                );
            }
        }
        // Exactly enough room: the write completes.
        let plan = Plan::new().fail_write_after(total, libc::ENOSPC);
        write(&path).unwrap();
        drop(plan);
        assert_eq!(std::fs::read(&path).unwrap(), complete, "{name}");
        std::fs::remove_file(&path).unwrap();
    }
}

/// An unwritable destination (injected, since root ignores permissions): the
/// temporary file cannot be created (read-only file system), or the final
/// rename fails (permission denied); also a destination whose directory is a
/// file. Each is an error naming the destination, with nothing left behind.
#[test]
fn unwritable_destinations_are_named_and_leave_nothing() {
    use mcdenoise::fault::{Call, Failure, Plan};
    let dir = TempDir::new("unwritable");
    let img = synthetic_stats(4, 4, &REQUIRED);
    let path = dir.path("out.exr");
    for (call, errno, text) in [
        (Call::FileCreate, libc::EROFS, "Read-only file system"),
        (Call::FileRename, libc::EACCES, "Permission denied"),
        (Call::FileWrite, libc::EIO, "Input/output error"),
    ] {
        for existing in [false, true] {
            if existing {
                std::fs::write(&path, b"old").unwrap();
            }
            let plan = Plan::new().fail(call, 1, Failure::Os(errno));
            let result = write_stats(&path, &img);
            assert!(plan.all_fired(), "{call:?}");
            drop(plan);
            let (got, message) = os_error(result, &path);
            eprintln!("write_stats, {call:?} fails (existing file: {existing}): {message}");
            assert_eq!(got, errno, "{call:?}: {message}");
            assert!(
                message.contains("out.exr") && message.contains(text),
                "{message}"
            );
            if existing {
                assert_eq!(std::fs::read(&path).unwrap(), b"old");
                std::fs::remove_file(&path).unwrap();
            }
            assert!(dir.entries().is_empty(), "{call:?}: {:?}", dir.entries());
        }
    }
    // A path through a regular file: not a directory.
    std::fs::write(dir.path("file"), b"x").unwrap();
    let through = dir.path("file/out.exr");
    let (errno, message) = os_error(write_stats(&through, &img), &through);
    assert_eq!(errno, libc::ENOTDIR, "{message}");
    assert_eq!(dir.entries(), ["file"]);
}

/// Unreadable inputs: a directory, and a path through a regular file, are
/// errors naming the path (as a missing file is, above).
#[test]
fn unreadable_inputs_are_named() {
    let dir = TempDir::new("unreadable");
    std::fs::create_dir(dir.path("a_directory.exr")).unwrap();
    std::fs::write(dir.path("file"), b"x").unwrap();
    for name in ["a_directory.exr", "file/stats.exr"] {
        let path = dir.path(name);
        let message = match read_stats(&path) {
            Err(e @ (Error::Io { .. } | Error::BadInput { .. })) => e.to_string(),
            other => panic!("{name}: {other:?}"),
        };
        eprintln!("read_stats of {name}: {message}");
        assert!(message.contains(name), "{message}");
    }
}

fn decode_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn png_preview_and_heatmap() {
    let dir = TempDir::new("png");
    // 0 → 0; 1 → t = 0.5 → sRGB 0.7354 → 188; NaN and negative → 0; +Inf → 255; 1e9 → 255.
    let img = RgbImage::from_planes(
        3,
        1,
        [
            vec![0.0, 1.0, f32::NAN],
            vec![-1.0, 1e9, f32::INFINITY],
            vec![1.0, 0.0, 1.0],
        ],
    );
    let path = dir.path("preview.png");
    write_png_preview(&path, &img).unwrap();
    let (w, h, data) = decode_png(&path);
    assert_eq!((w, h), (3, 1));
    assert_eq!(data, [0, 0, 188, 188, 255, 0, 0, 255, 188]);

    let heat = dir.path("heat.png");
    write_heatmap_png(&heat, 2, 2, &[0.0, 0.5, 1.0, f32::NAN], 0.5).unwrap();
    let (_, _, data) = decode_png(&heat);
    assert_eq!(&data[0..3], &[0, 0, 0]);
    assert_eq!(&data[3..6], &[255, 255, 255]);
    assert_eq!(&data[6..9], &[255, 255, 255]);
    assert_eq!(&data[9..12], &[255, 255, 255]);
    // Automatic range: the largest finite value is white.
    write_heatmap_png(&heat, 3, 1, &[0.0, 2.0, 4.0], 0.0).unwrap();
    let (_, _, data) = decode_png(&heat);
    assert_eq!(&data[6..9], &[255, 255, 255]);
    assert!(data[3..6].iter().map(|v| *v as u32).sum::<u32>() > 0);

    assert!(matches!(
        write_heatmap_png(&heat, 2, 2, &[0.0; 3], 1.0),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        write_png_preview(&dir.path("empty.png"), &RgbImage::new(0, 4)),
        Err(Error::InvalidArgument(_))
    ));
    assert_eq!(dir.entries(), ["heat.png", "preview.png"]);
}
