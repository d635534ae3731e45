//! The `mcdenoise` binary as a user runs it: exit codes, messages, outputs.

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mcdenoise"))
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// A fresh folder of one test's own, removed when the guard drops.
fn tmpdir(tag: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("mcdenoise-cli-{tag}-"))
        .tempdir()
        .unwrap()
}

fn run(cmd: &mut Command) -> (i32, String, String) {
    let o = cmd.output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn info_lists_a_device() {
    let (code, out, _) = run(bin().arg("info"));
    assert_eq!(code, 0);
    assert!(out.contains("maxStorageBufferRange"), "{out}");
    assert!(out.contains("shaderFloat64"));
    assert!(
        out.lines().any(|l| l.starts_with('*')),
        "no device marked as used:\n{out}"
    );
}

#[test]
fn inspect_fixture() {
    let (code, out, err) = run(bin()
        .arg("inspect")
        .arg(fixture("dof_checker_64_spp16.exr")));
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("64 x 64"), "{out}");
    assert!(out.contains("color_variance.R"));
    assert!(out.contains("spp"));
}

#[test]
fn compare_and_max_error() {
    let input = fixture("dof_checker_64_spp16.exr");
    let reference = fixture("dof_checker_64_ref.exr");
    let tmp = tmpdir("compare");
    let dir = tmp.path();
    let heat = dir.join("heat.png");
    let (code, out, err) = run(bin()
        .arg("compare")
        .arg(&input)
        .arg(&reference)
        .arg("--heatmap")
        .arg(&heat));
    assert_eq!(code, 0, "{err}");
    let rmse: f64 = out
        .lines()
        .find_map(|l| l.strip_prefix("rMSE"))
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert!(rmse > 0.0 && rmse < 1.0, "{out}");
    assert!(out.contains("SSIM") && out.contains("PSNR") && out.contains("relMSE"));
    assert!(heat.exists());
    let (code, _, err) = run(bin()
        .arg("compare")
        .arg(&input)
        .arg(&reference)
        .args(["--max-error", "0.000001"]));
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("exceeds"));
    let (code, _, _) = run(bin()
        .arg("compare")
        .arg(&input)
        .arg(&reference)
        .args(["--max-error", "10"]));
    assert_eq!(code, 0);
}

#[test]
fn denoise_none_gpu_and_cpu_agree_and_inputs_are_protected() {
    let input = fixture("dof_checker_64_spp16.exr");
    let tmp = tmpdir("denoise");
    let dir = tmp.path();
    let (g, c) = (dir.join("gpu.exr"), dir.join("cpu.exr"));
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(&g)
        .args(["--method", "none", "--png"])
        .arg(dir.join("p.png")));
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = run(bin().arg("denoise").arg(&input).arg("-o").arg(&c).args([
        "--method",
        "none",
        "--backend",
        "cpu",
    ]));
    assert_eq!(code, 0, "{err}");
    let (code, out, _) = run(bin().arg("compare").arg(&g).arg(&c));
    assert_eq!(code, 0);
    assert!(out.contains("rMSE    0.00000"), "{out}");
    assert!(dir.join("p.png").exists());
    // Never overwrite an input.
    let before = std::fs::read(&input).unwrap();
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(&input)
        .args(["--method", "none"]));
    assert_eq!(code, 2);
    assert!(err.contains("refusing to overwrite"), "{err}");
    assert_eq!(std::fs::read(&input).unwrap(), before);
    // Through a hard link (issue #14): the same file under another name is
    // not recognised, but the atomic write renames a new file over the
    // link's name, so the input's data stay as they were.
    let copy = dir.join("input_copy.exr");
    std::fs::copy(&input, &copy).unwrap();
    let link = dir.join("hard_link.exr");
    let _ = std::fs::remove_file(&link);
    std::fs::hard_link(&copy, &link).unwrap();
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&copy)
        .arg("-o")
        .arg(&link)
        .args(["--method", "none", "--quiet"]));
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read(&copy).unwrap(), before);
    assert_ne!(std::fs::read(&link).unwrap(), before);
    // AOS runs on the GPU and on the CPU, and the two agree.
    let out = dir.join("aos.exr");
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--method", "aos", "--quiet"]));
    assert_eq!(code, 0, "{err}");
    let cpu_out = dir.join("aos_cpu.exr");
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(&cpu_out)
        .args(["--method", "aos", "--backend", "cpu", "--quiet"]));
    assert_eq!(code, 0, "{err}");
    let (code, text, err) = run(bin().arg("compare").arg(&out).arg(&cpu_out));
    assert_eq!(code, 0, "{err}");
    let psnr: f64 = text
        .lines()
        .find_map(|l| l.strip_prefix("PSNR"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no PSNR in {text}"));
    assert!(psnr > 50.0, "AOS GPU vs CPU: PSNR {psnr}");
    let out = dir.join("apr.exr");
    // APR's own feature prefilter runs on the CPU backend only: on the GPU
    // it is a clear error.
    let (code, _, err) = run(bin().arg("denoise").arg(&input).arg("-o").arg(&out).args([
        "--method",
        "apr",
        "--opt",
        "apr.prefilter=on",
    ]));
    assert_eq!(code, 2);
    assert!(err.contains("CPU backend"), "{err}");
    assert!(!out.exists());
    // So is an option of a stage that is not built yet.
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--opt", "aos.order=3"]));
    assert_eq!(code, 2);
    assert!(err.contains("unknown option"), "{err}");
    assert!(!out.exists());
    // Options are validated.
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(dir.join("x.exr"))
        .args(["--method", "none", "--opt", "wlr.reject=perhaps"]));
    assert_eq!(code, 2);
    assert!(err.contains("wlr.reject"), "{err}");
}

