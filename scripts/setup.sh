#!/usr/bin/env bash
# Installs what mcdenoise needs on Debian/Ubuntu, idempotently and quietly:
# the Vulkan loader and Mesa's drivers (lavapipe, the software device), and
# with --tests the Khronos validation layer. Needs root only when something
# is missing. Rust (cargo >= 1.80) is expected to be installed (rustup).
set -euo pipefail
pkgs=(mesa-vulkan-drivers libvulkan1)
[ "${1:-}" = "--tests" ] && pkgs+=(vulkan-validationlayers libvulkan-dev)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" != 0 ]; then
    echo "setup: missing packages ${missing[*]}; run as root or: sudo apt-get install ${missing[*]}" >&2
    exit 1
  fi
  echo "setup: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
if ! command -v cargo >/dev/null 2>&1; then
  echo "setup: cargo not found; install Rust 1.80 or newer (https://rustup.rs), then run again" >&2
  exit 1
fi
