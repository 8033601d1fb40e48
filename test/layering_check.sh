#!/usr/bin/env bash
# The product and the instrument stay apart.
#  1. What a planner loads (the plugin library and what it links) must not pull in the
#     simulator: fails if any of its shared libraries is Assimp, Embree, libpng, yaml-cpp or the
#     package's sim or planner loop. Its own DT_NEEDED entries must be product libraries.
#  2. No product source or header (src/product, include/fruit_shape_completion minus
#     instrument/) includes an instrument header.
#   test/layering_check.sh PLUGIN_LIBRARY SOURCE_DIR
set -euo pipefail
lib="$1"
src="${2:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}"
[ -f "$lib" ] || { echo "no such library: $lib" >&2; exit 1; }
deps="$(ldd "$lib")"
echo "$lib loads $(echo "$deps" | wc -l) shared libraries"
bad="$(echo "$deps" | grep -Ei 'assimp|embree|libpng|yaml-cpp|fruit_shape_sim|fruit_shape_planner|vtk' || true)"
if [ -n "$bad" ]; then
  echo "simulator libraries in the plugin's closure:" >&2
  echo "$bad" >&2
  exit 1
fi
own="$(objdump -p "$lib" | awk '/NEEDED/ {print $2}' | grep fruit_shape || true)"
echo "its own libraries: $(echo $own)"
for l in $own; do
  case "$l" in
    libfruit_shape_core.so|libfruit_shape_host.so|libfruit_shape_ros.so) ;;
    *) echo "the plugin needs $l, which is not a product library" >&2; exit 1 ;;
  esac
done
product_files="$(find "$src/src/product" "$src/include/fruit_shape_completion" -path '*/instrument' -prune -o \
                 \( -name '*.h' -o -name '*.cpp' \) -print)"
leaks="$(grep -n 'fruit_shape_completion/instrument/' $product_files || true)"
if [ -n "$leaks" ]; then
  echo "product files include instrument headers:" >&2
  echo "$leaks" >&2
  exit 1
fi
echo "$(echo "$product_files" | wc -l) product files include no instrument header"
