#!/usr/bin/env bash
# Takes the README's rviz screenshot without a display: Xvfb, the demo launch (planner with the
# superellipsoid plugin on a scene), rviz with config/fruit_mapping.rviz, then a grab of the
# virtual screen once the planner has run for a while.
#   scripts/screenshot.sh [OUT.png] [scene] [wait_seconds]
# Needs rviz, xvfb, x11-apps and imagemagick: scripts/setup.sh --rviz
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/docs/images/rviz_demo.png}"
SCENE="${2:-procedural}"
WAIT="${3:-60}"
"$ROOT/scripts/setup.sh" --rviz
"$ROOT/scripts/build.sh" sim_planner_node >/dev/null
export PATH=/usr/bin:$PATH
set +u; source "$ROOT/build/devel/setup.bash"; set -u
export FSC_SHARED_DATA="${FSC_SHARED_DATA:-$ROOT/../shared/data}"

DISPLAY_NUM=":$((90 + RANDOM % 9))"
export ROS_MASTER_URI="http://localhost:$((12000 + RANDOM % 1000))"
export ROS_HOME="$(mktemp -d)"
# Software GL: Xvfb has no GPU.
export LIBGL_ALWAYS_SOFTWARE=1
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; [ -n "${KEEP_LOG:-}" ] && cp "$ROS_HOME/launch.log" /tmp/screenshot_launch.log; rm -rf "$ROS_HOME"; }
trap cleanup EXIT

Xvfb "$DISPLAY_NUM" -screen 0 1280x800x24 +extension GLX -nolisten tcp >/dev/null 2>&1 &
pids+=($!)
export DISPLAY="$DISPLAY_NUM"
sleep 2
roslaunch fruit_shape_completion demo.launch scene:="$SCENE" rviz:=true realtime_factor:=1.0 \
  -p "${ROS_MASTER_URI##*:}" >"$ROS_HOME/launch.log" 2>&1 &
pids+=($!)
sleep "$WAIT"
mkdir -p "$(dirname "$OUT")"
# The 3D view only: rviz lays the window out the same way on this fixed-size screen.
xwd -root -silent -display "$DISPLAY" | /usr/bin/convert xwd:- -crop 820x708+364+62 +repage "$OUT"
echo "screenshot: $OUT"
