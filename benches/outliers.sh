#!/usr/bin/env bash
# The outlier stage (spec §4.4, issue #11): rMSE of the input and of WLR,
# LP and APR with the stage off and on, and the image mean of the output relative to
# the input's, on the public scenes (4, 16, 64 spp) and on the built-in
# firefly scene `glossy` (128², same spp levels, against a K-spp reference).
#
#   bash benches/outliers.sh [--reference K]      (K = 1024 by default)
set -euo pipefail
cd "$(dirname "$0")/.."
k=1024
[ "${1:-}" = "--reference" ] && k=$2
cargo build --release --quiet --example outlier_table
bin=target/release/mcdenoise
work=target/outliers; mkdir -p "$work"
export MCDENOISE_CACHE=${MCDENOISE_CACHE:-$work/cache}
pairs=()
for s in ../shared/data/scenes/*/; do
  for n in 4 16 64; do
    [ -f "$s/spp$n.exr" ] && pairs+=("$s/spp$n.exr=$s/reference.exr")
  done
done
for n in 4 16 64; do
  out=$($bin render --quiet --scene glossy --size 128x128 --spp $n --method none \
        --reference "$k" -o "$work/glossy-$n-none.exr" --save-stats "$work/glossy_spp$n.exr")
  pairs+=("$work/glossy_spp$n.exr=$(echo "$out" | awk '/^reference:/ {print $2}')")
done
target/release/examples/outlier_table "${pairs[@]}"
