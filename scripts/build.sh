#!/usr/bin/env bash
# Configures (once) and builds the package in build/ (Release unless BUILD_TYPE says otherwise).
# Usage: scripts/build.sh [extra make targets]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
BUILD_TYPE="${BUILD_TYPE:-Release}"
# catkin's helpers need Debian's python (the pyenv python3 on PATH lacks catkin_pkg).
export PATH="/usr/bin:$PATH"
# The upstream message packages, built once in their own small workspace, as a user's workspace
# holds them; the package builds on top of it.
UPSTREAM_DEVEL="$("$ROOT/scripts/upstream_ws.sh")"
set +u
# shellcheck disable=SC1091
source "$UPSTREAM_DEVEL/setup.bash"
set -u
# A configure that failed or was interrupted leaves a cache but no build files: run it again.
# The install prefix stays inside the build: catkin writes its workspace setup files to it
# whatever prefix an install is later given (the downstream test installs elsewhere); a build
# configured before with another prefix is moved to it.
if [ ! -f "$BUILD_DIR/Makefile" ] && [ ! -f "$BUILD_DIR/build.ninja" ]; then
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE="$BUILD_TYPE" -DCMAKE_INSTALL_PREFIX="$BUILD_DIR/install" \
        -DPYTHON_EXECUTABLE=/usr/bin/python3 >"$BUILD_DIR.configure.log" 2>&1 || {
    rm -f "$BUILD_DIR/CMakeCache.txt"; cat "$BUILD_DIR.configure.log" >&2; exit 1; }
elif ! grep -qxF "CMAKE_INSTALL_PREFIX:PATH=$BUILD_DIR/install" "$BUILD_DIR/CMakeCache.txt"; then
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_INSTALL_PREFIX="$BUILD_DIR/install" >"$BUILD_DIR.configure.log" 2>&1 || {
    cat "$BUILD_DIR.configure.log" >&2; exit 1; }
fi
JOBS="${JOBS:-$(nproc)}"
cmake --build "$BUILD_DIR" -j "$JOBS" ${1:+--target "$@"}
