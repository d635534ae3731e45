//! Output of the benchmark reports: Markdown tables and JSON.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use serde::Serialize;

use super::backend_name;
use super::quality::QualityReport;
use super::timing::{TimingReport, TimingRow};
use crate::error::{Error, Result};
use crate::io;

impl QualityReport {
    /// The report as Markdown: the table, the summary lines, and the skipped
    /// cases. The `err corr` / `naive corr` columns appear when any row has
    /// an error estimate (blank in the rows without one).
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "Quality benchmark: {}", self.dir.display());
        if let Some(d) = &self.device {
            let _ = writeln!(s, "Device: {d}");
        }
        if !self.settings.is_empty() {
            let _ = writeln!(s, "Settings: {}", self.settings);
        }
        s.push('\n');
        let corr = self.rows.iter().any(|r| r.err_corr.is_some());
        let centres = self.rows.iter().any(|r| r.centres.is_some());
        let mut header = vec![
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
        ];
        let mut align = vec![
            "---", "---:", "---", "---", "---:", "---:", "---:", "---:", "---:", "---:", "---:",
        ];
        if centres {
            header.push("centres");
            align.push("---:");
        }
        if corr {
            header.extend(["err corr", "naive corr", "map share"]);
            align.extend(["---:", "---:"]);
        }
        let mut rows: Vec<Vec<String>> = vec![
            header.iter().map(|h| h.to_string()).collect(),
            align.iter().map(|a| a.to_string()).collect(),
        ];
        for r in &self.rows {
            let mut cells = vec![
                r.scene.clone(),
                r.spp.to_string(),
                r.method.clone(),
                r.backend.map_or("-".into(), |b| backend_name(b).into()),
                fmt_error(r.metrics.rmse),
                fmt_error(r.metrics.relmse),
                fmt_fixed(r.metrics.psnr, 2),
                fmt_fixed(r.metrics.ssim, 4),
                r.wall_s.map_or(String::new(), |t| format!("{t:.3}")),
                r.gpu_ms.map_or(String::new(), |t| format!("{t:.2}")),
                r.gpu_ms_per_mp.map_or(String::new(), |t| format!("{t:.0}")),
            ];
            if centres {
                cells.push(
                    r.centres
                        .map_or(String::new(), |c| format!("{:.2}%", 100.0 * c)),
                );
            }
            if corr {
                cells.push(r.err_corr.map_or(String::new(), |c| fmt_fixed(c, 3)));
                cells.push(r.naive_corr.map_or(String::new(), |c| fmt_fixed(c, 3)));
                cells.push(
                    r.map_share
                        .map_or(String::new(), |c| format!("{:.1}%", 100.0 * c)),
                );
            }
            rows.push(cells);
        }
        s.push_str(&markdown_table(&rows));
        let summary = self.summary();
        if !summary.is_empty() {
            s.push_str(
                "\nMean over scenes of rMSE(input) / rMSE(method) (> 1: better than the input):\n",
            );
            for q in &summary {
                let _ = write!(
                    s,
                    "- {} ({}), spp {}: {:.2} over {} scene{}",
                    q.method,
                    backend_name(q.backend),
                    q.spp,
                    q.mean_rmse_ratio,
                    q.scenes,
                    if q.scenes == 1 { "" } else { "s" }
                );
                if let Some(c) = q.mean_err_corr {
                    let _ = write!(s, "; mean err corr {c:.3}");
                }
                s.push('\n');
            }
        }
        let vs = self.vs_wlr();
        if !vs.is_empty() {
            s.push_str("\nAgainst WLR (same scene, spp and backend):\n\n");
            let mut rows: Vec<Vec<String>> = vec![
                [
                    "scene",
                    "spp",
                    "method",
                    "backend",
                    "rMSE / WLR",
                    "WLR GPU time / GPU time",
                ]
                .map(String::from)
                .to_vec(),
                ["---", "---:", "---", "---", "---:", "---:"]
                    .map(String::from)
                    .to_vec(),
            ];
            for c in &vs {
                rows.push(vec![
                    c.scene.clone(),
                    c.spp.to_string(),
                    c.method.clone(),
                    backend_name(c.backend).into(),
                    format!("{:.3}", c.rmse_ratio),
                    c.speedup.map_or(String::new(), |x| format!("{x:.1}")),
                ]);
            }
            s.push_str(&markdown_table(&rows));
        }
        push_warnings(&mut s, &self.warnings);
        s
    }

    /// The report as JSON: `{"kind": "quality", "dir", "device", "rows": [...],
    /// "summary": [...], "vs_wlr": [...], "warnings": [...]}`.
    /// Each row has `case scene spp method backend rmse relmse psnr ssim
    /// wall_s gpu_ms err_corr naive_corr gpu_ms_per_mp centres` (`null` where absent or
    /// non-finite); numbers at full precision. Pretty-printed by `serde_json`,
    /// with a final newline.
    pub fn to_json(&self) -> String {
        let summary = self.summary();
        let vs_wlr = self.vs_wlr();
        to_json_text(&QualityJson {
            kind: "quality",
            dir: self.dir.display().to_string(),
            device: self.device.as_deref(),
            settings: &self.settings,
            rows: self
                .rows
                .iter()
                .map(|r| QualityRowJson {
                    case: &r.case,
                    scene: &r.scene,
                    spp: r.spp,
                    method: &r.method,
                    backend: r.backend.map(backend_name),
                    rmse: r.metrics.rmse,
                    relmse: r.metrics.relmse,
                    psnr: r.metrics.psnr,
                    ssim: r.metrics.ssim,
                    wall_s: r.wall_s,
                    gpu_ms: r.gpu_ms,
                    err_corr: r.err_corr,
                    naive_corr: r.naive_corr,
                    map_share: r.map_share,
                    gpu_ms_per_mp: r.gpu_ms_per_mp,
                    centres: r.centres,
                })
                .collect(),
            summary: summary
                .iter()
                .map(|q| QualitySummaryJson {
                    method: &q.method,
                    backend: backend_name(q.backend),
                    spp: q.spp,
                    scenes: q.scenes,
                    mean_rmse_ratio: q.mean_rmse_ratio,
                    mean_err_corr: q.mean_err_corr,
                })
                .collect(),
            vs_wlr: vs_wlr
                .iter()
                .map(|c| VsWlrJson {
                    scene: &c.scene,
                    spp: c.spp,
                    method: &c.method,
                    backend: backend_name(c.backend),
                    rmse_ratio: c.rmse_ratio,
                    speedup: c.speedup,
                })
                .collect(),
            warnings: &self.warnings,
        })
    }
}