#[test]
fn outputs_never_replace_inputs_or_each_other() {
    let tmp = tmpdir("outputs");
    let dir = tmp.path();
    let input = dir.join("in.exr");
    let reference = dir.join("ref.exr");
    std::fs::copy(fixture("dof_checker_64_spp16.exr"), &input).unwrap();
    std::fs::copy(fixture("dof_checker_64_ref.exr"), &reference).unwrap();
    let kept = |p: &Path, original: &str, what: &str| {
        assert_eq!(
            std::fs::read(p).unwrap(),
            std::fs::read(fixture(original)).unwrap(),
            "{what} changed {}",
            p.display()
        );
    };
    let refused = |cmd: &mut Command, what: &str, message: &str| {
        let (code, _, err) = run(cmd);
        assert_eq!(code, 2, "{what}: {err}");
        assert!(err.contains(message), "{what}: {err}");
    };
    let compare = || {
        let mut c = bin();
        c.arg("compare").arg(&input).arg(&reference);
        c
    };
    let render = || {
        let mut c = bin();
        c.args([
            "render", "--scene", "cornell", "--size", "16x16", "--spp", "4",
        ]);
        c
    };
    // compare's heat map on its image or reference.
    for target in [&input, &reference] {
        refused(
            compare().arg("--heatmap").arg(target),
            "compare --heatmap",
            "refusing to overwrite an input file",
        );
    }
    // A gate that can never fail is refused.
    refused(
        compare().args(["--max-error", "nan"]),
        "compare --max-error nan",
        "finite",
    );
    // Two outputs on one file.
    let same = dir.join("same.exr");
    refused(
        bin()
            .arg("denoise")
            .arg(&input)
            .arg("-o")
            .arg(&same)
            .arg("--sample-map")
            .arg(&same)
            .args(["--budget", "1000"]),
        "denoise -o X --sample-map X",
        "named for two outputs",
    );
    refused(
        render()
            .arg("-o")
            .arg(&same)
            .arg("--save-stats")
            .arg(dir.join(".").join("same.exr")),
        "render -o X --save-stats X",
        "named for two outputs",
    );
    assert!(!same.exists());
    // A folder is not an output file; a missing folder is made before the
    // work, as the README's `-o out/frame_####.exr` needs.
    refused(
        render().arg("-o").arg(dir),
        "render -o FOLDER",
        "a folder; name the output file",
    );
    let nested = dir.join("new").join("deeper").join("f_####.exr");
    let (code, _, err) = run(bin()
        .args(["render", "--scene", "moving_box", "--frames", "0..1"])
        .args(["--size", "16x16", "--spp", "4", "-o"])
        .arg(&nested));
    assert_eq!(code, 0, "{err}");
    assert!(dir.join("new/deeper/f_0000.exr").exists());
    refused(
        bin()
            .args(["render", "--scene", "no_such_scene", "-o"])
            .arg(&same),
        "render --scene TYPO",
        "neither a scene file nor a built-in scene (cornell,",
    );
    // bench's quality folder holds inputs.
    let q = dir.join("q").join("scene");
    std::fs::create_dir_all(&q).unwrap();
    std::fs::copy(&input, q.join("spp16.exr")).unwrap();
    std::fs::copy(&reference, q.join("reference.exr")).unwrap();
    refused(
        bin()
            .arg("bench")
            .arg("--quality")
            .arg(dir.join("q"))
            .args(["--methods", "none", "--markdown"])
            .arg(q.join("reference.exr")),
        "bench --markdown into --quality",
        "refusing to overwrite a file of the --quality folder",
    );
    kept(
        &q.join("reference.exr"),
        "dof_checker_64_ref.exr",
        "bench --markdown",
    );
    // A pipeline cache path that names a statistics file: the file is not
    // a cache, so the run goes on without one and leaves the file alone.
    let out = dir.join("out.exr");
    let (code, _, err) = run(bin()
        .arg("--pipeline-cache")
        .arg(&input)
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--method", "none"]));
    assert_eq!(code, 0, "{err}");
    assert!(out.exists());
    kept(&input, "dof_checker_64_spp16.exr", "--pipeline-cache");
    kept(&reference, "dof_checker_64_ref.exr", "compare");
    // Frame options that would fail every frame are refused before the first.
    let frames = dir.join("f");
    std::fs::create_dir_all(&frames).unwrap();
    std::fs::copy(&input, frames.join("f_0000.exr")).unwrap();
    refused(
        bin()
            .arg("denoise")
            .arg("--frames")
            .arg(frames.join("f_####.exr"))
            .arg("-o")
            .arg(dir.join("o_####.exr"))
            .args(["--temporal", "apr"]),
        "denoise --frames --temporal apr --method wlr",
        "runs with --method apr",
    );
    assert!(!dir.join("o_0000.exr").exists());
}

/// An option that would change nothing is refused, or warned about where
/// it names a method that does not run.
#[test]
fn options_without_effect_are_refused_or_warned() {
    let tmp = tmpdir("noeffect");
    let dir = tmp.path();
    let out = dir.join("o.exr");
    for (extra, message) in [
        (&["--max-spp", "8"][..], "--max-spp bounds --target-error"),
        (
            &["--pass-cap", "2"][..],
            "--pass-cap caps the adaptive passes",
        ),
    ] {
        let (code, _, err) = run(bin()
            .args([
                "render", "--scene", "cornell", "--size", "16x16", "--spp", "4",
            ])
            .args(extra)
            .arg("-o")
            .arg(&out));
        assert_eq!(code, 2, "{extra:?}: {err}");
        assert!(err.contains(message), "{extra:?}: {err}");
        assert!(!out.exists());
    }
    let denoise = |method: &str| {
        run(bin()
            .arg("denoise")
            .arg(fixture("dof_checker_64_spp16.exr"))
            .arg("-o")
            .arg(&out)
            .args(["--method", method, "--opt", "lp.error_mode=paper"]))
    };
    let (code, _, err) = denoise("wlr");
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("--opt lp.error_mode: method lp does not run"),
        "{err}"
    );
    // auto runs LP: no warning.
    let (code, _, err) = denoise("auto");
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("warning"), "{err}");
}

