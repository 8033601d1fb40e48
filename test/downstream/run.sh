#!/usr/bin/env bash
# Installs the built package into a fresh prefix, builds this downstream package against that
# prefix only (not the source or devel space), with the README's snippet compiled in, then runs
# one view through the plugin loaded by name. usage: run.sh BUILD_DIR README
set -euo pipefail
BUILD_DIR="$1"; README="$2"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
WORK="$(mktemp -d)"
trap 'kill $ROSCORE_PID 2>/dev/null || true; rm -rf "$WORK"' EXIT
ROSCORE_PID=""
export PATH="/usr/bin:$PATH"

cmake --install "$BUILD_DIR" --prefix "$WORK/install" > "$WORK/install.log"

# The README's snippet: the ```cpp block after the "use-from-your-planner" marker.
mkdir -p "$WORK/snippet"
awk '/snippet: use-from-your-planner/{f=1; next} f && /^```cpp/{g=1; next} g && /^```/{exit} g' "$README" > "$WORK/snippet/all.inc"
[ -s "$WORK/snippet/all.inc" ] || { echo "no use-from-your-planner snippet in $README" >&2; exit 1; }
grep '^#include' "$WORK/snippet/all.inc" > "$WORK/snippet/includes.inc" || true
grep -v '^#include' "$WORK/snippet/all.inc" > "$WORK/snippet/body.inc"

# The user's workspace holds the upstream message packages too (scripts/upstream_ws.sh).
UPSTREAM_DEVEL="$("$HERE/../../scripts/upstream_ws.sh")"
export CMAKE_PREFIX_PATH="$WORK/install:$UPSTREAM_DEVEL"
export ROS_PACKAGE_PATH="$WORK/install/share:$UPSTREAM_DEVEL/share:/usr/share"
export LD_LIBRARY_PATH="$WORK/install/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
cmake -S "$HERE" -B "$WORK/build" -DPYTHON_EXECUTABLE=/usr/bin/python3 -DSNIPPET_DIR="$WORK/snippet" \
      -DCATKIN_DEVEL_PREFIX="$WORK/build/devel" > "$WORK/configure.log" || { cat "$WORK/configure.log"; exit 1; }
cmake --build "$WORK/build" -- -j2 > "$WORK/build.log" 2>&1 || { cat "$WORK/build.log"; exit 1; }

export ROS_MASTER_URI="http://localhost:$((20000 + RANDOM % 20000))"
export ROS_HOME="$WORK/ros_home"
roscore -p "${ROS_MASTER_URI##*:}" > "$WORK/roscore.log" 2>&1 &
ROSCORE_PID=$!
for _ in $(seq 100); do rosparam list > /dev/null 2>&1 && break; sleep 0.2; done
"$WORK/build/devel/lib/fsc_downstream_check/downstream_check"
