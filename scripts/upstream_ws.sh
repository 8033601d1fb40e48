#!/usr/bin/env bash
# Builds the upstream message packages (superellipsoid_msgs, pointcloud_roi_msgs) in a small
# catkin workspace and prints its devel space; the package's build sources that first, as a
# user's workspace would hold them. Sources: ../shared/upstream if present (offline, the pinned
# commits), else `vcs import` of integration/upstream.repos. Does nothing when already built.
#   scripts/upstream_ws.sh [WORKSPACE_DIR]      (default: build-upstream-ws)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WS="${1:-$ROOT/build-upstream-ws}"
export PATH="/usr/bin:$PATH"
if [ -f "$WS/devel/setup.bash" ] && [ -f "$WS/devel/include/superellipsoid_msgs/SuperellipsoidArray.h" ] &&
   [ -f "$WS/devel/include/pointcloud_roi_msgs/PointcloudWithRoi.h" ]; then
  echo "$WS/devel"; exit 0
fi
mkdir -p "$WS/src"
SHARED="$ROOT/../shared/upstream"
if [ -d "$SHARED/superellipsoid_msgs" ] && [ -d "$SHARED/pointcloud_roi_msgs" ]; then
  for p in superellipsoid_msgs pointcloud_roi_msgs; do rm -rf "$WS/src/$p"; cp -r "$SHARED/$p" "$WS/src/$p"; done
else
  command -v vcs >/dev/null || { echo "upstream_ws: vcstool is needed (apt-get install vcstool)" >&2; exit 2; }
  vcs import "$WS/src" < "$ROOT/integration/upstream.repos" >&2
fi
ln -sf /usr/share/catkin/cmake/toplevel.cmake "$WS/src/CMakeLists.txt"
cmake -S "$WS/src" -B "$WS/build" -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCATKIN_DEVEL_PREFIX="$WS/devel" \
      -DCMAKE_BUILD_TYPE=Release > "$WS/configure.log" 2>&1 || { cat "$WS/configure.log" >&2; exit 1; }
cmake --build "$WS/build" -j "$(nproc)" > "$WS/build.log" 2>&1 || { cat "$WS/build.log" >&2; exit 1; }
echo "$WS/devel"