impl TimingReport {
    /// The report as Markdown: one row per case, then the per-kernel GPU times.
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Timing benchmark: {} ({} timed run{} per case after 1 warm-up)",
            self.source,
            self.runs,
            if self.runs == 1 { "" } else { "s" }
        );
        if let Some(d) = &self.device {
            let _ = writeln!(s, "Device: {d}");
        }
        if !self.settings.is_empty() {
            let _ = writeln!(s, "Settings: {}", self.settings);
        }
        s.push('\n');
        if let Some(p) = &self.peak {
            let _ = writeln!(s, "Device limits ({} runs after a warm-up):\n", p.runs);
            s.push_str(&p.to_markdown());
            s.push('\n');
        }
        let mut rows: Vec<Vec<String>> = vec![
            [
                "case",
                "backend",
                "median wall ms",
                "ms/MP",
                "GPU ms",
                "peak device MB",
                "peak RSS MB",
            ]
            .map(String::from)
            .to_vec(),
            ["---", "---", "---:", "---:", "---:", "---:", "---:"]
                .map(String::from)
                .to_vec(),
        ];
        for r in &self.rows {
            rows.push(vec![
                r.case.clone(),
                backend_name(r.backend).into(),
                format!("{:.2}", r.median_wall_ms),
                format!("{:.2}", r.ms_per_megapixel),
                r.gpu_ms.map_or(String::new(), |t| format!("{t:.2}")),
                r.device_mb.map_or(String::new(), |m| format!("{m:.0}")),
                r.rss_mb.map_or(String::new(), |m| format!("{m:.0}")),
            ]);
        }
        s.push_str(&markdown_table(&rows));
        let with_kernels: Vec<&TimingRow> =
            self.rows.iter().filter(|r| !r.kernels.is_empty()).collect();
        s.push('\n');
        if with_kernels.is_empty() {
            s.push_str("Per-kernel GPU times: none reported by these cases.\n");
        } else {
            s.push_str(
                "Per-kernel GPU times (median over the runs); GFLOP/s from each kernel's \
                 counted flops (`src/kernels/<name>.rs`), and their fraction of the device's \
                 FMA peak for the kernel's precision (median of `peak_fma`); GB/s from its \
                 compulsory traffic (each bound range read or written once per dispatch), and \
                 its fraction of the copy bandwidth (median of `peak_copy`):\n\n",
            );
            let mut rows: Vec<Vec<String>> = vec![
                [
                    "case",
                    "backend",
                    "kernel",
                    "GPU ms",
                    "dispatches",
                    "GFLOP/s",
                    "% of peak",
                    "GB/s",
                    "% of copy",
                ]
                .map(String::from)
                .to_vec(),
                [
                    "---", "---", "---", "---:", "---:", "---:", "---:", "---:", "---:",
                ]
                .map(String::from)
                .to_vec(),
            ];
            for r in with_kernels {
                for k in &r.kernels {
                    let fraction = self
                        .peak
                        .as_ref()
                        .and_then(|p| p.flops_for(&k.kernel))
                        .map_or(String::new(), |p| format!("{:.1}", 100.0 * k.gflops / p));
                    let copy = self.peak.as_ref().map_or(String::new(), |p| {
                        format!("{:.1}", 100.0 * k.gbs / p.copy.median)
                    });
                    rows.push(vec![
                        r.case.clone(),
                        backend_name(r.backend).into(),
                        k.kernel.clone(),
                        format!("{:.3}", k.ms),
                        k.dispatches.to_string(),
                        format!("{:.2}", k.gflops),
                        fraction,
                        format!("{:.2}", k.gbs),
                        copy,
                    ]);
                }
            }
            s.push_str(&markdown_table(&rows));
        }
        push_warnings(&mut s, &self.warnings);
        s
    }

    /// The report as JSON: `{"kind": "timing", "device", "inputs", "source",
    /// "runs", "peak", "rows": [...], "warnings"}`;
    /// `peak` is `{runs, fma_f32, fma_f64, copy}` with `{min, median, max}`
    /// each (GFLOP/s, GB/s) or `null`; each row has `case method backend
    /// width height wall_ms median_wall_ms ms_per_megapixel gpu_ms device_mb
    /// rss_mb kernels`
    /// and each kernel `kernel gpu_ms dispatches gflops gbs` (`null` where
    /// absent or non-finite). Pretty-printed by
    /// `serde_json`, with a final newline.
    pub fn to_json(&self) -> String {
        to_json_text(&TimingJson {
            kind: "timing",
            device: self.device.as_deref(),
            settings: &self.settings,
            inputs: &self.inputs,
            source: &self.source,
            runs: self.runs,
            peak: self.peak.as_ref(),
            rows: self
                .rows
                .iter()
                .map(|r| TimingRowJson {
                    case: &r.case,
                    method: r.method.name(),
                    backend: backend_name(r.backend),
                    width: r.width,
                    height: r.height,
                    wall_ms: &r.wall_ms,
                    median_wall_ms: r.median_wall_ms,
                    ms_per_megapixel: r.ms_per_megapixel,
                    gpu_ms: r.gpu_ms,
                    device_mb: r.device_mb,
                    rss_mb: r.rss_mb,
                    kernels: r
                        .kernels
                        .iter()
                        .map(|k| KernelJson {
                            kernel: &k.kernel,
                            gpu_ms: k.ms,
                            dispatches: k.dispatches,
                            gflops: k.gflops,
                            gbs: k.gbs,
                        })
                        .collect(),
                })
                .collect(),
            warnings: &self.warnings,
        })
    }
}

