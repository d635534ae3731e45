//! Every decision tag used in the code has a record, and every record is in
//! the index.
//!
//! A decision tag is a token of the form `LP-PIXEL-TEST`: an uppercase
//! letter, then uppercase letters or digits, then one or more groups of `-`
//! and uppercase letters or digits, on word boundaries (the same tokens as
//! `grep -rhoE '\b[A-Z][A-Z0-9]+(-[A-Z0-9]+)+\b' src spirv`). This test scans
//! every file under `src/` and `spirv/` for such tokens and fails, listing
//! them, when a tag has no `docs/decisions/TAG.md`, when a record's first
//! line is not `# TAG: ...`, or when a record is not linked from
//! `docs/decisions/README.md`. It reads files only: no GPU, no build of the
//! crate's kernels beyond what `cargo test` already does.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

/// Tokens of the tag form that are not decision tags.
const NOT_TAGS: &[&str] = &[
    // The name of Vulkan's shader format (build.rs, the kernels' headers).
    "SPIR-V",
    // A text encoding, in an error message about file names (src/io/frames.rs).
    "UTF-8",
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every file under `dir`, recursively, in sorted order.
fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for p in paths {
        if p.is_dir() {
            files_under(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn is_word_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// `[A-Z][A-Z0-9]+`
fn is_head(w: &str) -> bool {
    let mut chars = w.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_uppercase())
        && w.len() >= 2
        && w.chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit())
}

/// `[A-Z0-9]+`
fn is_group(w: &str) -> bool {
    !w.is_empty()
        && w.chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit())
}

/// The tokens of `text` that match `\b[A-Z][A-Z0-9]+(-[A-Z0-9]+)+\b`.
///
/// The text is cut into words (maximal runs of letters, digits and `_`);
/// words joined by a single `-` form a chain, and a tag is the longest run
/// of a chain that starts with a head word and continues with group words.
fn tags_in(text: &str, out: &mut BTreeSet<String>) {
    let chars: Vec<char> = text.chars().collect();
    let mut i = 0;
    let mut chain: Vec<String> = Vec::new();
    let flush = |chain: &mut Vec<String>, out: &mut BTreeSet<String>| {
        let mut s = 0;
        while s < chain.len() {
            if is_head(&chain[s]) {
                let mut e = s + 1;
                while e < chain.len() && is_group(&chain[e]) {
                    e += 1;
                }
                if e - s >= 2 {
                    out.insert(chain[s..e].join("-"));
                    s = e;
                    continue;
                }
            }
            s += 1;
        }
        chain.clear();
    };
    while i < chars.len() {
        if is_word_char(chars[i]) {
            let start = i;
            while i < chars.len() && is_word_char(chars[i]) {
                i += 1;
            }
            let word: String = chars[start..i].iter().collect();
            let joined = i + 1 < chars.len() && chars[i] == '-' && is_word_char(chars[i + 1]);
            chain.push(word);
            if joined {
                i += 1; // the '-'
            } else {
                flush(&mut chain, out);
            }
        } else {
            i += 1;
        }
    }
    flush(&mut chain, out);
}

/// Every tag used under `src/` and `spirv/`, with the first file using it.
fn code_tags() -> Vec<(String, PathBuf)> {
    let mut files = Vec::new();
    for dir in ["src", "spirv"] {
        files_under(&root().join(dir), &mut files);
    }
    assert!(!files.is_empty(), "no files under src/ and spirv/");
    let mut seen: Vec<(String, PathBuf)> = Vec::new();
    let mut names = BTreeSet::new();
    for f in &files {
        let Ok(bytes) = fs::read(f) else { continue };
        let text = String::from_utf8_lossy(&bytes);
        let mut tags = BTreeSet::new();
        tags_in(&text, &mut tags);
        for t in tags {
            if !NOT_TAGS.contains(&t.as_str()) && names.insert(t.clone()) {
                seen.push((t, f.strip_prefix(root()).unwrap_or(f).to_path_buf()));
            }
        }
    }
    seen.sort();
    seen
}

fn decisions_dir() -> PathBuf {
    root().join("docs").join("decisions")
}

#[test]
fn the_scanner_finds_tags_as_grep_does() {
    let mut t = BTreeSet::new();
    tags_in(
        "LP-PIXEL-TEST (ours), x-MAP-SMOOTH-LP; SPIR-V AB-cd LP_RING A-B AB-C-d \
         AOS-SCALE_x 3D-POLY NOISE-CONST.",
        &mut t,
    );
    let got: Vec<&str> = t.iter().map(String::as_str).collect();
    assert_eq!(
        got,
        [
            "AB-C",
            "LP-PIXEL-TEST",
            "MAP-SMOOTH-LP",
            "NOISE-CONST",
            "SPIR-V"
        ]
    );
}

#[test]
fn every_tag_in_the_code_has_a_decision_record() {
    let dir = decisions_dir();
    let missing: Vec<String> = code_tags()
        .into_iter()
        .filter(|(t, _)| !dir.join(format!("{t}.md")).is_file())
        .map(|(t, f)| format!("{t} (first in {})", f.display()))
        .collect();
    assert!(
        missing.is_empty(),
        "{} decision tag(s) used in src/ or spirv/ have no docs/decisions/TAG.md \
         (write one, or list a token that is not a tag in NOT_TAGS with the reason):\n  {}",
        missing.len(),
        missing.join("\n  ")
    );
}

#[test]
fn every_record_is_titled_and_linked_from_the_index() {
    let dir = decisions_dir();
    let index = fs::read_to_string(dir.join("README.md")).expect("docs/decisions/README.md");
    let mut records = Vec::new();
    files_under(&dir, &mut records);
    let mut problems = Vec::new();
    let mut count = 0;
    for r in records {
        let name = r.file_name().unwrap().to_string_lossy().into_owned();
        let Some(tag) = name.strip_suffix(".md") else {
            continue;
        };
        if tag == "README" {
            continue;
        }
        count += 1;
        if !index.contains(&format!("]({name})")) {
            problems.push(format!("{name}: not linked from README.md as ]({name})"));
        }
        let text = fs::read_to_string(&r).unwrap_or_default();
        let first = text.lines().next().unwrap_or("");
        if !first.starts_with(&format!("# {tag}: ")) {
            problems.push(format!("{name}: first line is not `# {tag}: ...`"));
        }
    }
    assert!(count > 0, "no records in docs/decisions/");
    assert!(
        problems.is_empty(),
        "decision records:\n  {}",
        problems.join("\n  ")
    );
}

#[test]
fn every_index_link_names_a_record() {
    let dir = decisions_dir();
    let index = fs::read_to_string(dir.join("README.md")).expect("docs/decisions/README.md");
    let mut broken = Vec::new();
    for piece in index.split("](").skip(1) {
        let target = piece.split(')').next().unwrap_or("");
        if target.ends_with(".md") && !target.contains('/') && !dir.join(target).is_file() {
            broken.push(target.to_string());
        }
    }
    assert!(
        broken.is_empty(),
        "README.md links to missing records: {broken:?}"
    );
}
