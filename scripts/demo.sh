#!/usr/bin/env bash
# The main job on a built-in default (no files needed):
#  1. demo_fit: synthetic fruits seen fully, half and a quarter are fitted with superellipsoids
#     and compared with their known shape;
#  2. demo_mapping: a depth camera views a leafy fruit cluster; every view goes through the
#     TSDF fruit map, surface extraction, clustering and fitting.
# Arguments go to both (e.g. --seed 5).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/build.sh" demo_fit demo_mapping >/dev/null
"$ROOT/scripts/run.sh" demo_fit "$@"
echo
exec "$ROOT/scripts/run.sh" demo_mapping "$@"
