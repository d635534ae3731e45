#!/usr/bin/env bash
# The outlier stage (spec §4.4, issue #11): rMSE of the input and of each
# method (WLR, LP, APR, AOS) with the stage off and on, and the image mean of
# the output relative to the input's, on the public scenes (4, 16, 64 spp)
# and on the built-in firefly scene `glossy` (128², same spp levels, against
# a K-spp reference).
#
#   bash benches/outliers.sh [--reference K] [--methods wlr,lp,apr,aos]
#   (K = 1024 by default)
set -euo pipefail
cd "$(dirname "$0")/.."
k=1024
methods=wlr,lp,apr,aos
while [ $# -gt 0 ]; do
  case $1 in
    --reference) k=$2; shift 2 ;;
    --methods) methods=$2; shift 2 ;;
    *) echo "outliers.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
cargo build --release --quiet -p mcdenoise-tools --bin outlier_table
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
target/release/outlier_table --methods "$methods" "${pairs[@]}"
