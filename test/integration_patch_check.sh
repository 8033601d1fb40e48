#!/usr/bin/env bash
# The integration patch applies cleanly to the pinned upstream planner (../shared/upstream).
# Exit 77 (skipped) when the upstream copy is absent.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
UPSTREAM="${FSC_SHARED_DATA:-$ROOT/../shared/data}/../upstream/roi_viewpoint_planner"
if [ ! -f "$UPSTREAM/src/viewpoint_planner.cpp" ]; then
  echo "skipped: no upstream roi_viewpoint_planner at $UPSTREAM (../shared is absent)"
  exit 77
fi
COPY="$(mktemp -d)"
trap 'rm -rf "$COPY"' EXIT
cp -r "$UPSTREAM/." "$COPY/"
chmod -R u+w "$COPY"
# --fuzz=0: no fuzzy matching; a hunk that needs it counts as not applying cleanly.
patch -p1 --fuzz=0 --no-backup-if-mismatch -d "$COPY" -i "$ROOT/integration/roi_viewpoint_planner.patch"
if find "$COPY" -name '*.rej' -o -name '*.orig' | grep -q .; then
  echo "the patch left rejects or offsets" >&2
  exit 1
fi
grep -q "shapeEstimators->insertView" "$COPY/src/viewpoint_planner.cpp"
grep -q "shapeEstimators->targetRound()" "$COPY/src/viewpoint_samplers.cpp"
grep -qF "shapeTargets.viewGain(origin, dirVec, *planner->planningTree)" "$COPY/src/viewpoint_samplers.cpp"
echo "integration patch applies cleanly to $UPSTREAM"