/// `render --save-stats` writes the statistics its reconstruction read:
/// `denoise` of the file gives the rendered image bit for bit, with the
/// G-buffer prefilter too (they were finalised on the host in f64, the
/// render's on the GPU in f32: 6e-4 rMSE apart at 32², 4 spp).
#[test]
fn saved_statistics_denoise_to_the_rendered_image() {
    let tmp = tmpdir("savedstats");
    let dir = tmp.path();
    for method in ["wlr", "lp"] {
        let (stats, rendered, denoised) = (
            dir.join(format!("{method}_s.exr")),
            dir.join(format!("{method}_r.exr")),
            dir.join(format!("{method}_d.exr")),
        );
        let (code, _, err) = run(bin()
            .args([
                "render", "--scene", "cornell", "--size", "24x16", "--spp", "4",
            ])
            .args(["--method", method, "--save-stats"])
            .arg(&stats)
            .arg("-o")
            .arg(&rendered));
        assert_eq!(code, 0, "{err}");
        let (code, _, err) = run(bin()
            .arg("denoise")
            .arg(&stats)
            .args(["--method", method, "-o"])
            .arg(&denoised));
        assert_eq!(code, 0, "{err}");
        let r = mcdenoise::io::read_rgb(&rendered).unwrap();
        let d = mcdenoise::io::read_rgb(&denoised).unwrap();
        assert_eq!(r.planes, d.planes, "{method}");
    }
}

#[test]
fn files_without_samples_or_with_non_finite_values() {
    let tmp = tmpdir("nosamples");
    let dir = tmp.path();
    let mut img = mcdenoise::io::read_stats(&fixture("dof_checker_64_spp16.exr")).unwrap();
    for v in img.get_mut(mcdenoise::Layer::Spp).unwrap()[0].iter_mut() {
        *v = 0.0;
    }
    let empty = dir.join("empty.exr");
    mcdenoise::io::write_stats(&empty, &img).unwrap();
    let out = dir.join("out.exr");
    let (code, _, err) = run(bin().arg("denoise").arg(&empty).arg("-o").arg(&out));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no pixel has a sample"), "{err}");
    assert!(!out.exists());
    // Non-finite values are named by layer and first pixel; a channel with
    // nothing else is refused.
    let mut img = mcdenoise::io::read_stats(&fixture("dof_checker_64_spp16.exr")).unwrap();
    img.get_mut(mcdenoise::Layer::Albedo).unwrap()[1][5 * 64 + 7] = f32::NAN;
    let nan = dir.join("nan.exr");
    mcdenoise::io::write_stats(&nan, &img).unwrap();
    let (code, _, err) = run(bin().arg("denoise").arg(&nan).arg("-o").arg(&out));
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("layer albedo: 1 non-finite values, the first at pixel (7, 5)"),
        "{err}"
    );
    img.get_mut(mcdenoise::Layer::Color).unwrap()[2].fill(f32::INFINITY);
    mcdenoise::io::write_stats(&nan, &img).unwrap();
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&nan)
        .arg("-o")
        .arg(dir.join("o2.exr")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("layer color, channel B: every value is non-finite"),
        "{err}"
    );
}

#[test]
fn denoise_lp_writes_error_and_debug_layers() {
    let input = fixture("dof_checker_64_spp16.exr");
    let reference = fixture("dof_checker_64_ref.exr");
    let tmp = tmpdir("lp");
    let dir = tmp.path();
    let (g, c) = (dir.join("gpu.exr"), dir.join("cpu.exr"));
    let (code, out, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(&g)
        .args(["--method", "lp", "--error", "--debug-layers", "--ref"])
        .arg(&reference));
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("rMSE"), "{out}");
    let meta = exr::meta::MetaData::read_from_file(&g, false).unwrap();
    let names: Vec<String> = meta.headers[0]
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    for want in [
        "color.R",
        "error.G",
        "debug.centre_pass",
        "debug.r_opt",
        "debug.rank",
        "debug.coverage",
        "debug.dmse.B",
    ] {
        assert!(
            names.iter().any(|n| n == want),
            "{want} missing from {names:?}"
        );
    }
    let (code, _, err) = run(bin().arg("denoise").arg(&input).arg("-o").arg(&c).args([
        "--method",
        "lp",
        "--backend",
        "cpu",
        "--opt",
        "lp.error_mode=paper",
    ]));
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .arg("-o")
        .arg(dir.join("x.exr"))
        .args(["--method", "lp", "--opt", "lp.error_mode=sometimes"]));
    assert_eq!(code, 2);
    assert!(err.contains("lp.error_mode"), "{err}");
}

