//! The C library is built on the core only: none of the CLI's, the
//! renderer's or the file formats' dependencies reach an embedder
//! (`mcdenoise` with `default-features = false`).

use std::process::Command;

#[test]
fn embedders_pull_in_no_cli_renderer_or_file_dependencies() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["tree", "--offline", "-p", "mcdenoise-capi", "-e", "normal"])
        .args(["--prefix", "none", "--format", "{p}"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo tree");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tree = String::from_utf8_lossy(&out.stdout);
    let names: Vec<&str> = tree
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert!(names.contains(&"mcdenoise"), "{tree}");
    for banned in [
        "clap",
        "indicatif",
        "ctrlc",
        "png",
        "obvhs",
        "tobj",
        "toml",
        "exr",
        "serde_json",
        "anyhow",
    ] {
        assert!(
            !names.contains(&banned),
            "the C library pulls in {banned}:\n{tree}"
        );
    }
}
