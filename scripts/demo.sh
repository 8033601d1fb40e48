#!/usr/bin/env bash
# The main job on a built-in default (no files needed): the viewpoint planner maps the fruits of
# a procedural glasshouse for 90 simulated seconds, twice, with the superellipsoid estimator as
# its plugin, and prints the Old (ROI octree boxes) vs SE (superellipsoids) table of the paper.
# Results (results.json, per-view CSV, a plot if matplotlib is there) go to results/demo/.
# Arguments replace the defaults, e.g.: scripts/demo.sh --scene procedural:5 --trials 4 --duration 180
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/build.sh" run_trials >/dev/null
OUT="$ROOT/results/demo"
if [ $# -eq 0 ]; then
  set -- --scene procedural --trials 2 --duration 90
fi
"$ROOT/scripts/run.sh" run_trials --out "$OUT" "$@"
if /usr/bin/python3 -c "import matplotlib, numpy" 2>/dev/null; then
  /usr/bin/python3 "$ROOT/scripts/plot_results.py" "$OUT" >/dev/null && echo "plot: $OUT/fruits_over_time.png"
fi
