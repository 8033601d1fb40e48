#!/usr/bin/env bash
# The main job on a built-in default: synthetic, partially seen fruits are fitted with
# superellipsoids and compared with their known shape. Extra arguments go to demo_fit.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/build.sh" demo_fit >/dev/null
exec "$ROOT/scripts/run.sh" demo_fit "$@"
