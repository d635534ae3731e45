#!/usr/bin/env bash
# Equal-sample and equal-time comparison of adaptive and uniform sampling on
# the built-in scenes, for every method, against references whose own error
# is estimated from independent seeds (tools/src/bin/equal_samples.rs says how).
#
#   bash benches/equal_samples.sh [--scenes a,b] [--size 256x256] [--spp 16,64]
#        [--methods wlr,lp,apr,aos] [--reference 4096] [--reference-renders 2]
#        [--oidn] [--equal-time] [--passes N]
#        [--json out.json] [--opt KEY=VALUE ...]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet -p mcdenoise-tools --bin equal_samples
exec target/release/equal_samples "$@"