/// Writes `text` to `path` atomically ([`io::write_atomic`]).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    io::write_atomic(path, |w| {
        w.write_all(text.as_bytes()).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// An error metric: 5 decimals (as in `BASELINES.md`) down to 0.001, then
/// 3 significant digits in scientific notation.
fn fmt_error(v: f64) -> String {
    if !v.is_finite() {
        format!("{v}")
    } else if v == 0.0 || v.abs() >= 1e-3 {
        format!("{v:.5}")
    } else {
        format!("{v:.2e}")
    }
}

fn fmt_fixed(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        format!("{v}")
    }
}

/// A Markdown table from rows of cells (header, alignment row, body), padded
/// so the columns line up in a terminal.
pub(super) fn markdown_table(rows: &[Vec<String>]) -> String {
    let cols = rows.iter().map(|r| r.len()).max().unwrap_or(0);
    let width: Vec<usize> = (0..cols)
        .map(|c| {
            rows.iter()
                .filter_map(|r| r.get(c))
                .map(|s| s.chars().count())
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut s = String::new();
    for (i, r) in rows.iter().enumerate() {
        s.push('|');
        for (c, w) in width.iter().enumerate() {
            let cell = r.get(c).map(String::as_str).unwrap_or("");
            if i == 1 {
                // The alignment row: dashes to the column width, keep the colon.
                let colon = cell.ends_with(':');
                let dashes = "-".repeat(w.saturating_sub(colon as usize).max(3));
                let _ = write!(s, " {dashes}{} |", if colon { ":" } else { "" });
            } else {
                let right = rows
                    .get(1)
                    .and_then(|a| a.get(c))
                    .is_some_and(|a| a.ends_with(':'));
                if right {
                    let _ = write!(s, " {cell:>w$} |");
                } else {
                    let _ = write!(s, " {cell:<w$} |");
                }
            }
        }
        s.push('\n');
    }
    s
}

// The JSON documents, field for field in the order they are written. They
// borrow from the reports; the report structs themselves stay free of serde.
// Every `f64` goes through serde_json, which writes NaN and ±∞ as `null`
// (as the hand-written writer did); `None` is `null` too.

/// Pretty-prints `doc` (two-space indents) with a final newline.
fn to_json_text(doc: &impl Serialize) -> String {
    let mut s = serde_json::to_string_pretty(doc)
        .expect("the report documents hold only strings, numbers and lists");
    s.push('\n');
    s
}

/// [`QualityReport::to_json`].
#[derive(Serialize)]
struct QualityJson<'a> {
    kind: &'static str,
    dir: String,
    device: Option<&'a str>,
    settings: &'a str,
    rows: Vec<QualityRowJson<'a>>,
    summary: Vec<QualitySummaryJson<'a>>,
    vs_wlr: Vec<VsWlrJson<'a>>,
    warnings: &'a [String],
}

/// A [`QualityRow`](super::QualityRow), its metrics inlined.
#[derive(Serialize)]
struct QualityRowJson<'a> {
    case: &'a str,
    scene: &'a str,
    spp: u32,
    method: &'a str,
    backend: Option<&'static str>,
    rmse: f64,
    relmse: f64,
    psnr: f64,
    ssim: f64,
    wall_s: Option<f64>,
    gpu_ms: Option<f64>,
    err_corr: Option<f64>,
    naive_corr: Option<f64>,
    map_share: Option<f64>,
    gpu_ms_per_mp: Option<f64>,
    centres: Option<f64>,
}

