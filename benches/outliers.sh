#!/usr/bin/env bash
# The outlier stage (spec §4.4, issues #11 and #41): rMSE of the input and of
# each method (WLR, LP, APR, AOS) with the stage off and on, and the image
# mean of the output relative to the input's, on the public scenes (4, 16,
# 64 spp) and on the built-in firefly scenes `glossy`, `fireflies` and
# `caustics` (256², the same spp levels, seeds 3 and 4, against the mean of
# two K-spp references whose own error is printed and taken off in the
# summary). Further arguments go to the tool, for example
# `--base-opt outliers.wide=0` to compare the stage with the spec's single
# window against its default.
#
#   bash benches/outliers.sh [--reference K] [--methods wlr,lp,apr,aos] [tool arguments]
#   (K = 1024 by default)
set -euo pipefail
cd "$(dirname "$0")/.."
k=1024
methods=wlr,lp,apr,aos
extra=()
while [ $# -gt 0 ]; do
  case $1 in
    --reference) k=$2; shift 2 ;;
    --methods) methods=$2; shift 2 ;;
    *) extra+=("$1"); shift ;;
  esac
done
cargo build --release --quiet -p mcdenoise-tools --bin outlier_table
pairs=()
for s in ../shared/data/scenes/*/; do
  for n in 4 16 64; do
    [ -f "$s/spp$n.exr" ] && pairs+=("$s/spp$n.exr=$s/reference.exr")
  done
done
target/release/outlier_table --methods "$methods" --scenes glossy,fireflies,caustics \
  --size 256x256 --spp 4,16,64 --seeds 3,4 --reference "$k" "${extra[@]}" "${pairs[@]}"