#[test]
fn bad_files_give_clear_errors() {
    let tmp = tmpdir("bad");
    let dir = tmp.path();
    let text = dir.join("notes.exr");
    std::fs::write(&text, "this is not an image").unwrap();
    let (code, _, err) = run(bin().arg("inspect").arg(&text));
    assert_eq!(code, 2);
    assert!(err.contains("notes.exr"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let truncated = dir.join("half.exr");
    let bytes = std::fs::read(fixture("dof_checker_64_spp16.exr")).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let (code, _, err) = run(bin().arg("inspect").arg(&truncated));
    assert_eq!(code, 2);
    assert!(
        err.contains("half.exr") && !err.contains("panicked"),
        "{err}"
    );
    let (code, _, err) = run(bin().arg("inspect").arg(dir.join("missing.exr")));
    assert_eq!(code, 2);
    assert!(err.contains("missing.exr"), "{err}");
    // The OS error once, not once per level of the error chain.
    let (code, _, err) = run(bin()
        .args(["denoise", "-o"])
        .arg(dir.join("out.exr"))
        .arg(dir.join("missing.exr")));
    assert_eq!(code, 2);
    assert!(err.contains("missing.exr"), "{err}");
    assert_eq!(err.matches("os error").count(), 1, "{err}");
}

#[test]
fn help_lists_the_spec_options() {
    let (code, out, _) = run(bin().args(["denoise", "--help"]));
    assert_eq!(code, 0);
    for key in [
        "wlr.reject",
        "lp.error_mode",
        "lp.centre_test",
        "sampling.smooth",
        "--sample-map",
        "--budget",
        "--prefilter",
        "--pass",
        "--debug-layers",
        "--max-error",
        "--outliers",
    ] {
        assert!(out.contains(key), "--help lacks {key}");
    }
    // AOS is listed with its options.
    assert!(out.contains("aos.variance") && out.contains("aos.identity"));
}

#[test]
fn demo_runs() {
    let tmp = tmpdir("demo");
    let dir = tmp.path();
    let (code, out, err) = run(bin().arg("demo").arg("--out").arg(dir));
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("rMSE"), "{out}");
    assert!(dir.join("output.exr").exists() && dir.join("output.png").exists());
}

#[test]
fn no_vulkan_driver_gives_a_one_line_install_hint() {
    for args in [
        vec!["info"],
        vec!["demo", "--out", "/nonexistent-dir-for-mcdenoise/x"],
    ] {
        let (code, _, err) = run(bin()
            .args(&args)
            .env("VK_DRIVER_FILES", "/nonexistent-icd.json")
            .env("VK_ICD_FILENAMES", "/nonexistent-icd.json"));
        assert_eq!(code, 2, "{args:?}: {err}");
        if args[0] == "info" {
            assert_eq!(err.trim().lines().count(), 1, "{err}");
            assert!(err.contains("apt-get install mesa-vulkan-drivers"), "{err}");
        }
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// `mcdenoise compare a b | head -1`: a reader that goes away ends the
/// process quietly (SIGPIPE), never with a panic message.
#[test]
fn closed_stdout_is_not_a_panic() {
    use std::process::Stdio;
    let r = fixture("dof_checker_64_ref.exr");
    for _ in 0..3 {
        let mut child = bin()
            .args(["compare"])
            .arg(&r)
            .arg(&r)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// `denoise --frames` (issue #14's batches): every frame of the sequence
/// into the output pattern, one GPU device; a corrupt frame is reported by
/// number and path and skipped, the others are written (each as a single
/// run writes it, one frame with other content), the exit status is 1.
/// `--resume` skips the complete outputs and redoes a corrupt one; an
/// output pattern naming the inputs is refused.
#[test]
fn denoise_frames_continues_past_a_bad_frame_and_resumes() {
    let tmp = tmpdir("frames");
    let dir = tmp.path();
    let (inp, out) = (dir.join("in"), dir.join("out"));
    std::fs::create_dir_all(&inp).unwrap();
    std::fs::create_dir_all(&out).unwrap();
    for n in [1, 2, 3, 12] {
        std::fs::copy(
            fixture("dof_checker_64_spp16.exr"),
            inp.join(format!("f_{n:04}.exr")),
        )
        .unwrap();
    }
    std::fs::write(inp.join("f_0002.exr"), b"not an exr").unwrap();
    // Frame 3 differs from frames 1 and 12 (colour ×3, variance ×9), so
    // state carried over by the reused denoiser would show.
    let mut brighter = mcdenoise::io::read_stats(&fixture("dof_checker_64_spp16.exr")).unwrap();
    for (layer, k) in [
        (mcdenoise::Layer::Color, 3.0f32),
        (mcdenoise::Layer::ColorVariance, 9.0),
    ] {
        let planes: Vec<Vec<f32>> = brighter
            .get(layer)
            .unwrap()
            .iter()
            .map(|p| p.iter().map(|v| v * k).collect())
            .collect();
        brighter.set(layer, planes);
    }
    mcdenoise::io::write_stats(&inp.join("f_0003.exr"), &brighter).unwrap();
    let frames = |extra: &[&str]| {
        run(bin()
            .arg("denoise")
            .arg("--frames")
            .arg(inp.join("f_####.exr"))
            .arg("-o")
            .arg(out.join("o_####.exr"))
            .args(["--method", "lp"])
            .args(extra))
    };
    let (code, _, err) = frames(&[]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("4 frames"), "{err}");
    assert!(
        err.contains("3 denoised") && err.contains("1 failed"),
        "{err}"
    );
    assert!(
        err.contains("failed frame 2") && err.contains("f_0002.exr"),
        "{err}"
    );
    for n in [1, 3, 12] {
        let img = mcdenoise::io::read_rgb(&out.join(format!("o_{n:04}.exr"))).unwrap();
        assert_eq!((img.width, img.height), (64, 64));
    }
    assert!(!out.join("o_0002.exr").exists());
    // The same frame denoised alone gives the same image.
    let single = dir.join("single.exr");
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(inp.join("f_0003.exr"))
        .arg("-o")
        .arg(&single)
        .args(["--method", "lp"]));
    assert_eq!(code, 0, "{err}");
    let a = mcdenoise::io::read_rgb(&single).unwrap();
    let b = mcdenoise::io::read_rgb(&out.join("o_0003.exr")).unwrap();
    assert_eq!(a.planes, b.planes);
    // --resume: two complete outputs are skipped, a corrupt one is redone.
    std::fs::write(out.join("o_0012.exr"), b"truncated").unwrap();
    let (code, _, err) = frames(&["--resume"]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("1 denoised") && err.contains("2 skipped") && err.contains("1 failed"),
        "{err}"
    );
    assert!(mcdenoise::io::read_rgb(&out.join("o_0012.exr")).is_ok());
    // Once the bad frame is fixed, the sequence completes.
    std::fs::copy(fixture("dof_checker_64_spp16.exr"), inp.join("f_0002.exr")).unwrap();
    let (code, _, err) = frames(&["--resume"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("1 denoised") && err.contains("3 skipped"),
        "{err}"
    );
    // An output pattern that names input frames is refused up front, also
    // with --resume (a statistics file reads as a complete image).
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg("--frames")
        .arg(inp.join("f_####.exr"))
        .arg("-o")
        .arg(inp.join("f_####.exr"))
        .arg("--resume"));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("refusing to overwrite input frames"), "{err}");
    // A pattern without #, and --resume without --frames, are usage errors.
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg("--frames")
        .arg(inp.join("f.exr"))
        .arg("-o")
        .arg(out.join("o_####.exr")));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("run of #"), "{err}");
    let (code, _, _) = run(bin()
        .arg("denoise")
        .arg(inp.join("f_0001.exr"))
        .arg("-o")
        .arg(dir.join("x.exr"))
        .arg("--resume"));
    assert_eq!(code, 2);
}

/// `mcdenoise prefilter` writes readable statistics with every input layer;
/// in tiles (`--tile`) the file is byte-identical; `--opt` reaches the
/// stage (`gbf.second_below=32` filters the 16-spp fixture twice: other
/// features); it refuses to overwrite its input.
#[test]
fn prefilter_writes_the_same_statistics_whole_and_tiled() {
    let tmp = tmpdir("prefilter");
    let dir = tmp.path();
    let input = fixture("dof_checker_64_spp16.exr");
    let (whole, tiled, twice) = (
        dir.join("whole.exr"),
        dir.join("tiled.exr"),
        dir.join("twice.exr"),
    );
    for (out, extra) in [
        (&whole, vec![]),
        (&tiled, vec!["--tile", "24"]),
        (&twice, vec!["--opt", "gbf.second_below=32"]),
    ] {
        let (code, _, err) = run(bin()
            .args(["-q", "prefilter"])
            .arg(&input)
            .arg("-o")
            .arg(out)
            .args(&extra));
        assert_eq!(code, 0, "{err}");
    }
    let a = std::fs::read(&whole).unwrap();
    assert_eq!(a, std::fs::read(&tiled).unwrap(), "tiled output differs");
    let stats = mcdenoise::io::read_stats(&whole).unwrap();
    let raw = mcdenoise::io::read_stats(&input).unwrap();
    for (layer, _) in raw.layers() {
        assert!(stats.has(layer), "{} missing", layer.name());
    }
    // The prefilter replaced the normals.
    assert_ne!(
        stats.get(mcdenoise::image::Layer::Normal),
        raw.get(mcdenoise::image::Layer::Normal)
    );
    let twice = mcdenoise::io::read_stats(&twice).unwrap();
    assert_ne!(
        twice.get(mcdenoise::image::Layer::Normal),
        stats.get(mcdenoise::image::Layer::Normal)
    );
    let (code, _, err) = run(bin()
        .args(["-q", "prefilter"])
        .arg(&input)
        .arg("-o")
        .arg(&input));
    assert_ne!(code, 0);
    assert!(err.contains("refusing to overwrite"), "{err}");
}

/// `render --frames` renders an animated built-in scene's frames into the
/// output pattern, each frame from its own seed (frame 1 alone is the same
/// file as frame 1 of a longer run), and with --reference prints per-frame
/// rMSE and the sequence's temporal error, and --strip a PNG of the frames
/// side by side; a range past the scene's frames,
/// and a still scene, are clear errors.
#[test]
fn render_frames_writes_a_deterministic_sequence_with_its_metrics() {
    let tmp = tmpdir("frames");
    let dir = tmp.path();
    let render = |range: &str, out: &str| {
        let mut cmd = bin();
        cmd.env("MCDENOISE_CACHE", dir.join("cache"))
            .args([
                "render",
                "--scene",
                "moving_box",
                "--size",
                "16x16",
                "--spp",
                "4",
            ])
            .args([
                "--method",
                "wlr",
                "--reference",
                "16",
                "--frames",
                range,
                "-o",
            ])
            .arg(dir.join(out))
            .arg("--strip")
            .arg(dir.join(format!("{out}.png")));
        run(&mut cmd)
    };
    let (code, out, err) = render("0..=2", "a_##.exr");
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("temporal error"), "{out}");
    assert_eq!(
        out.lines()
            .filter(|l| l.trim_start().starts_with(['0', '1', '2']))
            .count(),
        3,
        "{out}"
    );
    for f in 0..3 {
        assert!(dir.join(format!("a_{f:02}.exr")).exists(), "frame {f}");
    }
    // The strip: three 16-pixel frames, 4 pixels apart.
    let png = std::fs::read(dir.join("a_##.exr.png")).unwrap();
    let width = u32::from_be_bytes(png[16..20].try_into().unwrap());
    assert_eq!(width, 3 * 16 + 2 * 4);
    let (code, _, err) = render("1..2", "b_##.exr");
    assert_eq!(code, 0, "{err}");
    let bytes = |p: &str| std::fs::read(dir.join(p)).unwrap();
    assert_eq!(bytes("a_01.exr"), bytes("b_01.exr"));
    assert_ne!(bytes("a_01.exr"), bytes("a_02.exr"));
    let (code, _, err) = render("20..30", "c_##.exr");
    assert_ne!(code, 0);
    assert!(err.contains("frames 0..24"), "{err}");
    let mut cmd = bin();
    cmd.args([
        "render", "--scene", "cornell", "--size", "16x16", "--frames", "0..2", "-o",
    ])
    .arg(dir.join("d_##.exr"));
    let (code, _, err) = run(&mut cmd);
    assert_ne!(code, 0);
    assert!(err.contains("no [animation]"), "{err}");
}

