#!/usr/bin/env bash
# Soak test (not in CI): 10 000 views into one estimator, never reset, resident memory sampled
# every 100 views; figures in results/soak/soak.csv, a summary line at the end.
#   scripts/soak.sh [--views N] [--scene FILE|procedural] ...   (soak's own options)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/build.sh" soak >/dev/null
mkdir -p "$ROOT/results/soak"
"$ROOT/scripts/run.sh" soak --out "$ROOT/results/soak/soak.csv" "$@"