/// A [`QualitySummary`](super::QualitySummary).
#[derive(Serialize)]
struct QualitySummaryJson<'a> {
    method: &'a str,
    backend: &'static str,
    spp: u32,
    scenes: usize,
    mean_rmse_ratio: f64,
    mean_err_corr: Option<f64>,
}

/// A [`VsWlr`](super::VsWlr).
#[derive(Serialize)]
struct VsWlrJson<'a> {
    scene: &'a str,
    spp: u32,
    method: &'a str,
    backend: &'static str,
    rmse_ratio: f64,
    speedup: Option<f64>,
}

/// [`TimingReport::to_json`].
#[derive(Serialize)]
struct TimingJson<'a> {
    kind: &'static str,
    device: Option<&'a str>,
    settings: &'a str,
    inputs: &'a str,
    source: &'a str,
    runs: usize,
    peak: Option<&'a super::Peak>,
    rows: Vec<TimingRowJson<'a>>,
    warnings: &'a [String],
}

/// A [`TimingRow`].
#[derive(Serialize)]
struct TimingRowJson<'a> {
    case: &'a str,
    method: &'static str,
    backend: &'static str,
    width: usize,
    height: usize,
    wall_ms: &'a [f64],
    median_wall_ms: f64,
    ms_per_megapixel: f64,
    gpu_ms: Option<f64>,
    device_mb: Option<f64>,
    rss_mb: Option<f64>,
    kernels: Vec<KernelJson<'a>>,
}

/// A [`KernelRow`](super::KernelRow).
#[derive(Serialize)]
struct KernelJson<'a> {
    kernel: &'a str,
    gpu_ms: f64,
    dispatches: usize,
    gflops: f64,
    gbs: f64,
}