/// `--temporal lp`: `render --frames` filters the sequence (frame 0, which
/// starts the filter, is the plain render's; later frames differ from it,
/// and a rerun is bit-identical); `denoise --frames` restarts the history
/// at a gap in the numbering and says so; without `--frames`, or with
/// `--resume`, it is a usage error.
#[test]
fn temporal_filter_from_the_command_line() {
    let tmp = tmpdir("temporal");
    let dir = tmp.path();
    let render = |temporal: &str, out: &str| {
        let mut cmd = bin();
        cmd.args(["render", "--scene", "moving_box", "--size", "16x16"])
            .args(["--spp", "4", "--frames", "0..3", "--temporal", temporal])
            .arg("--save-stats")
            .arg(dir.join(format!("{out}_stats_##.exr")))
            .arg("-o")
            .arg(dir.join(format!("{out}_##.exr")));
        run(&mut cmd)
    };
    for (t, out) in [("off", "plain"), ("lp", "lp"), ("lp", "again")] {
        let (code, _, err) = render(t, out);
        assert_eq!(code, 0, "{err}");
    }
    let bytes = |p: &str| std::fs::read(dir.join(p)).unwrap();
    let rgb = |p: &str| mcdenoise::io::read_rgb(&dir.join(p)).unwrap().planes;
    assert_eq!(rgb("plain_00.exr"), rgb("lp_00.exr"));
    assert_ne!(rgb("plain_02.exr"), rgb("lp_02.exr"));
    assert_eq!(bytes("lp_02.exr"), bytes("again_02.exr"));
    // denoise --frames over the saved statistics, frame 1 missing.
    std::fs::remove_file(dir.join("lp_stats_01.exr")).unwrap();
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg("--frames")
        .arg(dir.join("lp_stats_##.exr"))
        .arg("-o")
        .arg(dir.join("d_##.exr"))
        .args(["--temporal", "lp"]));
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("frame 2: frame 1 is missing or failed: the temporal history starts again"),
        "{err}"
    );
    for args in [
        &["denoise", "x.exr", "-o", "y.exr", "--temporal", "lp"][..],
        &[
            "denoise",
            "--frames",
            "f_##.exr",
            "-o",
            "o_##.exr",
            "--temporal",
            "lp",
            "--resume",
        ],
        &[
            "render",
            "--scene",
            "cornell",
            "-o",
            "y.exr",
            "--temporal",
            "lp",
        ],
    ] {
        let (code, _, err) = run(bin().args(args));
        assert_eq!(code, 2, "{args:?}: {err}");
    }
}

