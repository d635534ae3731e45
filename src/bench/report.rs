//! Output of the benchmark reports: Markdown tables and JSON.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

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
            header.extend(["err corr", "naive corr"]);
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
    /// "summary": [...], "vs_wlr": [...], "unavailable_methods": [...],
    /// "warnings": [...]}`.
    /// Each row has `case scene spp method backend rmse relmse psnr ssim
    /// wall_s gpu_ms err_corr naive_corr gpu_ms_per_mp centres` (`null` where absent or
    /// non-finite); numbers at full precision.
    pub fn to_json(&self) -> String {
        let rows = self
            .rows
            .iter()
            .map(|r| {
                Json::Obj(vec![
                    ("case".into(), Json::Str(r.case.clone())),
                    ("scene".into(), Json::Str(r.scene.clone())),
                    ("spp".into(), Json::Int(r.spp as i64)),
                    ("method".into(), Json::Str(r.method.clone())),
                    (
                        "backend".into(),
                        r.backend
                            .map_or(Json::Null, |b| Json::Str(backend_name(b).into())),
                    ),
                    ("rmse".into(), Json::Num(r.metrics.rmse)),
                    ("relmse".into(), Json::Num(r.metrics.relmse)),
                    ("psnr".into(), Json::Num(r.metrics.psnr)),
                    ("ssim".into(), Json::Num(r.metrics.ssim)),
                    ("wall_s".into(), Json::opt(r.wall_s)),
                    ("gpu_ms".into(), Json::opt(r.gpu_ms)),
                    ("err_corr".into(), Json::opt(r.err_corr)),
                    ("naive_corr".into(), Json::opt(r.naive_corr)),
                    ("gpu_ms_per_mp".into(), Json::opt(r.gpu_ms_per_mp)),
                    ("centres".into(), Json::opt(r.centres)),
                ])
            })
            .collect();
        let summary = self
            .summary()
            .into_iter()
            .map(|q| {
                Json::Obj(vec![
                    ("method".into(), Json::Str(q.method)),
                    ("backend".into(), Json::Str(backend_name(q.backend).into())),
                    ("spp".into(), Json::Int(q.spp as i64)),
                    ("scenes".into(), Json::Int(q.scenes as i64)),
                    ("mean_rmse_ratio".into(), Json::Num(q.mean_rmse_ratio)),
                    ("mean_err_corr".into(), Json::opt(q.mean_err_corr)),
                ])
            })
            .collect();
        Json::Obj(vec![
            ("kind".into(), Json::Str("quality".into())),
            ("dir".into(), Json::Str(self.dir.display().to_string())),
            (
                "device".into(),
                self.device.clone().map_or(Json::Null, Json::Str),
            ),
            ("rows".into(), Json::Arr(rows)),
            ("summary".into(), Json::Arr(summary)),
            (
                "vs_wlr".into(),
                Json::Arr(
                    self.vs_wlr()
                        .into_iter()
                        .map(|c| {
                            Json::Obj(vec![
                                ("scene".into(), Json::Str(c.scene)),
                                ("spp".into(), Json::Int(c.spp as i64)),
                                ("method".into(), Json::Str(c.method)),
                                ("backend".into(), Json::Str(backend_name(c.backend).into())),
                                ("rmse_ratio".into(), Json::Num(c.rmse_ratio)),
                                ("speedup".into(), Json::opt(c.speedup)),
                            ])
                        })
                        .collect(),
                ),
            ),
            (
                "unavailable_methods".into(),
                Json::Arr(
                    self.unavailable
                        .iter()
                        .map(|m| Json::Str(m.name().into()))
                        .collect(),
                ),
            ),
            (
                "warnings".into(),
                Json::Arr(self.warnings.iter().cloned().map(Json::Str).collect()),
            ),
        ])
        .render()
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
        s.push('\n');
        let mut rows: Vec<Vec<String>> = vec![
            ["case", "backend", "median wall ms", "ms/MP", "GPU ms"]
                .map(String::from)
                .to_vec(),
            ["---", "---", "---:", "---:", "---:"]
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
            ]);
        }
        s.push_str(&markdown_table(&rows));
        let with_kernels: Vec<&TimingRow> =
            self.rows.iter().filter(|r| !r.kernels.is_empty()).collect();
        s.push('\n');
        if with_kernels.is_empty() {
            s.push_str("Per-kernel GPU times: none reported by these cases.\n");
        } else {
            s.push_str("Per-kernel GPU times (median over the runs):\n\n");
            let mut rows: Vec<Vec<String>> = vec![
                ["case", "backend", "kernel", "GPU ms", "dispatches"]
                    .map(String::from)
                    .to_vec(),
                ["---", "---", "---", "---:", "---:"]
                    .map(String::from)
                    .to_vec(),
            ];
            for r in with_kernels {
                for k in &r.kernels {
                    rows.push(vec![
                        r.case.clone(),
                        backend_name(r.backend).into(),
                        k.kernel.clone(),
                        format!("{:.3}", k.ms),
                        k.dispatches.to_string(),
                    ]);
                }
            }
            s.push_str(&markdown_table(&rows));
        }
        push_warnings(&mut s, &self.warnings);
        s
    }

    /// The report as JSON: `{"kind": "timing", "device", "inputs", "source",
    /// "runs", "rows": [...], "unavailable_methods", "warnings"}`; each row
    /// has `case method backend width height wall_ms median_wall_ms
    /// ms_per_megapixel gpu_ms kernels` and each kernel `kernel gpu_ms
    /// dispatches`.
    pub fn to_json(&self) -> String {
        let rows = self
            .rows
            .iter()
            .map(|r| {
                Json::Obj(vec![
                    ("case".into(), Json::Str(r.case.clone())),
                    ("method".into(), Json::Str(r.method.name().into())),
                    ("backend".into(), Json::Str(backend_name(r.backend).into())),
                    ("width".into(), Json::Int(r.width as i64)),
                    ("height".into(), Json::Int(r.height as i64)),
                    (
                        "wall_ms".into(),
                        Json::Arr(r.wall_ms.iter().map(|&t| Json::Num(t)).collect()),
                    ),
                    ("median_wall_ms".into(), Json::Num(r.median_wall_ms)),
                    ("ms_per_megapixel".into(), Json::Num(r.ms_per_megapixel)),
                    ("gpu_ms".into(), Json::opt(r.gpu_ms)),
                    (
                        "kernels".into(),
                        Json::Arr(
                            r.kernels
                                .iter()
                                .map(|k| {
                                    Json::Obj(vec![
                                        ("kernel".into(), Json::Str(k.kernel.clone())),
                                        ("gpu_ms".into(), Json::Num(k.ms)),
                                        ("dispatches".into(), Json::Int(k.dispatches as i64)),
                                    ])
                                })
                                .collect(),
                        ),
                    ),
                ])
            })
            .collect();
        Json::Obj(vec![
            ("kind".into(), Json::Str("timing".into())),
            (
                "device".into(),
                self.device.clone().map_or(Json::Null, Json::Str),
            ),
            ("inputs".into(), Json::Str(self.inputs.clone())),
            ("source".into(), Json::Str(self.source.clone())),
            ("runs".into(), Json::Int(self.runs as i64)),
            ("rows".into(), Json::Arr(rows)),
            (
                "unavailable_methods".into(),
                Json::Arr(
                    self.unavailable
                        .iter()
                        .map(|m| Json::Str(m.name().into()))
                        .collect(),
                ),
            ),
            (
                "warnings".into(),
                Json::Arr(self.warnings.iter().cloned().map(Json::Str).collect()),
            ),
        ])
        .render()
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
fn markdown_table(rows: &[Vec<String>]) -> String {
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

/// A JSON value, rendered by hand (no serialisation dependency).
#[derive(Clone, Debug)]
enum Json {
    Null,
    Int(i64),
    /// Non-finite numbers render as `null`.
    Num(f64),
    Str(String),
    Arr(Vec<Json>),
    Obj(Vec<(String, Json)>),
}

impl Json {
    fn opt(v: Option<f64>) -> Json {
        v.map_or(Json::Null, Json::Num)
    }

    fn is_scalar(&self) -> bool {
        !matches!(self, Json::Arr(_) | Json::Obj(_))
    }

    /// Pretty-printed with two-space indents; an object or array holding only
    /// scalars goes on one line (one table row per line).
    fn render(&self) -> String {
        let mut s = String::new();
        self.write(&mut s, 0);
        s.push('\n');
        s
    }

    fn write(&self, s: &mut String, indent: usize) {
        match self {
            Json::Null => s.push_str("null"),
            Json::Int(i) => {
                let _ = write!(s, "{i}");
            }
            // `{:?}` is the shortest representation that reads back to the
            // same f64, and is valid JSON (`1.0`, `1e-7`, `0.036870001`).
            Json::Num(v) if v.is_finite() => {
                let _ = write!(s, "{v:?}");
            }
            Json::Num(_) => s.push_str("null"),
            Json::Str(t) => write_json_string(s, t),
            Json::Arr(items) => {
                if items.is_empty() {
                    s.push_str("[]");
                } else if items.iter().all(Json::is_scalar) {
                    s.push('[');
                    for (i, v) in items.iter().enumerate() {
                        if i > 0 {
                            s.push_str(", ");
                        }
                        v.write(s, indent);
                    }
                    s.push(']');
                } else {
                    s.push_str("[\n");
                    for (i, v) in items.iter().enumerate() {
                        s.push_str(&"  ".repeat(indent + 1));
                        v.write(s, indent + 1);
                        s.push_str(if i + 1 < items.len() { ",\n" } else { "\n" });
                    }
                    s.push_str(&"  ".repeat(indent));
                    s.push(']');
                }
            }
            Json::Obj(fields) => {
                if fields.is_empty() {
                    s.push_str("{}");
                } else if fields.iter().all(|(_, v)| v.is_scalar()) {
                    s.push('{');
                    for (i, (k, v)) in fields.iter().enumerate() {
                        if i > 0 {
                            s.push_str(", ");
                        }
                        write_json_string(s, k);
                        s.push_str(": ");
                        v.write(s, indent);
                    }
                    s.push('}');
                } else {
                    s.push_str("{\n");
                    for (i, (k, v)) in fields.iter().enumerate() {
                        s.push_str(&"  ".repeat(indent + 1));
                        write_json_string(s, k);
                        s.push_str(": ");
                        v.write(s, indent + 1);
                        s.push_str(if i + 1 < fields.len() { ",\n" } else { "\n" });
                    }
                    s.push_str(&"  ".repeat(indent));
                    s.push('}');
                }
            }
        }
    }
}

fn write_json_string(s: &mut String, t: &str) {
    s.push('"');
    for c in t.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\r' => s.push_str("\\r"),
            '\t' => s.push_str("\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(s, "\\u{:04x}", c as u32);
            }
            c => s.push(c),
        }
    }
    s.push('"');
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

    #[test]
    fn json_rendering() {
        let j = Json::Obj(vec![
            ("a".into(), Json::Num(f64::NAN)),
            ("b".into(), Json::Str("q\"\\\n\u{1}".into())),
            (
                "c".into(),
                Json::Arr(vec![Json::Num(1.0), Json::Num(1e-7), Json::Int(3)]),
            ),
            ("d".into(), Json::Arr(vec![])),
        ]);
        let s = j.render();
        assert!(s.contains(r#""a": null"#), "{s}");
        assert!(s.contains(r#""b": "q\"\\\n\u0001""#), "{s}");
        assert!(s.contains("[1.0, 1e-7, 3]"), "{s}");
        assert!(s.contains(r#""d": []"#), "{s}");
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
        assert!(report.to_json().contains(r#""rmse_ratio": 1.2"#));
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
        assert!(md.contains("| err corr | naive corr |"), "{md}");
        assert!(md.contains("|    0.800 |      0.400 |"), "{md}");
        // Rows without an estimate have blank correlation cells.
        let none = md.lines().find(|l| l.contains("| none ")).unwrap();
        assert!(none.ends_with("|          |            |"), "{none}");
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
        assert!(report.to_json().contains(
            r#""err_corr": 0.8, "naive_corr": 0.4, "gpu_ms_per_mp": null, "centres": null}"#
        ));
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
