//! `mcdenoise bench` and `mcdenoise::bench`: the quality table on a tiny
//! scenes folder made from the committed fixtures, its JSON, skipped cases,
//! the error-estimate correlations, the synthetic frame and the timing run.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::Rng;
use mcdenoise::bench::{
    self, error_correlation, naive_correlation, synthetic, Note, QualityConfig, TimingConfig,
    TimingInput,
};
use mcdenoise::image::{Layer, RgbImage, StatsImage};
use mcdenoise::io;
use mcdenoise::methods::{self, Backend, DenoiseRequest, Method};
use mcdenoise::metrics;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// A fresh, empty temporary folder for one test.
fn tmpdir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mcdenoise-bench-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `<root>/<scene>/spp16.exr` and, if `reference`, `<root>/<scene>/reference.exr`
/// from the 64x64 fixtures.
fn fixture_scene(root: &Path, scene: &str, reference: bool) -> PathBuf {
    let dir = root.join(scene);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(fixture("dof_checker_64_spp16.exr"), dir.join("spp16.exr")).unwrap();
    if reference {
        std::fs::copy(fixture("dof_checker_64_ref.exr"), dir.join("reference.exr")).unwrap();
    }
    dir
}

fn run(cmd: &mut Command) -> (i32, String, String) {
    let o = cmd.output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The trimmed cells of the Markdown table row whose cells start with `prefix`.
fn table_row(md: &str, prefix: &[&str]) -> Option<Vec<String>> {
    md.lines()
        .filter(|l| l.starts_with('|'))
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect::<Vec<_>>()
        })
        .find(|cells| cells.len() >= prefix.len() && cells.iter().zip(prefix).all(|(c, p)| c == p))
}

// --- A small JSON reader: proves the output is valid JSON, and lets the tests
// --- look values up by key instead of by string position.

#[derive(Debug, Clone, PartialEq)]
enum J {
    Null,
    Bool(bool),
    Num(f64),
    Str(String),
    Arr(Vec<J>),
    Obj(Vec<(String, J)>),
}

impl J {
    fn get(&self, key: &str) -> &J {
        match self {
            J::Obj(f) => {
                &f.iter()
                    .find(|(k, _)| k == key)
                    .unwrap_or_else(|| panic!("no key {key:?} in {self:?}"))
                    .1
            }
            _ => panic!("not an object: {self:?}"),
        }
    }
    fn arr(&self) -> &[J] {
        match self {
            J::Arr(a) => a,
            _ => panic!("not an array: {self:?}"),
        }
    }
    fn num(&self) -> f64 {
        match self {
            J::Num(v) => *v,
            _ => panic!("not a number: {self:?}"),
        }
    }
    fn str(&self) -> &str {
        match self {
            J::Str(s) => s,
            _ => panic!("not a string: {self:?}"),
        }
    }
}

fn parse_json(text: &str) -> J {
    let b = text.as_bytes();
    let mut i = 0;
    let v = json_value(b, &mut i);
    skip_ws(b, &mut i);
    assert_eq!(i, b.len(), "trailing characters after the JSON value");
    v
}

fn skip_ws(b: &[u8], i: &mut usize) {
    while *i < b.len() && b" \t\r\n".contains(&b[*i]) {
        *i += 1;
    }
}

fn expect(b: &[u8], i: &mut usize, c: u8) {
    skip_ws(b, i);
    assert_eq!(b.get(*i), Some(&c), "expected {:?} at byte {i}", c as char);
    *i += 1;
}

fn json_string(b: &[u8], i: &mut usize) -> String {
    expect(b, i, b'"');
    let mut out = Vec::new();
    loop {
        let c = *b.get(*i).expect("unterminated string");
        *i += 1;
        match c {
            b'"' => break,
            b'\\' => {
                let e = b[*i];
                *i += 1;
                match e {
                    b'"' | b'\\' | b'/' => out.push(e),
                    b'n' => out.push(b'\n'),
                    b'r' => out.push(b'\r'),
                    b't' => out.push(b'\t'),
                    b'b' => out.push(8),
                    b'f' => out.push(12),
                    b'u' => {
                        let hex = std::str::from_utf8(&b[*i..*i + 4]).unwrap();
                        let ch = char::from_u32(u32::from_str_radix(hex, 16).unwrap()).unwrap();
                        out.extend(ch.to_string().as_bytes());
                        *i += 4;
                    }
                    _ => panic!("bad escape \\{}", e as char),
                }
            }
            c if c < 0x20 => panic!("raw control character in a string"),
            c => out.push(c),
        }
    }
    String::from_utf8(out).unwrap()
}