/// `--temporal lp-smooth` (TEMPORAL-SMOOTH): `render --frames` writes every
/// frame once the range is rendered, the first one different from the
/// filter in frame order's (which is the frame alone's: the two-way filter
/// sees the frames after it); `denoise --frames` runs it over saved
/// statistics; the CPU backend, or a temporary directory that cannot hold
/// the kept frames, is a clear error.
#[test]
fn two_way_filter_from_the_command_line() {
    let tmp = tmpdir("two_way");
    let dir = tmp.path();
    for (t, out) in [("lp", "lp"), ("lp-smooth", "two")] {
        let (code, _, err) = run(bin()
            .args(["render", "--scene", "moving_box", "--size", "16x16"])
            .args(["--spp", "4", "--frames", "0..3", "--temporal", t])
            .arg("--save-stats")
            .arg(dir.join(format!("{out}_stats_##.exr")))
            .arg("-o")
            .arg(dir.join(format!("{out}_##.exr"))));
        assert_eq!(code, 0, "{err}");
    }
    let rgb = |p: &str| mcdenoise::io::read_rgb(&dir.join(p)).unwrap().planes;
    assert_ne!(rgb("lp_00.exr"), rgb("two_00.exr"));
    // The statistics waited for the two-way filter in a temporary file.
    for f in 0..3 {
        let bytes = |p: String| std::fs::read(dir.join(p)).unwrap();
        assert!(
            bytes(format!("lp_stats_{f:02}.exr")) == bytes(format!("two_stats_{f:02}.exr")),
            "frame {f}'s statistics"
        );
    }
    let denoise = |out: &str, extra: &[&str]| {
        run(bin()
            .arg("denoise")
            .arg("--frames")
            .arg(dir.join("two_stats_##.exr"))
            .arg("-o")
            .arg(dir.join(format!("{out}_##.exr")))
            .args(["--temporal", "lp-smooth"])
            .args(extra))
    };
    let (code, _, err) = denoise("d", &[]);
    assert_eq!(code, 0, "{err}");
    for f in 0..3 {
        assert!(dir.join(format!("d_{f:02}.exr")).exists(), "frame {f}");
    }
    assert_ne!(rgb("d_00.exr"), rgb("d_01.exr"));
    let (code, _, err) = denoise("cpu", &["--backend", "cpu"]);
    assert_ne!(code, 0);
    assert!(
        err.contains("--temporal lp-smooth keeps its frames on the GPU"),
        "{err}"
    );
    let missing = dir.join("no_such_dir");
    let (code, _, err) = run(bin()
        .env("TMPDIR", &missing)
        .args(["render", "--scene", "moving_box", "--size", "16x16"])
        .args(["--spp", "4", "--frames", "0..2", "--temporal", "lp-smooth"])
        .arg("-o")
        .arg(dir.join("tmp_##.exr")));
    assert_ne!(code, 0);
    assert!(
        err.contains(&format!(
            "{}: could not create the temporary file of the two-way filter's kept frames",
            missing.display()
        )),
        "{err}"
    );
    assert!(!dir.join("tmp_00.exr").exists());
}

