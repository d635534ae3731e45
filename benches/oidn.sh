#!/usr/bin/env bash
# OIDN (Intel Open Image Denoise 2.5, via pyoidn) on render-statistics EXRs:
# installs pyoidn, OpenEXR and numpy into a virtual environment under
# target/oidn-venv (once, quietly), then denoises each IN.exr into OUT.exr.
#   bash benches/oidn.sh IN.exr OUT.exr [IN.exr OUT.exr ...]
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/oidn-venv
if ! "$venv/bin/python" -c "import pyoidn, OpenEXR, numpy" 2>/dev/null; then
  if ! python3 -m venv --help >/dev/null 2>&1 || ! python3 -c "import ensurepip" 2>/dev/null; then
    if [ "$(id -u)" = 0 ]; then
      DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null
    else
      echo "oidn.sh: python3-venv is missing (apt-get install python3-venv)" >&2; exit 1
    fi
  fi
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check "pyoidn==2.5.1.0" OpenEXR numpy
fi
exec "$venv/bin/python" benches/oidn_denoise.py "$@"
