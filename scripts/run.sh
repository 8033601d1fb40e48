#!/usr/bin/env bash
# Runs a built executable of the package with its environment set, e.g.
#   scripts/run.sh fit_cloud --input cloud.pcd --json
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
BIN_DIR="$BUILD_DIR/devel/lib/fruit_shape_completion"  # catkin puts executables here
if [ $# -lt 1 ]; then
  echo "usage: scripts/run.sh EXECUTABLE [ARGS...]" >&2
  echo "executables: $(ls "$BIN_DIR" 2>/dev/null | tr '\n' ' ')" >&2
  exit 2
fi
exe="$1"; shift
if [ ! -x "$BIN_DIR/$exe" ]; then
  "$ROOT/scripts/build.sh" >&2
fi
if [ ! -x "$BIN_DIR/$exe" ]; then
  echo "run.sh: no executable '$exe' in $BIN_DIR" >&2
  exit 2
fi
if [ -f "$BUILD_DIR/devel/setup.bash" ]; then
  # setup.bash reads the positional parameters as its own options (--extend, ...): source it
  # with none, then restore the executable's.
  args=("$@")
  set --
  # shellcheck disable=SC1091
  set +u; source "$BUILD_DIR/devel/setup.bash"; set -u
  set -- ${args[@]+"${args[@]}"}
fi
export FSC_SHARED_DATA="${FSC_SHARED_DATA:-$ROOT/../shared/data}"
exec "$BIN_DIR/$exe" "$@"
