//! Fuzzing on stable Rust (issue #14): `proptest` mutates real statistics
//! files (the checked-in corpus `tests/fuzz_corpus/`, small renders of the
//! built-in scenes saved with `render --save-stats`, and two committed
//! fixtures) and feeds them to the EXR statistics reader; whatever it
//! accepts goes through validation and a CPU denoise (sanitation, the
//! outlier stage and LP). Nothing may panic, and an accepted image must give
//! a finite, non-negative output. The `--opt` parser gets arbitrary strings.
//!
//! CI runs a few hundred cases. A long run:
//! `MCDENOISE_FUZZ_CASES=100000 cargo test --release --test fuzz -- --nocapture`.
//! Inputs that once failed live in `tests/fuzz_corpus/regressions/` and are
//! replayed by `regressions_are_handled`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use mcdenoise::options::Options;
use mcdenoise::{Config, Denoiser, Method, Source};
use proptest::prelude::*;
use proptest::test_runner::{Config as RunnerConfig, TestRunner};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests")
}

/// The seed files: the corpus and two small fixtures.
fn corpus() -> Vec<Vec<u8>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("fuzz_corpus"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "exr"))
        .collect();
    files.push(root().join("fixtures/smooth_64.exr"));
    files.push(root().join("fixtures/dof_checker_64_ref.exr"));
    files.sort();
    assert!(files.len() >= 5, "the fuzz corpus is missing");
    files.iter().map(|p| std::fs::read(p).unwrap()).collect()
}

/// One edit of a seed file.
#[derive(Clone, Debug)]
enum Mutation {
    /// Flip one bit.
    Flip(usize, u8),
    /// Overwrite one byte.
    Set(usize, u8),
    /// Overwrite a little-endian u32 with an interesting value (sizes,
    /// offsets, counts: 0, 1, huge, negative).
    Word(usize, u32),
    /// Cut the file.
    Truncate(usize),
    /// Insert bytes.
    Insert(usize, Vec<u8>),
    /// Copy a range of the file over another place of it.
    Splice(usize, usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let words = prop_oneof![
        Just(0u32),
        Just(1),
        Just(0x7fff_ffff),
        Just(0xffff_ffff),
        Just(0x8000_0000),
        Just(65536),
        Just(16385),
        any::<u32>(),
    ];
    prop_oneof![
        3 => (any::<usize>(), 0u8..8).prop_map(|(a, b)| Mutation::Flip(a, b)),
        3 => (any::<usize>(), any::<u8>()).prop_map(|(a, b)| Mutation::Set(a, b)),
        3 => (any::<usize>(), words).prop_map(|(a, w)| Mutation::Word(a, w)),
        1 => any::<usize>().prop_map(Mutation::Truncate),
        1 => (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(a, v)| Mutation::Insert(a, v)),
        1 => (any::<usize>(), any::<usize>(), 1usize..64)
            .prop_map(|(a, b, n)| Mutation::Splice(a, b, n)),
    ]
}

/// Mutations land in the header (first 1 KiB) half of the time: that is
/// where sizes, channel lists and offsets live.
fn place(at: usize, len: usize) -> usize {
    if len == 0 {
        return 0;
    }
    if at % 2 == 0 {
        (at / 2) % len.min(1024)
    } else {
        (at / 2) % len
    }
}

fn apply(mut bytes: Vec<u8>, edits: &[Mutation]) -> Vec<u8> {
    for m in edits {
        let len = bytes.len();
        match m {
            Mutation::Flip(a, b) if len > 0 => bytes[place(*a, len)] ^= 1 << b,
            Mutation::Set(a, v) if len > 0 => bytes[place(*a, len)] = *v,
            Mutation::Word(a, w) if len >= 4 => {
                let at = place(*a, len - 3);
                bytes[at..at + 4].copy_from_slice(&w.to_le_bytes());
            }
            Mutation::Truncate(a) => bytes.truncate(place(*a, len + 1)),
            Mutation::Insert(a, v) => {
                let at = place(*a, len + 1).min(len);
                bytes.splice(at..at, v.iter().copied());
            }
            Mutation::Splice(a, b, n) if len > 0 => {
                let (from, to) = (place(*a, len), place(*b, len));
                let n = (*n).min(len - from).min(len - to);
                let src = bytes[from..from + n].to_vec();
                bytes[to..to + n].copy_from_slice(&src);
            }
            _ => {}
        }
    }
    bytes
}

/// Inputs the reader accepted, and of those the ones denoised.
static ACCEPTED: AtomicUsize = AtomicUsize::new(0);
static DENOISED: AtomicUsize = AtomicUsize::new(0);

/// Panics raised in mcdenoise's own code (`src/`), even those the reader's
/// `catch_unwind` turns into an error: a malformed file must meet a check,
/// not an index out of bounds. Panics inside the `exr` crate's decoder are
/// what that `catch_unwind` is for, and are not counted.
static OUR_PANICS: AtomicUsize = AtomicUsize::new(0);

fn count_our_panics() {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        std::panic::set_hook(Box::new(|info| {
            let file = info.location().map_or("", |l| l.file());
            if file.starts_with("src/") {
                OUR_PANICS.fetch_add(1, Ordering::Relaxed);
                eprintln!("panic in mcdenoise: {info}");
            } else if !file.contains(".cargo/registry") {
                eprintln!("{info}");
            }
        }));
    });
}

