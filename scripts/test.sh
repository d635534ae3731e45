#!/usr/bin/env bash
# The whole test suite, on lavapipe with the validation layer (see README).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --tests
# Tests pick the best device; on a machine with a real GPU set MCDENOISE_DEVICE.
# The validation layer is required: without it every GPU test fails.
export MCDENOISE_REQUIRE_VALIDATION=1
# The API docs' links must resolve (the whole suite only, not a filtered run).
if [ $# -eq 0 ]; then
  RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --lib --quiet
fi
# The library and its C API (capi/: the C example is compiled and run).
exec cargo test --no-fail-fast -p mcdenoise -p mcdenoise-capi "$@"