fn json_value(b: &[u8], i: &mut usize) -> J {
    skip_ws(b, i);
    match b.get(*i).copied().expect("unexpected end of JSON") {
        b'{' => {
            *i += 1;
            let mut fields = Vec::new();
            skip_ws(b, i);
            if b[*i] == b'}' {
                *i += 1;
                return J::Obj(fields);
            }
            loop {
                let k = json_string(b, i);
                expect(b, i, b':');
                fields.push((k, json_value(b, i)));
                skip_ws(b, i);
                match b[*i] {
                    b',' => *i += 1,
                    b'}' => {
                        *i += 1;
                        return J::Obj(fields);
                    }
                    c => panic!("expected , or }} at byte {i}, got {:?}", c as char),
                }
            }
        }
        b'[' => {
            *i += 1;
            let mut items = Vec::new();
            skip_ws(b, i);
            if b[*i] == b']' {
                *i += 1;
                return J::Arr(items);
            }
            loop {
                items.push(json_value(b, i));
                skip_ws(b, i);
                match b[*i] {
                    b',' => *i += 1,
                    b']' => {
                        *i += 1;
                        return J::Arr(items);
                    }
                    c => panic!("expected , or ] at byte {i}, got {:?}", c as char),
                }
            }
        }
        b'"' => J::Str(json_string(b, i)),
        b't' | b'f' | b'n' => {
            for (word, v) in [
                ("true", J::Bool(true)),
                ("false", J::Bool(false)),
                ("null", J::Null),
            ] {
                if b[*i..].starts_with(word.as_bytes()) {
                    *i += word.len();
                    return v;
                }
            }
            panic!("bad literal at byte {i}");
        }
        _ => {
            let start = *i;
            while *i < b.len() && b"+-0123456789.eE".contains(&b[*i]) {
                *i += 1;
            }
            let s = std::str::from_utf8(&b[start..*i]).unwrap();
            // JSON numbers: no leading '+', no bare '.', digits after the point.
            assert!(
                !s.starts_with('+')
                    && !s.starts_with('.')
                    && !s.contains(".e")
                    && !s.ends_with('.'),
                "not a JSON number: {s:?}"
            );
            J::Num(s.parse().unwrap_or_else(|_| panic!("not a number: {s:?}")))
        }
    }
}

fn ignore(_: Note) {}

/// The colour of a CPU `none` reconstruction (the sanitised input).
fn none_cpu(img: &StatsImage) -> RgbImage {
    let mut req = DenoiseRequest::new(Method::None);
    req.backend = Backend::Cpu;
    methods::denoise(None, img, &req).unwrap().color
}

