//! The examples a user copies from run as tests: `examples/embed.rs` (a raw
//! ash host embedding mcdenoise) under the validation layer, 0 messages.

use std::path::PathBuf;
use std::process::Command;

/// `target/<profile>/examples/<name>`, built by `cargo test` with the tests.
fn example(name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().unwrap().parent().unwrap();
    dir.join("examples").join(name)
}

fn validation_installed() -> bool {
    let entry = unsafe { ash::Entry::load() }.unwrap();
    unsafe { entry.enumerate_instance_layer_properties() }
        .unwrap()
        .iter()
        .any(|l| l.layer_name_as_c_str() == Ok(c"VK_LAYER_KHRONOS_validation"))
}

#[test]
fn embed_example_runs_clean() {
    let path = example("embed");
    assert!(path.exists(), "{} not built", path.display());
    let validate = validation_installed();
    let out = Command::new(&path)
        .env(
            "MCDENOISE_EMBED_VALIDATION",
            if validate { "1" } else { "0" },
        )
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("sample map: 12288 samples for a budget of 12288"),
        "{stdout}"
    );
    if validate {
        assert!(
            stdout.contains("validation layer: on, 0 messages"),
            "{stdout}"
        );
    }
}
