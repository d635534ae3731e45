#!/usr/bin/env bash
# Equal-sample comparison (issue #10): per built-in scene and average spp,
# rMSE against a K-spp reference of
#   (a) uniform sampling, no reconstruction (the Monte Carlo mean),
#   (b) uniform sampling + each method,
#   (c) adaptive sampling (spec §9.3) + each method,
#   (d) OIDN 2.5.1 (albedo + normal) on the same uniform samples.
# Every run of a scene uses the same seed, so (a), (b) and (d) see the same
# samples. Prints a Markdown table.
#
#   bash benches/equal_samples.sh [--size WxH] [--spp "16 64"] [--reference K]
#        [--scenes "cornell dof motion soft_shadows glossy mix"] [--methods "wlr lp"] [--no-oidn]
#        [--opt KEY=VALUE ...]   (passed to every reconstructing render)
set -euo pipefail
cd "$(dirname "$0")/.."
size=256x256; spps="16 64"; k=4096; scenes="cornell dof motion soft_shadows glossy mix"
methods="wlr lp"; oidn=1; opts=()
while [ $# -gt 0 ]; do
  case "$1" in
    --size) size=$2; shift 2;; --spp) spps=$2; shift 2;; --reference) k=$2; shift 2;;
    --scenes) scenes=$2; shift 2;; --methods) methods=$2; shift 2;; --no-oidn) oidn=0; shift;;
    --opt) opts+=(--opt "$2"); shift 2;;
    *) echo "unknown argument $1" >&2; exit 2;;
  esac
done
cargo build --release --quiet
bin=target/release/mcdenoise
work=target/equal_samples; mkdir -p "$work"
export MCDENOISE_CACHE=${MCDENOISE_CACHE:-$work/cache}
# rMSE of the method column (last number of the rMSE line) and of the MC mean.
rmse() { awk '/^  rMSE/ {print $NF}'; }
rmse_mc() { awk '/^  rMSE/ {print $(NF-1)}'; }
header="| scene | spp | uniform MC |"
for m in $methods; do header+=" uniform $m | adaptive $m | adaptive/uniform $m |"; done
[ $oidn = 1 ] && header+=" OIDN (uniform) |"
echo "$header"
echo "$header" | sed 's/[^|]*|/---|/g; s/^---|/|/'
for s in $scenes; do
  for n in $spps; do
    row="| $s | $n |"
    out=$($bin render --quiet --scene "$s" --size "$size" --spp "$n" --method none \
          --reference "$k" -o "$work/$s-$n-none.exr" --save-stats "$work/$s-$n-stats.exr")
    ref=$(echo "$out" | awk '/^reference:/ {print $2}')
    row+=" $(echo "$out" | rmse) |"
    for m in $methods; do
      u=$($bin render --quiet --scene "$s" --size "$size" --spp "$n" --method "$m" "${opts[@]}" \
            --reference "$k" -o "$work/$s-$n-$m-uniform.exr" | rmse)
      a=$($bin render --quiet --scene "$s" --size "$size" --spp "$n" --method "$m" --adaptive "${opts[@]}" \
            --reference "$k" -o "$work/$s-$n-$m-adaptive.exr" | rmse)
      row+=" $u | $a | $(awk -v a="$a" -v u="$u" 'BEGIN {printf "%.2f", a/u}') |"
    done
    if [ $oidn = 1 ]; then
      bash benches/oidn.sh "$work/$s-$n-stats.exr" "$work/$s-$n-oidn.exr" >/dev/null
      o=$($bin compare "$work/$s-$n-oidn.exr" "$ref" | awk '/^rMSE/ {print $2}')
      row+=" $o |"
    fi
    echo "$row"
  done
done
