#!/usr/bin/env bash
# Samples and rays per second of the built-in renderer, uniform against
# adaptive, on every built-in scene (or the ones named), from the GPU
# timestamps and traversal counters of `mcdenoise render` ("GPU: render …
# ksamples/s, … Mrays/s, … rays … per sample"); each run REPS times, the two
# kinds alternating, medians printed as a markdown table.
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
rate() { # scene, extra args: "ksamples/s Mrays/s rays-per-sample" of one run
  "$bin" render --scene "$1" --size "$size" --spp "$spp" --method "$method" "${@:2}" \
    -o "$out/x.exr" 2>&1 |
    sed -n 's/.*GPU: render [0-9.]* ms (\([0-9.]*\) ksamples\/s, \([0-9.]*\) Mrays\/s, \([0-9.]*\) rays .*/\1 \2 \3/p'
}
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
echo "| scene | uniform ksamples/s | adaptive ksamples/s | adaptive / uniform | uniform rays/sample | adaptive rays/sample | uniform Mrays/s | adaptive Mrays/s | adaptive / uniform |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
col() { awk -v k="$1" '{ print $k }'; }
for s in "${scenes[@]}"; do
  u=() a=()
  for _ in $(seq "$reps"); do
    u+=("$(rate "$s")")
    a+=("$(rate "$s" --adaptive)")
  done
  mu=$(printf '%s\n' "${u[@]}" | col 1 | median)
  ma=$(printf '%s\n' "${a[@]}" | col 1 | median)
  ru=$(printf '%s\n' "${u[@]}" | col 2 | median)
  ra=$(printf '%s\n' "${a[@]}" | col 2 | median)
  # Rays per sample: the same in every run of a kind.
  pu=$(printf '%s\n' "${u[@]}" | col 3 | head -1)
  pa=$(printf '%s\n' "${a[@]}" | col 3 | head -1)
  awk -v s="$s" -v u="$mu" -v a="$ma" -v ru="$ru" -v ra="$ra" -v pu="$pu" -v pa="$pa" \
    'BEGIN { printf "| %s | %.0f | %.0f | %.2f | %.1f | %.1f | %.2f | %.2f | %.2f |\n", s, u, a, a / u, pu, pa, ru, ra, ra / ru }'
done
