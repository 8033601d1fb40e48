#!/usr/bin/env bash
# Builds everything and runs every test; ends with the ctest summary, exits non-zero on failure.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
"$ROOT/scripts/build.sh"
export FSC_SHARED_DATA="${FSC_SHARED_DATA:-$ROOT/../shared/data}"
# rostest and catkin's test wrappers need Debian's python (the pyenv python3 lacks catkin_pkg).
export PATH="/usr/bin:$PATH"
cd "$BUILD_DIR"
ctest --output-on-failure -j "$(nproc)" --timeout 600
