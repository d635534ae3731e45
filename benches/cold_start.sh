#!/usr/bin/env bash
# Cold start per method (issue #13): the wall time of a whole `mcdenoise
# denoise` on a small committed fixture with an empty Mesa shader cache (as
# on a fresh machine: lavapipe compiles each pipeline at its first dispatch)
# and again with the cache that run filled. Their difference is the shader
# compile time a user waits for once.
#
#   bash benches/cold_start.sh [--methods "wlr lp apr aos"] [--bin PATH]
set -euo pipefail
cd "$(dirname "$0")/.."
methods="wlr lp apr aos"
bin=target/release/mcdenoise
while [ $# -gt 0 ]; do
    case "$1" in
        --methods) methods="$2"; shift 2 ;;
        --bin) bin="$2"; shift 2 ;;
        *) echo "usage: $0 [--methods \"wlr lp apr aos\"] [--bin PATH]" >&2; exit 2 ;;
    esac
done
[ -x "$bin" ] || cargo build --release --quiet
input=tests/fixtures/dof_checker_64_spp16.exr
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
run() { # method cache_dir -> seconds
    local t0 t1
    t0=$(date +%s.%N)
    MESA_SHADER_CACHE_DIR="$2" "$bin" denoise "$input" --method "$1" -o "$work/out.exr" -q >/dev/null
    t1=$(date +%s.%N)
    awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }'
}
echo "Cold start: $input (64x64), $("$bin" info 2>/dev/null | grep '^\*' | head -1 | sed 's/^\* //')"
echo
echo "| method | cold s (empty shader cache) | warm s | compile s |"
echo "|---|---:|---:|---:|"
for m in $methods; do
    cache="$work/cache-$m"
    mkdir -p "$cache"
    cold=$(run "$m" "$cache")
    warm=$(run "$m" "$cache")
    awk -v m="$m" -v c="$cold" -v w="$warm" 'BEGIN { printf "| %s | %.1f | %.1f | %.1f |\n", m, c, w, c - w }'
done
