#!/usr/bin/env bash
# The main job on the built-in example (no files needed): see README.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --release --quiet
exec target/release/mcdenoise demo --out out/demo "$@"
