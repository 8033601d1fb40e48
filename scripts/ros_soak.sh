#!/usr/bin/env bash
# The soak over ROS (not in CI): fruit_mapping_node hosting the plugin for SECONDS (default 600)
# under 30 Hz organized 640x480 camera clouds, 10 Hz planner views, clear/save/load_map every
# 4 s from another thread, and tf that goes missing (5 %) or stale (5 %). Writes
# results/soak_ros/rss.csv and summary.json (RSS, service results, the host's diagnostics:
# counters and insertView latency).
#   scripts/ros_soak.sh [SECONDS]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECONDS_TO_RUN="${1:-600}"
"$ROOT/scripts/build.sh" >/dev/null
export PATH="/usr/bin:$PATH"
OUT="$ROOT/results/soak_ros"
mkdir -p "$OUT"
set +u
# shellcheck disable=SC1091
source "$ROOT/build/devel/setup.bash"
set -u
# roslaunch starts a master if none runs; the driver is required: its end ends the launch.
roslaunch fruit_shape_completion soak.launch duration:="$SECONDS_TO_RUN" out_csv:="$OUT/rss.csv" \
  > "$OUT/roslaunch.log" 2>&1 || true
grep '^{"seconds"' "$OUT/roslaunch.log" | tail -1 > "$OUT/summary.json" || true
if [ -s "$OUT/summary.json" ]; then cat "$OUT/summary.json"; else echo "ros_soak: no summary; see $OUT/roslaunch.log" >&2; exit 1; fi
