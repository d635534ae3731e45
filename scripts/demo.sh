#!/usr/bin/env bash
# The main job (no files needed): an adaptive render of the built-in scene
# `mix` at 256x256 and 16 spp on average — pass 0 uniform, five passes where
# WLR's sample map sends them, the final WLR reconstruction — written as EXR
# and PNG, with the comparison to a 512-spp reference (rendered once, then
# cached in ~/.cache/mcdenoise) and a figure (out/demo/figure.png: uniform
# input at the same spp, samples per pixel, reconstruction, estimated error,
# reference). See README.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --release --quiet
mkdir -p out/demo
exec target/release/mcdenoise render --scene mix --size 256x256 --spp 16 --adaptive \
  --method wlr -o out/demo/render.exr --png out/demo/render.png \
  --save-stats out/demo/render_stats.exr --figure out/demo/figure.png --reference 512 "$@"