/// Appends the Markdown "Warnings:" section (nothing when there are none).
fn push_warnings(s: &mut String, warnings: &[String]) {
    if !warnings.is_empty() {
        s.push_str("\nWarnings:\n");
        for w in warnings {
            let _ = writeln!(s, "- {w}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::QualityRow;
    use crate::methods::Backend;
    use crate::metrics::Metrics;

    /// Whether every `"key": ` is in `text`, first occurrences in the order given.
    fn keys_in_order(text: &str, keys: &[&str]) -> bool {
        let pos: Vec<Option<usize>> = keys
            .iter()
            .map(|k| text.find(&format!("\"{k}\": ")))
            .collect();
        pos.iter().all(Option::is_some) && pos.windows(2).all(|w| w[0] < w[1])
    }

    #[test]
    fn json_keys_nulls_and_escapes() {
        let mut input = row("input", None, 0.2, None);
        input.metrics.psnr = f64::INFINITY;
        input.metrics.ssim = f64::NAN;
        let report = QualityReport {
            dir: "scenes".into(),
            rows: vec![input],
            warnings: vec!["q\"\\\n\u{1}".into()],
            ..Default::default()
        };
        let text = report.to_json();
        assert!(text.ends_with("}\n"), "{text}");
        assert!(
            keys_in_order(
                &text,
                &[
                    "kind",
                    "dir",
                    "device",
                    "rows",
                    "case",
                    "scene",
                    "spp",
                    "method",
                    "backend",
                    "rmse",
                    "relmse",
                    "psnr",
                    "ssim",
                    "wall_s",
                    "gpu_ms",
                    "err_corr",
                    "naive_corr",
                    "gpu_ms_per_mp",
                    "centres",
                    "summary",
                    "vs_wlr",
                    "warnings",
                ]
            ),
            "{text}"
        );
        assert!(text.contains(r#""q\"\\\n\u0001""#), "{text}");
        let j: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(j["kind"], "quality");
        assert_eq!(j["device"], serde_json::Value::Null);
        let r = &j["rows"][0];
        // Non-finite numbers and absent values are both `null`.
        assert_eq!(r["psnr"], serde_json::Value::Null);
        assert_eq!(r["ssim"], serde_json::Value::Null);
        assert_eq!(r["backend"], serde_json::Value::Null);
        assert_eq!(r["wall_s"], serde_json::Value::Null);
        assert_eq!(r["rmse"], 0.2);
        assert_eq!(r["spp"], 4);
        assert_eq!(j["warnings"][0], "q\"\\\n\u{1}");
    }

    #[test]
    fn timing_json_keys() {
        let report = TimingReport {
            inputs: "synthetic".into(),
            source: "synthetic frame".into(),
            runs: 2,
            rows: vec![TimingRow {
                case: "wlr.synthetic.4x4".into(),
                method: crate::methods::Method::Wlr,
                backend: Backend::Gpu,
                width: 4,
                height: 4,
                wall_ms: vec![1.5, f64::NAN],
                median_wall_ms: 1.5,
                ms_per_megapixel: 93750.0,
                gpu_ms: Some(1.0),
                device_mb: Some(12.0),
                rss_mb: None,
                kernels: vec![crate::bench::KernelRow {
                    kernel: "wlr_fit".into(),
                    ms: 1.0,
                    dispatches: 3,
                    gflops: 2.5,
                    gbs: 0.5,
                }],
            }],
            ..Default::default()
        };
        let text = report.to_json();
        assert!(
            keys_in_order(
                &text,
                &[
                    "kind",
                    "device",
                    "inputs",
                    "source",
                    "runs",
                    "peak",
                    "rows",
                    "case",
                    "method",
                    "backend",
                    "width",
                    "height",
                    "wall_ms",
                    "median_wall_ms",
                    "ms_per_megapixel",
                    "gpu_ms",
                    "device_mb",
                    "rss_mb",
                    "kernels",
                    "kernel",
                    "dispatches",
                    "gflops",
                    "gbs",
                    "warnings",
                ]
            ),
            "{text}"
        );
        let j: serde_json::Value = serde_json::from_str(&text).unwrap();
        let r = &j["rows"][0];
        assert_eq!(j["peak"], serde_json::Value::Null);
        assert_eq!(r["method"], "wlr");
        assert_eq!(r["backend"], "gpu");
        assert_eq!(r["wall_ms"], serde_json::json!([1.5, null]));
        assert_eq!(
            r["kernels"],
            serde_json::json!([{"kernel": "wlr_fit", "gpu_ms": 1.0, "dispatches": 3, "gflops": 2.5, "gbs": 0.5}])
        );
    }

    fn row(method: &str, backend: Option<Backend>, rmse: f64, corr: Option<f64>) -> QualityRow {
        QualityRow {
            case: format!("{method}.s.spp4"),
            scene: "s".into(),
            spp: 4,
            method: method.into(),
            backend,
            metrics: Metrics {
                rmse,
                relmse: rmse,
                psnr: 30.0,
                ssim: 0.9,
            },
            wall_s: backend.map(|_| 0.5),
            gpu_ms: None,
            err_corr: corr,
            naive_corr: corr.map(|c| c / 2.0),
            map_share: None,
            gpu_ms_per_mp: None,
            centres: None,
        }
    }

    #[test]
    fn methods_against_wlr() {
        let mut wlr = row("wlr", Some(Backend::Gpu), 0.01, None);
        wlr.gpu_ms = Some(1000.0);
        let mut lp = row("lp", Some(Backend::Gpu), 0.012, None);
        lp.gpu_ms = Some(100.0);
        lp.centres = Some(0.05);
        let cpu_lp = row("lp", Some(Backend::Cpu), 0.012, None);
        let report = QualityReport {
            dir: "scenes".into(),
            rows: vec![row("input", None, 0.2, None), wlr, lp, cpu_lp],
            ..Default::default()
        };
        let vs = report.vs_wlr();
        assert_eq!(vs.len(), 1, "{vs:?}");
        assert!((vs[0].rmse_ratio - 1.2).abs() < 1e-12);
        assert_eq!(vs[0].speedup, Some(10.0));
        let md = report.to_markdown();
        assert!(
            md.contains(
                "| s     |    4 | lp     | gpu     |      1.200 |                    10.0 |"
            ),
            "{md}"
        );
        assert!(md.contains("5.00%"), "{md}");
        let j: serde_json::Value = serde_json::from_str(&report.to_json()).unwrap();
        assert_eq!(j["vs_wlr"][0]["rmse_ratio"], 1.2);
    }

    #[test]
    fn quality_report_with_error_estimates() {
        let report = QualityReport {
            dir: "scenes".into(),
            rows: vec![
                row("input", None, 0.2, None),
                row("wlr", Some(Backend::Gpu), 0.01, Some(0.8)),
                row("none", Some(Backend::Gpu), 0.2, None),
            ],
            ..Default::default()
        };
        let md = report.to_markdown();
        assert!(md.contains("| err corr | naive corr | map share |"), "{md}");
        assert!(md.contains("|    0.800 |      0.400 |"), "{md}");
        // Rows without an estimate have blank correlation cells.
        let none = md.lines().find(|l| l.contains("| none ")).unwrap();
        assert!(
            none.ends_with("|          |            |           |"),
            "{none}"
        );
        let summary = report.summary();
        assert_eq!(summary.len(), 2);
        assert_eq!(summary[0].method, "wlr");
        assert!((summary[0].mean_rmse_ratio - 20.0).abs() < 1e-9);
        assert_eq!(summary[0].mean_err_corr, Some(0.8));
        assert!((summary[1].mean_rmse_ratio - 1.0).abs() < 1e-12);
        assert!(
            md.contains("- wlr (gpu), spp 4: 20.00 over 1 scene; mean err corr 0.800"),
            "{md}"
        );
        let j: serde_json::Value = serde_json::from_str(&report.to_json()).unwrap();
        let wlr = &j["rows"][1];
        assert_eq!(wlr["err_corr"], 0.8);
        assert_eq!(wlr["naive_corr"], 0.4);
        assert_eq!(wlr["gpu_ms_per_mp"], serde_json::Value::Null);
        assert_eq!(wlr["centres"], serde_json::Value::Null);
    }

    #[test]
    fn markdown_table_aligns() {
        let rows = vec![
            vec!["a".to_string(), "bb".to_string()],
            vec!["---".to_string(), "---:".to_string()],
            vec!["long".to_string(), "1".to_string()],
        ];
        let t = markdown_table(&rows);
        assert_eq!(t, "| a    |   bb |\n| ---- | ---: |\n| long |    1 |\n");
    }
}
