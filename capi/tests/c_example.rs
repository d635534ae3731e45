//! Builds `examples/c/host.c` with the system C compiler against
//! `include/mcdenoise.h`, the Vulkan loader and this package's
//! `libmcdenoise.so`, and runs it under the validation layer: a C host that
//! accumulates in its own shader (`examples/c/accumulate.comp` on
//! `include/mcdenoise_accum.glsl`), records mcdenoise into its command
//! buffer, renders a second pass where the sample map says and checks the
//! results (the program exits non-zero when they are wrong, or on any
//! validation message), then denoises a sequence with the temporal filter
//! in frame order and both ways (`McdSmoother`), which must beat frame
//! order; its context keeps a pipeline cache file, which must be written.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Builds `libmcdenoise.so` (cargo does not build a cdylib for an
/// integration test) with the test's own profile and target folder, and
/// returns the folder holding it. It builds what `cargo test -p mcdenoise
/// -p mcdenoise-capi` built, so that only the C library is new: the same
/// profile (`test`, or `bench` with `--release`), the main crate's default
/// features, and the examples, which `cargo test` builds too: with a
/// target that takes the dev-dependencies, their features on the shared
/// dependencies (`getrandom`'s `std` under `tobj`) are those of the test
/// binaries' build, and the main crate is not compiled again.
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let profile_dir = exe.parent().unwrap().parent().unwrap();
    let target_dir = profile_dir.parent().unwrap();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.args([
        "build",
        "--quiet",
        "--lib",
        "--examples",
        "-p",
        "mcdenoise",
        "-p",
        "mcdenoise-capi",
    ])
    .arg("--target-dir")
    .arg(target_dir)
    .current_dir(env!("CARGO_MANIFEST_DIR"));
    let release = profile_dir.file_name().is_some_and(|n| n == "release");
    cmd.args(["--profile", if release { "bench" } else { "test" }]);
    let status = cmd.status().expect("cargo build -p mcdenoise-capi");
    assert!(status.success(), "building libmcdenoise.so failed");
    assert!(
        profile_dir.join("libmcdenoise.so").exists(),
        "libmcdenoise.so not found in {}",
        profile_dir.display()
    );
    profile_dir.to_path_buf()
}

/// Whether the Khronos validation layer is installed (the README's test
/// command requires it; a plain `cargo test` runs without it when missing).
fn validation_installed() -> bool {
    // SAFETY: loading the system's Vulkan loader.
    let entry = unsafe { ash::Entry::load() }.expect("the Vulkan loader");
    // SAFETY: a valid entry.
    unsafe { entry.enumerate_instance_layer_properties() }
        .expect("vkEnumerateInstanceLayerProperties")
        .iter()
        .any(|l| l.layer_name_as_c_str() == Ok(c"VK_LAYER_KHRONOS_validation"))
}

#[test]
fn c_host_accumulates_on_the_gpu_and_denoises() {
    let exe = compile_c("examples/c/host.c", "host");
    let out = exe.parent().unwrap().to_path_buf();

    let spv = Path::new(env!("OUT_DIR")).join("accumulate.spv");
    let spv_position = Path::new(env!("OUT_DIR")).join("accumulate_position.spv");
    let validate = validation_installed();
    let cache = out.join("pipelines.bin");
    let _ = std::fs::remove_file(&cache);
    let output = Command::new(&exe)
        .arg(&spv)
        .arg(&spv_position)
        .arg(&cache)
        .env(
            "MCDENOISE_EMBED_VALIDATION",
            if validate { "1" } else { "0" },
        )
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    println!("{stdout}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "the C host failed ({}):\n{stdout}\n{stderr}",
        output.status
    );
    assert!(
        stdout.contains("sample map:")
            && stdout.contains("with the pyramid: rMSE")
            && stdout.contains("stage flags: ok")
            && stdout.contains("sums in host memory:")
            && stdout.contains("coarse map flag: ok")
            && stdout.contains("two-way: rMSE")
            && stdout.ends_with("ok\n"),
        "{stdout}"
    );
    let saved = std::fs::metadata(&cache).map(|m| m.len()).unwrap_or(0);
    assert!(
        saved >= 32,
        "the pipeline cache was not written ({saved} bytes)"
    );
    if std::env::var("MCDENOISE_REQUIRE_VALIDATION").is_ok_and(|v| v == "1") {
        assert!(
            validate,
            "the validation layer is required but not installed"
        );
    }
}

/// Compiles `source` (relative to the repository) with the system C
/// compiler against `include/`, `libmcdenoise.so` and the Vulkan loader into
/// a folder of its own; returns the executable.
fn compile_c(source: &str, name: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let lib = library_dir();
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("c_{name}"));
    std::fs::create_dir_all(&out).unwrap();
    let exe = out.join(name);
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let status = Command::new(&cc)
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-O1"])
        .arg(root.join(source))
        .arg("-I")
        .arg(root.join("include"))
        .arg("-o")
        .arg(&exe)
        .arg("-L")
        .arg(&lib)
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .args(["-lmcdenoise", "-lvulkan", "-lm"])
        .status()
        .unwrap_or_else(|e| panic!("cannot run the C compiler {cc}: {e}"));
    assert!(status.success(), "compiling {source} failed");
    exe
}

/// `capi/tests/c/errors.c`: NULL and invalid arguments give a status and a
/// message (no device needed).
#[test]
fn c_error_paths_return_statuses() {
    let exe = compile_c("capi/tests/c/errors.c", "errors");
    let output = Command::new(&exe).output().unwrap();
    assert!(
        output.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}