/// `--temporal apr` (APR's window, §10.2): `render --frames` writes every
/// frame of the range, different from the frame-by-frame render, and
/// `denoise --frames` over the saved statistics writes the same frames;
/// a gap in the numbering starts a new sequence and says so; a frame that
/// does not read fails alone (exit status 1); another method, tiles or the
/// CPU backend is a clear error.
#[test]
fn temporal_window_from_the_command_line() {
    let tmp = tmpdir("window");
    let dir = tmp.path();
    let render = |temporal: &str, out: &str| {
        let mut cmd = bin();
        cmd.args(["render", "--scene", "moving_box", "--size", "24x24"])
            .args(["--spp", "4", "--frames", "0..4", "--method", "apr"])
            .args(["--temporal", temporal])
            .arg("--save-stats")
            .arg(dir.join(format!("{out}_stats_##.exr")))
            .arg("-o")
            .arg(dir.join(format!("{out}_##.exr")));
        run(&mut cmd)
    };
    for (t, out) in [("off", "plain"), ("apr", "apr")] {
        let (code, _, err) = render(t, out);
        assert_eq!(code, 0, "{err}");
    }
    let rgb = |p: &str| mcdenoise::io::read_rgb(&dir.join(p)).unwrap().planes;
    for f in 0..4 {
        assert_ne!(
            rgb(&format!("plain_{f:02}.exr")),
            rgb(&format!("apr_{f:02}.exr"))
        );
    }
    let denoise = |out: &str, extra: &[&str]| {
        run(bin()
            .arg("denoise")
            .arg("--frames")
            .arg(dir.join("apr_stats_##.exr"))
            .arg("-o")
            .arg(dir.join(format!("{out}_##.exr")))
            .args(["--method", "apr", "--temporal", "apr"])
            .args(extra))
    };
    let (code, _, err) = denoise("d", &[]);
    assert_eq!(code, 0, "{err}");
    for f in 0..4 {
        assert_eq!(
            rgb(&format!("apr_{f:02}.exr")),
            rgb(&format!("d_{f:02}.exr")),
            "frame {f}"
        );
    }
    std::fs::remove_file(dir.join("apr_stats_01.exr")).unwrap();
    let (code, _, err) = denoise("gap", &[]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("frame 2: not the next frame of the last one: a new sequence starts"),
        "{err}"
    );
    assert!(dir.join("gap_03.exr").exists() && !dir.join("gap_01.exr").exists());
    // A frame that does not read fails alone; the others are written.
    std::fs::write(dir.join("apr_stats_02.exr"), b"not an EXR").unwrap();
    let (code, _, err) = denoise("bad", &[]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("failed frame 2"), "{err}");
    assert!(dir.join("bad_00.exr").exists() && dir.join("bad_03.exr").exists());
    let (code, _, err) = denoise("tiled", &["--tile", "16"]);
    assert_ne!(code, 0);
    assert!(
        err.contains("--max-memory and --tile do not apply"),
        "{err}"
    );
    let (code, _, err) = denoise("cpu", &["--backend", "cpu"]);
    assert_ne!(code, 0);
    assert!(
        err.contains("--temporal apr keeps its frames on the GPU"),
        "{err}"
    );
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg("--frames")
        .arg(dir.join("apr_stats_##.exr"))
        .arg("-o")
        .arg(dir.join("w_##.exr"))
        .args(["--method", "wlr", "--temporal", "apr"]));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("runs with --method apr, not wlr"), "{err}");
}

/// An adaptive 32×32 render of `cornell` (seed 3, 8 spp) with `extra`
/// arguments, its statistics saved: `dir/<out>.exr`, `dir/<out>_stats.exr`.
fn render_small(dir: &Path, extra: &[&str], out: &str) -> (i32, String, String) {
    let mut cmd = bin();
    cmd.args([
        "render", "--scene", "cornell", "--size", "32x32", "--spp", "8",
    ])
    .args(["--adaptive", "--seed", "3"])
    .args(extra)
    .arg("--save-stats")
    .arg(dir.join(format!("{out}_stats.exr")))
    .arg("-o")
    .arg(dir.join(format!("{out}.exr")));
    run(&mut cmd)
}