#[test]
fn quality_table_json_and_markdown_from_the_cli() {
    let root = tmpdir("quality");
    let scenes = root.join("scenes");
    let dir = fixture_scene(&scenes, "tiny", true);
    let (json_path, md_path) = (root.join("q.json"), root.join("q.md"));
    let (code, out, err) = run(Command::new(env!("CARGO_BIN_EXE_mcdenoise")).args([
        "bench".as_ref(),
        "--quality".as_ref(),
        scenes.as_os_str(),
        "--methods".as_ref(),
        "none".as_ref(),
        "--json".as_ref(),
        json_path.as_os_str(),
        "--markdown".as_ref(),
        md_path.as_os_str(),
    ]));
    assert_eq!(code, 0, "stdout:\n{out}\nstderr:\n{err}");

    // The table: header, the input row and the none row.
    let header = table_row(&out, &["scene"]).expect("table header");
    assert_eq!(
        header,
        [
            "scene",
            "spp",
            "method",
            "backend",
            "rMSE",
            "relMSE",
            "PSNR",
            "SSIM",
            "wall s",
            "GPU ms",
            "GPU ms/MP",
            "err corr",
            "naive corr",
            "map share"
        ]
    );
    let input_row = table_row(&out, &["tiny", "16", "input"]).unwrap_or_else(|| panic!("{out}"));
    let none_row =
        table_row(&out, &["tiny", "16", "none", "gpu"]).unwrap_or_else(|| panic!("{out}"));

    // rMSE of the input row = metrics::compare of the same two files.
    let input = io::read_rgb(&dir.join("spp16.exr")).unwrap();
    let reference = io::read_rgb(&dir.join("reference.exr")).unwrap();
    let expected = metrics::compare(&input, &reference).unwrap();
    let cell: f64 = input_row[4].parse().unwrap();
    // Five decimals in the table.
    assert!(
        (cell - expected.rmse).abs() <= 5.01e-6,
        "{cell} vs {}",
        expected.rmse
    );
    let wall: f64 = none_row[8].parse().expect("wall seconds of the none row");
    assert!(wall > 0.0);
    // none exports the variance of the mean as its error, and a sample map
    // of 4 spp per pixel: both scored.
    let corr: f64 = none_row[11].parse().expect("err corr of the none row");
    assert!((-1.0..=1.0).contains(&corr), "{corr}");
    assert!(none_row[13].ends_with('%'), "{none_row:?}");
    assert!(
        out.contains("none (gpu), spp 16:"),
        "summary line missing:\n{out}"
    );

    // JSON: valid, with the expected keys, and the exact metric values.
    let text = std::fs::read_to_string(&json_path).unwrap();
    assert_eq!(text.matches('{').count(), text.matches('}').count());
    assert_eq!(text.matches('[').count(), text.matches(']').count());
    for key in [
        "\"kind\"",
        "\"rows\"",
        "\"summary\"",
        "\"rmse\"",
        "\"err_corr\"",
        "\"naive_corr\"",
    ] {
        assert!(text.contains(key), "{key} missing from the JSON");
    }
    let j = parse_json(&text);
    assert_eq!(j.get("kind").str(), "quality");
    let rows = j.get("rows").arr();
    assert_eq!(rows.len(), 2, "{rows:?}");
    let row = |case: &str| rows.iter().find(|r| r.get("case").str() == case).unwrap();
    let input_json = row("input.tiny.spp16");
    assert_eq!(input_json.get("rmse").num(), expected.rmse);
    assert_eq!(input_json.get("relmse").num(), expected.relmse);
    assert_eq!(input_json.get("ssim").num(), expected.ssim);
    assert_eq!(input_json.get("backend"), &J::Null);
    let none_json = row("none.tiny.spp16");
    assert_eq!(none_json.get("backend").str(), "gpu");
    assert!(none_json.get("err_corr").num().abs() <= 1.0);
    let share = none_json.get("map_share").num();
    assert!((0.0..=1.0).contains(&share), "{share}");
    // The GPU's sanitised colour agrees with the CPU twin's (spec §0.3 tolerance).
    let img = io::read_stats(&dir.join("spp16.exr")).unwrap();
    let cpu = metrics::compare(&none_cpu(&img), &reference).unwrap().rmse;
    let gpu = none_json.get("rmse").num();
    assert!((gpu - cpu).abs() <= 1e-3 * cpu, "gpu {gpu} vs cpu {cpu}");
    let summary = j.get("summary").arr();
    assert_eq!(summary.len(), 1);
    assert_eq!(summary[0].get("scenes").num(), 1.0);

    // The Markdown file is what was printed.
    assert_eq!(std::fs::read_to_string(&md_path).unwrap(), out);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn quality_rows_match_metrics_and_bad_files_are_skipped() {
    let root = tmpdir("skips");
    fixture_scene(&root, "tiny", true);
    fixture_scene(&root, "noref", false);
    let broken = fixture_scene(&root, "broken", true);
    std::fs::write(broken.join("spp16.exr"), b"not an exr").unwrap();
    std::fs::create_dir_all(root.join("empty")).unwrap(); // no sppN.exr: not a scene

    let mut notes = Vec::new();
    let report = bench::run_quality(
        None,
        &QualityConfig {
            dir: root.clone(),
            methods: vec![Method::None],
            backends: vec![Backend::Cpu],
            filter: None,
            stages: Default::default(),
        },
        &mut |n| {
            if let Note::Warning(w) = n {
                notes.push(w.to_string())
            }
        },
    )
    .unwrap();

    // Only the good scene has rows; the CPU none row scores exactly the
    // sanitised colour, the input row exactly the file's colour.
    let cases: Vec<&str> = report.rows.iter().map(|r| r.case.as_str()).collect();
    assert_eq!(cases, ["input.tiny.spp16", "none.tiny.spp16"]);
    let dir = root.join("tiny");
    let img = io::read_stats(&dir.join("spp16.exr")).unwrap();
    let reference = io::read_rgb(&dir.join("reference.exr")).unwrap();
    let input = io::read_rgb(&dir.join("spp16.exr")).unwrap();
    assert_eq!(
        report.rows[0].metrics,
        metrics::compare(&input, &reference).unwrap()
    );
    assert_eq!(
        report.rows[1].metrics,
        metrics::compare(&none_cpu(&img), &reference).unwrap()
    );
    assert_eq!(report.rows[1].gpu_ms, None);
    assert!(report.rows[1].wall_s.unwrap() >= 0.0);

    // One warning per bad scene, naming the file; also passed to the callback.
    assert_eq!(report.warnings.len(), 2, "{:#?}", report.warnings);
    assert_eq!(notes, report.warnings);
    let find = |what: &str| report.warnings.iter().find(|w| w.contains(what)).cloned();
    let broken_msg = find("broken").expect("warning for the broken scene");
    assert!(
        broken_msg.contains(&format!("broken{}spp16.exr", std::path::MAIN_SEPARATOR)),
        "{broken_msg}"
    );
    let noref_msg = find("noref").expect("warning for the scene without reference");
    assert!(noref_msg.contains("reference.exr"), "{noref_msg}");
    let md = report.to_markdown();
    assert!(md.contains("Warnings:") && md.contains(&broken_msg), "{md}");

    // The filter: `spp4` selects nothing; `none.tiny` selects the none case
    // and keeps its input row.
    let filtered = |f: &str| {
        bench::run_quality(
            None,
            &QualityConfig {
                dir: root.join("tiny"),
                methods: vec![Method::None],
                backends: vec![Backend::Cpu],
                filter: Some(f.into()),
                stages: Default::default(),
            },
            &mut ignore,
        )
        .unwrap()
        .rows
        .len()
    };
    assert_eq!(filtered("spp4"), 0);
    assert_eq!(filtered("none.tiny"), 2);
    assert_eq!(filtered("input.tiny"), 1);
    let _ = std::fs::remove_dir_all(&root);
}

/// A 256x256 reference and an output with spatially varying noise.
fn noisy_pair(rng: &mut Rng) -> (RgbImage, RgbImage) {
    let (w, h) = (256, 256);
    let reference = RgbImage::from_planes(
        w,
        h,
        std::array::from_fn(|c| {
            (0..w * h)
                .map(|i| 0.5 + 0.1 * c as f32 + (i % w) as f32 / w as f32)
                .collect()
        }),
    );
    let mut out = reference.clone();
    for p in &mut out.planes {
        for (i, v) in p.iter_mut().enumerate() {
            let amp = 0.02
                + 0.3 * ((i % w) as f64 / 40.0).sin().powi(2) * ((i / w) as f64 / 90.0).cos().abs();
            *v += (amp * rng.normal()) as f32;
        }
    }
    (reference, out)
}

#[test]
fn error_correlation_is_one_for_the_truth_and_zero_for_noise() {
    let mut rng = Rng(0x1234_5678_9abc_def1);
    let (reference, out) = noisy_pair(&mut rng);
    let truth = RgbImage::from_planes(
        out.width,
        out.height,
        std::array::from_fn(|c| {
            out.planes[c]
                .iter()
                .zip(&reference.planes[c])
                .map(|(x, r)| (x - r) * (x - r))
                .collect()
        }),
    );
    let c = error_correlation(&truth, &out, &reference);
    assert!(
        (c - 1.0).abs() < 1e-9,
        "correlation with the true error: {c}"
    );
    // Scaling the estimate does not change a correlation.
    let mut scaled = truth.clone();
    scaled.planes.iter_mut().flatten().for_each(|v| *v *= 7.0);
    assert!((error_correlation(&scaled, &out, &reference) - 1.0).abs() < 1e-9);

    let random = RgbImage::from_planes(
        out.width,
        out.height,
        std::array::from_fn(|_| {
            (0..out.width * out.height)
                .map(|_| rng.uniform() as f32)
                .collect()
        }),
    );
    let c = error_correlation(&random, &out, &reference);
    // 1024 tiles: the standard deviation of an independent correlation is ≈ 0.03.
    assert!(c.abs() < 0.15, "correlation with an independent map: {c}");

    // A constant estimate carries no information: NaN, never a good score.
    let flat = RgbImage::from_planes(
        out.width,
        out.height,
        std::array::from_fn(|_| vec![1.0; 256 * 256]),
    );
    assert!(error_correlation(&flat, &out, &reference).is_nan());
}

#[test]
fn naive_correlation_of_the_synthetic_input_is_high() {
    // The input's own variance predicts the input's own error well.
    let s = synthetic(128, 128, 16, 5);
    let colour = s.stats.get(Layer::Color).unwrap();
    let input = RgbImage::from_planes(128, 128, std::array::from_fn(|c| colour[c].clone()));
    let c = naive_correlation(&s.stats, &input, &s.clean).unwrap();
    assert!(c > 0.5, "naive correlation on the synthetic frame: {c}");
    let mut no_var = s.stats.clone();
    no_var.remove(Layer::ColorVariance);
    assert_eq!(naive_correlation(&no_var, &input, &s.clean), None);
}

#[test]
fn synthetic_frame_is_deterministic() {
    let a = synthetic(48, 40, 16, 7);
    let b = synthetic(48, 40, 16, 7);
    assert_eq!(a.stats, b.stats);
    assert_eq!(a.clean, b.clean);
    assert_ne!(a.stats, synthetic(48, 40, 16, 8).stats);
    for l in [
        Layer::Color,
        Layer::ColorVariance,
        Layer::Albedo,
        Layer::AlbedoVariance,
        Layer::Normal,
        Layer::NormalVariance,
        Layer::Depth,
        Layer::DepthVariance,
        Layer::Position,
        Layer::PositionVariance,
        Layer::PositionCovariance,
        Layer::Spp,
    ] {
        let planes = a
            .stats
            .get(l)
            .unwrap_or_else(|| panic!("{} missing", l.name()));
        assert!(
            planes.iter().flatten().all(|v| v.is_finite()),
            "{}",
            l.name()
        );
    }
    assert!(a.stats.get(Layer::Spp).unwrap()[0]
        .iter()
        .all(|&n| n == 16.0));
    // The frame is a valid input: the library accepts it as-is.
    assert!(
        io::validate(&a.stats).is_empty(),
        "{:?}",
        io::validate(&a.stats)
    );
}

#[test]
fn synthetic_variance_layers_match_the_noise() {
    let (w, h) = (128, 128);
    let noisy = synthetic(w, h, 16, 3);
    // At 2^30 spp the noise (σ/32768) is negligible: the expected features.
    let exact = synthetic(w, h, 1 << 30, 3);
    for (mean, var) in [
        (Layer::Color, Layer::ColorVariance),
        (Layer::Albedo, Layer::AlbedoVariance),
        (Layer::Normal, Layer::NormalVariance),
        (Layer::Depth, Layer::DepthVariance),
        (Layer::Position, Layer::PositionVariance),
    ] {
        let x = noisy.stats.get(mean).unwrap();
        let e = exact.stats.get(mean).unwrap();
        let v = noisy.stats.get(var).unwrap();
        for c in 0..x.len() {
            let empirical = x[c]
                .iter()
                .zip(&e[c])
                .map(|(a, b)| (*a as f64 - *b as f64).powi(2))
                .sum::<f64>()
                / (w * h) as f64;
            let layer = v[c].iter().map(|&s| s as f64).sum::<f64>() / (w * h) as f64;
            let ratio = layer / empirical;
            assert!(
                (0.85..=1.15).contains(&ratio),
                "{} channel {c}: variance layer {layer:.3e} vs empirical {empirical:.3e}",
                mean.name()
            );
        }
    }
    // The clean colour is the expected colour too.
    let e = exact.stats.get(Layer::Color).unwrap();
    for c in 0..3 {
        for (a, b) in e[c].iter().zip(&noisy.clean.planes[c]) {
            assert!((a - b).abs() <= 1e-4 * (b.abs() + 1.0));
        }
    }
}

#[test]
fn timing_benchmark_reports_cases_and_json() {
    let report = bench::run_timing(
        None,
        &TimingConfig {
            methods: vec![Method::None],
            backends: vec![Backend::Cpu],
            input: TimingInput::Synthetic,
            size: Some((32, 24)),
            runs: 2,
            filter: Some("synthetic".into()),
            stages: Default::default(),
        },
        &mut ignore,
    )
    .unwrap();
    assert_eq!(report.rows.len(), 1);
    let r = &report.rows[0];
    assert_eq!(r.case, "none.synthetic.32x24");
    assert_eq!(r.wall_ms.len(), 2);
    assert!(r.median_wall_ms > 0.0 && r.ms_per_megapixel > r.median_wall_ms);
    let md = report.to_markdown();
    assert!(md.contains("| none.synthetic.32x24 |"), "{md}");
    let j = parse_json(&report.to_json());
    assert_eq!(j.get("kind").str(), "timing");
    let row = &j.get("rows").arr()[0];
    assert_eq!(row.get("case").str(), "none.synthetic.32x24");
    assert_eq!(row.get("wall_ms").arr().len(), 2);
    for key in ["median_wall_ms", "ms_per_megapixel", "gpu_ms", "kernels"] {
        row.get(key);
    }

    // A file input: named after its folder and stem, centre-cropped.
    let root = tmpdir("timing");
    let dir = fixture_scene(&root, "tiny", false);
    let report = bench::run_timing(
        None,
        &TimingConfig {
            methods: vec![Method::None],
            backends: vec![Backend::Cpu],
            input: TimingInput::File(dir.join("spp16.exr")),
            size: Some((16, 8)),
            runs: 1,
            filter: None,
            stages: Default::default(),
        },
        &mut ignore,
    )
    .unwrap();
    assert_eq!(report.rows[0].case, "none.tiny-spp16.16x8");
    let err = bench::run_timing(
        None,
        &TimingConfig {
            methods: vec![Method::None],
            backends: vec![Backend::Cpu],
            input: TimingInput::File(dir.join("spp16.exr")),
            size: Some((65, 8)),
            runs: 1,
            filter: None,
            stages: Default::default(),
        },
        &mut ignore,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("spp16.exr") && err.contains("65x8"), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn timing_benchmark_from_the_cli_on_the_gpu() {
    let root = tmpdir("timing-cli");
    let json = root.join("t.json");
    let (code, out, err) = run(Command::new(env!("CARGO_BIN_EXE_mcdenoise")).args([
        "bench".as_ref(),
        "--size".as_ref(),
        "40x24".as_ref(),
        "--runs".as_ref(),
        "1".as_ref(),
        "--methods".as_ref(),
        "none".as_ref(),
        "--json".as_ref(),
        json.as_os_str(),
    ]));
    assert_eq!(code, 0, "stdout:\n{out}\nstderr:\n{err}");
    assert!(
        table_row(&out, &["none.synthetic.40x24", "gpu"]).is_some(),
        "{out}"
    );
    let j = parse_json(&std::fs::read_to_string(&json).unwrap());
    assert_eq!(j.get("rows").arr()[0].get("backend").str(), "gpu");
    assert!(!j.get("device").str().is_empty());

    // Nothing selected: an error naming the filter.
    let (code, _, err) = run(Command::new(env!("CARGO_BIN_EXE_mcdenoise")).args([
        "bench",
        "--size",
        "8x8",
        "--runs",
        "1",
        "--filter",
        "no-such-case",
    ]));
    assert_eq!(code, 2);
    assert!(err.contains("no-such-case"), "{err}");
    // A bad size is refused by the argument parser.
    let (code, _, err) =
        run(Command::new(env!("CARGO_BIN_EXE_mcdenoise")).args(["bench", "--size", "12"]));
    assert_ne!(code, 0);
    assert!(err.contains("WIDTHxHEIGHT"), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}

/// `bench --temporal lp-smooth` times one frame's whole work of the
/// two-way filter: the filter runs twice per call (in frame order and in
/// reverse order) and `lp_smooth` once.
#[test]
fn timing_benchmark_of_the_two_way_filter() {
    let (code, out, err) = run(Command::new(env!("CARGO_BIN_EXE_mcdenoise")).args([
        "bench",
        "--size",
        "16x16",
        "--runs",
        "2",
        "--methods",
        "none",
        "--temporal",
        "lp-smooth",
    ]));
    assert_eq!(code, 0, "stdout:\n{out}\nstderr:\n{err}");
    let case = "none.synthetic.16x16";
    let dispatches = |kernel: &str| {
        let row =
            table_row(&out, &[case, "gpu", kernel]).unwrap_or_else(|| panic!("{kernel}: {out}"));
        row[4].clone()
    };
    assert_eq!(dispatches("lp_temporal"), "2", "{out}");
    assert_eq!(dispatches("lp_smooth"), "1", "{out}");
}
