#!/usr/bin/env bash
# The README's picture, docs/images/adaptive.png: the built-in scene
# `cornell` at 192x192, 16 spp on average, rendered adaptively and
# reconstructed with WLR, with (left to right) a uniform render of the same
# samples per pixel and seed, where the adaptive passes sent their samples,
# the reconstruction, its estimated error, and a 2048-spp reference
# (rendered once, then cached in ~/.cache/mcdenoise).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --release --quiet
mkdir -p docs/images out/figure
exec target/release/mcdenoise render --scene cornell --size 192x192 --spp 16 --adaptive \
  --method wlr --reference 2048 -o out/figure/render.exr \
  --figure docs/images/adaptive.png "$@"