/// `--pyramid` on `render` and `denoise`: the final reconstruction
/// changes, an adaptive render's passes do not (their sample counts are
/// the same), and a configuration it cannot run is a clear error.
#[test]
fn pyramid_from_the_command_line() {
    let tmp = tmpdir("pyramid");
    let dir = tmp.path();
    let render = |extra: &[&str], out: &str| render_small(dir, extra, out);
    for (extra, out) in [(&[][..], "plain"), (&["--pyramid"][..], "pyr")] {
        let (code, _, err) = render(extra, out);
        assert_eq!(code, 0, "{err}");
    }
    let rgb = |p: &str| mcdenoise::io::read_rgb(&dir.join(p)).unwrap().planes;
    let stats = |p: &str| mcdenoise::io::read_stats(&dir.join(p)).unwrap();
    assert!(rgb("plain.exr") != rgb("pyr.exr"));
    assert!(
        stats("plain_stats.exr").get(mcdenoise::Layer::Spp)
            == stats("pyr_stats.exr").get(mcdenoise::Layer::Spp)
    );
    // denoise --pyramid on the saved statistics changes the output too.
    for (extra, out) in [(&[][..], "d_plain.exr"), (&["--pyramid"][..], "d_pyr.exr")] {
        let (code, _, err) = run(bin()
            .arg("denoise")
            .arg(dir.join("pyr_stats.exr"))
            .arg("-o")
            .arg(dir.join(out))
            .args(extra));
        assert_eq!(code, 0, "{err}");
    }
    assert!(rgb("d_plain.exr") != rgb("d_pyr.exr"));
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(dir.join("pyr_stats.exr"))
        .arg("-o")
        .arg(dir.join("n.exr"))
        .args(["--pyramid", "--method", "none"]));
    assert_ne!(code, 0);
    assert!(err.contains("method none has none"), "{err}");
    assert!(!dir.join("n.exr").exists());
    // render checks before it traces anything.
    let (code, _, err) = render(&["--pyramid", "--method", "none"], "none");
    assert_ne!(code, 0);
    assert!(err.contains("method none has none"), "{err}");
    assert!(!dir.join("none_stats.exr").exists());
}

/// `--input-blend` on `render` and `denoise`: WLR's final reconstruction
/// (the stage on by default) changes with `--input-blend=off` and not with
/// `--input-blend`, an adaptive render's passes do not (their sample
/// counts are the same), AOS's output changes with `--input-blend=off`,
/// and method none is a clear error.
#[test]
fn input_blend_from_the_command_line() {
    let tmp = tmpdir("input_blend");
    let dir = tmp.path();
    let wlr = ["--method", "wlr"];
    let off = ["--method", "wlr", "--input-blend=off"];
    let explicit = ["--method", "wlr", "--input-blend"];
    for (extra, out) in [
        (&wlr[..], "plain"),
        (&off[..], "off"),
        (&explicit[..], "explicit"),
    ] {
        let (code, _, err) = render_small(dir, extra, out);
        assert_eq!(code, 0, "{err}");
    }
    let rgb = |p: &str| mcdenoise::io::read_rgb(&dir.join(p)).unwrap().planes;
    let stats = |p: &str| mcdenoise::io::read_stats(&dir.join(p)).unwrap();
    assert!(rgb("plain.exr") != rgb("off.exr"));
    assert!(rgb("plain.exr") == rgb("explicit.exr"));
    assert!(
        stats("plain_stats.exr").get(mcdenoise::Layer::Spp)
            == stats("off_stats.exr").get(mcdenoise::Layer::Spp)
    );
    let denoise = |extra: &[&str], out: &str| {
        run(bin()
            .arg("denoise")
            .arg(dir.join("plain_stats.exr"))
            .arg("-o")
            .arg(dir.join(out))
            .args(["--method", "aos"])
            .args(extra))
    };
    for (extra, out) in [
        (&[][..], "d_plain.exr"),
        (&["--input-blend=off"][..], "d_off.exr"),
    ] {
        let (code, _, err) = denoise(extra, out);
        assert_eq!(code, 0, "{err}");
    }
    assert!(rgb("d_plain.exr") != rgb("d_off.exr"));
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(dir.join("plain_stats.exr"))
        .arg("-o")
        .arg(dir.join("n.exr"))
        .args(["--input-blend", "--method", "none"]));
    assert_ne!(code, 0);
    assert!(err.contains("method none has none"), "{err}");
    assert!(!dir.join("n.exr").exists());
}

/// Statistics piped in (`denoise /dev/stdin`) denoise as the file does: the
/// header pre-read that warms the pipelines up must not consume a pipe.
#[test]
fn statistics_from_a_pipe_denoise_as_the_file() {
    let input = fixture("dof_checker_64_spp16.exr");
    let tmp = tmpdir("stdin");
    let (piped, file) = (tmp.path().join("piped.exr"), tmp.path().join("file.exr"));
    let mut child = bin()
        .args(["denoise", "/dev/stdin", "--method", "wlr", "-o"])
        .arg(&piped)
        .stdin(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let bytes = std::fs::read(&input).unwrap();
    let writer = std::thread::spawn(move || {
        use std::io::Write;
        // The reader may stop early on an error: a broken pipe is its story.
        let _ = stdin.write_all(&bytes);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let (code, _, err) = run(bin()
        .arg("denoise")
        .arg(&input)
        .args(["--method", "wlr", "-o"])
        .arg(&file));
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        std::fs::read(&piped).unwrap(),
        std::fs::read(&file).unwrap()
    );
}
