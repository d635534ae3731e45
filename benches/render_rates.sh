#!/usr/bin/env bash
# Samples per second of the built-in renderer, uniform against adaptive, on
# every built-in scene (or the ones named), from the GPU timestamps of
# `mcdenoise render` ("GPU: render … ksamples/s"); each run REPS times, the
# two kinds alternating, medians printed as a markdown table.
#   bash benches/render_rates.sh [--size 256x256] [--spp 16] [--reps 3] [--method wlr] [scene …]
set -euo pipefail
cd "$(dirname "$0")/.."
size=256x256 spp=16 reps=3 method=wlr scenes=()
while [ $# -gt 0 ]; do
  case "$1" in
    --size) size=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --reps) reps=$2; shift 2 ;;
    --method) method=$2; shift 2 ;;
    *) scenes+=("$1"); shift ;;
  esac
done
cargo build --release --quiet --bin mcdenoise
bin=target/release/mcdenoise
if [ ${#scenes[@]} -eq 0 ]; then
  mapfile -t scenes < <("$bin" render --list-scenes | awk '/^[a-z]/ { print $1 }')
fi
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
rate() { # scene, extra args: ksamples/s of one run
  "$bin" render --scene "$1" --size "$size" --spp "$spp" --method "$method" "${@:2}" \
    -o "$out/x.exr" 2>&1 | sed -n 's/.*GPU: render [0-9.]* ms (\([0-9.]*\) ksamples\/s).*/\1/p'
}
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
echo "| scene | uniform ksamples/s | adaptive ksamples/s | adaptive / uniform |"
echo "|---|---:|---:|---:|"
for s in "${scenes[@]}"; do
  u=() a=()
  for _ in $(seq "$reps"); do
    u+=("$(rate "$s")")
    a+=("$(rate "$s" --adaptive)")
  done
  mu=$(printf '%s\n' "${u[@]}" | median)
  ma=$(printf '%s\n' "${a[@]}" | median)
  awk -v s="$s" -v u="$mu" -v a="$ma" 'BEGIN { printf "| %s | %.0f | %.0f | %.2f |\n", s, u, a, a / u }'
done