/// What one input must satisfy: the reader returns (no panic); an accepted
/// image validates and, when small, denoises on the CPU to a finite,
/// non-negative image of its size.
fn check(path: &Path) {
    let Ok(img) = mcdenoise::io::read_stats(path) else {
        return;
    };
    ACCEPTED.fetch_add(1, Ordering::Relaxed);
    let _ = mcdenoise::io::inspect::validate(&img);
    if img.width * img.height > 64 * 64 {
        return;
    }
    for method in [Method::None, Method::Lp] {
        let Ok(d) = Denoiser::new_cpu(Source::of_image(&img), Config::new(method)) else {
            continue;
        };
        if let Ok(frame) = d.denoise(&img, None) {
            DENOISED.fetch_add(1, Ordering::Relaxed);
            assert_eq!(frame.color.width, img.width);
            assert_eq!(frame.color.height, img.height);
            for plane in &frame.color.planes {
                assert!(
                    plane.iter().all(|v| v.is_finite() && *v >= 0.0),
                    "{method:?}: a non-finite or negative output from an accepted input"
                );
            }
        }
    }
}

fn cases() -> u32 {
    std::env::var("MCDENOISE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

#[test]
fn mutated_statistics_files_never_panic() {
    count_our_panics();
    let seeds = corpus();
    let dir = tempdir();
    let path = dir.path().join("case.exr");
    // Outside the test's folder, which is removed when the test ends.
    let keep =
        std::env::temp_dir().join(format!("mcdenoise-fuzz-failing-{}.exr", std::process::id()));
    let mut runner = TestRunner::new(RunnerConfig {
        cases: cases(),
        failure_persistence: None,
        ..RunnerConfig::default()
    });
    let started = std::time::Instant::now();
    let strategy = (0..seeds.len(), prop::collection::vec(mutation(), 1..6));
    let result = runner.run(&strategy, |(seed, edits)| {
        let bytes = apply(seeds[seed].clone(), &edits);
        std::fs::write(&path, &bytes).unwrap();
        let before = OUR_PANICS.load(Ordering::Relaxed);
        let outcome = std::panic::catch_unwind(|| check(&path));
        let outcome = outcome.map_err(|_| ()).and_then(|()| {
            (OUR_PANICS.load(Ordering::Relaxed) == before)
                .then_some(())
                .ok_or(())
        });
        if outcome.is_err() {
            std::fs::write(&keep, &bytes).unwrap();
        }
        prop_assert!(
            outcome.is_ok(),
            "panicked on seed {seed} with {edits:?} (bytes kept in {})",
            keep.display()
        );
        Ok(())
    });
    eprintln!(
        "fuzz: {} cases from {} seeds in {:.1} s: {} read, {} denoised",
        cases(),
        seeds.len(),
        started.elapsed().as_secs_f64(),
        ACCEPTED.load(Ordering::Relaxed),
        DENOISED.load(Ordering::Relaxed)
    );
    result.unwrap();
}

#[test]
fn option_strings_never_panic() {
    let mut runner = TestRunner::new(RunnerConfig {
        cases: cases(),
        failure_persistence: None,
        ..RunnerConfig::default()
    });
    let key = prop_oneof![
        Just("aos.residual".to_string()),
        Just("sampling.smooth".to_string()),
        Just("lp.error_mode".to_string()),
        Just("lp.centre_test".to_string()),
        Just("lp.outlier_weight".to_string()),
        ".{0,24}",
    ];
    let pair = (
        key,
        ".{0,24}",
        prop_oneof![Just("="), Just(" = "), Just("")],
    )
        .prop_map(|(k, v, eq)| format!("{k}{eq}{v}"));
    runner
        .run(&prop::collection::vec(pair, 0..4), |pairs| {
            if let Ok(o) = Options::parse(&pairs) {
                for k in o.keys() {
                    let _ = o.get(k);
                }
            }
            Ok(())
        })
        .unwrap();
}

/// Inputs that once failed stay fixed: no panic in mcdenoise's code, caught
/// or not.
#[test]
fn regressions_are_handled() {
    count_our_panics();
    let dir = root().join("fuzz_corpus/regressions");
    let mut files = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let path = e.unwrap().path();
        let before = OUR_PANICS.load(Ordering::Relaxed);
        check(&path);
        assert_eq!(
            OUR_PANICS.load(Ordering::Relaxed),
            before,
            "{} panicked inside mcdenoise",
            path.display()
        );
        files += 1;
    }
    assert!(files >= 1, "the regression corpus is missing");
}

/// A fresh folder, removed when the guard drops.
fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("mcdenoise-fuzz-")
        .tempdir()
        .unwrap()
}
