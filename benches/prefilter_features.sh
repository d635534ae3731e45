#!/usr/bin/env bash
# The G-buffer prefilter on the built-in motion-blur and depth-of-field scenes
# (issue #10): feature MSE (normal, albedo, depth) of the 16- and 64-spp
# statistics against a K-spp render's features, without and with the
# prefilter (`mcdenoise prefilter`), and each method's rMSE against the K-spp
# colour reference with --prefilter none and gbf. 128² by default.
#
#   bash benches/prefilter_features.sh [--reference K] [--size WxH] [--methods "wlr lp apr aos"]
set -euo pipefail
cd "$(dirname "$0")/.."
k=1024; size=128x128; methods="wlr lp apr aos"
while [ $# -gt 0 ]; do
  case "$1" in
    --reference) k=$2; shift 2;; --size) size=$2; shift 2;; --methods) methods=$2; shift 2;;
    *) echo "unknown argument $1" >&2; exit 2;;
  esac
done
cargo build --release --quiet -p mcdenoise-tools --bin feature_mse
bin=target/release/mcdenoise
work=target/prefilter_features; mkdir -p "$work"
export MCDENOISE_CACHE=${MCDENOISE_CACHE:-$work/cache}
fmse() { target/release/feature_mse "$@"; }
for s in motion dof; do
  ref_stats="$work/$s-$size-k$k-ref-stats.exr"
  [ -f "$ref_stats" ] || $bin render --quiet --scene "$s" --size "$size" --spp "$k" --seed 7 \
      --method none -o "$work/$s-$size-k$k-ref.exr" --save-stats "$ref_stats"
  for n in 16 64; do
    st="$work/$s-$n-stats.exr"
    $bin render --quiet --scene "$s" --size "$size" --spp "$n" --method none -o "$work/$s-$n.exr" --save-stats "$st"
    $bin prefilter --quiet "$st" -o "$work/$s-$n-gbf.exr"
    echo "## $s, $n spp (feature MSE against the $k-spp features)"
    fmse "$ref_stats" "$st" "$work/$s-$n-gbf.exr" | sed "s|$work/||"
    for m in $methods; do
      for p in none gbf; do
        r=$($bin render --quiet --scene "$s" --size "$size" --spp "$n" --method $m --prefilter $p \
             --reference "$k" -o "$work/$s-$n-$m-$p.exr" | awk '/^  rMSE/ {print $NF}')
        echo "$m --prefilter $p: rMSE $r"
      done
    done
  done
done
