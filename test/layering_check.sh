#!/usr/bin/env bash
# What a planner loads (the plugin library and what it links) must not pull in the simulator:
# fails if any of its shared libraries is Assimp, Embree, libpng, yaml-cpp or the package's sim.
set -euo pipefail
lib="$1"
[ -f "$lib" ] || { echo "no such library: $lib" >&2; exit 1; }
deps="$(ldd "$lib")"
echo "$lib loads $(echo "$deps" | wc -l) shared libraries"
bad="$(echo "$deps" | grep -Ei 'assimp|embree|libpng|yaml-cpp|fruit_shape_sim|fruit_shape_planner|vtk' || true)"
if [ -n "$bad" ]; then
  echo "simulator libraries in the plugin's closure:" >&2
  echo "$bad" >&2
  exit 1
fi
