//! What the tools share: method names on the command line, and OIDN.

use std::path::PathBuf;

use anyhow::{bail, Context};
use mcdenoise::Method;

/// A method by name, for clap's `value_parser` (`--methods wlr,lp`).
pub fn parse_method(name: &str) -> Result<Method, String> {
    Method::from_name(name).ok_or_else(|| format!("no method {name:?}"))
}

/// Runs OIDN 2.5 (`benches/oidn.sh`: albedo and normal, installed on first
/// use) on `(statistics EXR, output EXR)` pairs, from the repository root.
pub fn oidn(pairs: &[(PathBuf, PathBuf)]) -> anyhow::Result<()> {
    let mut cmd = std::process::Command::new("bash");
    cmd.arg("benches/oidn.sh");
    for (i, o) in pairs {
        cmd.arg(i).arg(o);
    }
    let out = cmd.output().context("running benches/oidn.sh")?;
    if !out.status.success() {
        bail!("oidn.sh failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    Ok(())
}
