#!/usr/bin/env bash
# Builds the ROS-free tests with a sanitizer and runs them (not part of CI: ~10 min on 2 cores).
# Usage: scripts/sanitize.sh asan|tsan
#   asan: AddressSanitizer + UndefinedBehaviorSanitizer over core, sim and planner tests
#   tsan: ThreadSanitizer over the tests with threads (TSDF neighbour pass and ray casting, one
#         integrator called from two threads, estimator shared by a view thread and a query
#         thread, 2-thread renderer in planner episodes, the pipeline's parallel fits)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
KIND="${1:-}"
case "$KIND" in
  asan) FLAGS="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
        TESTS="test_superellipsoid test_clusters test_fit test_pipeline test_cloud_io test_tsdf test_sim test_planner" ;;
  tsan) FLAGS="-fsanitize=thread"
        TESTS="test_tsdf test_planner test_pipeline"
        # Third-party reports only (test/tsan.supp says which and why).
        export TSAN_OPTIONS="suppressions=$ROOT/test/tsan.supp${TSAN_OPTIONS:+ $TSAN_OPTIONS}" ;;
  *) echo "usage: scripts/sanitize.sh asan|tsan" >&2; exit 2 ;;
esac
"$ROOT/scripts/setup.sh"
export PATH="/usr/bin:$PATH"
UPSTREAM_DEVEL="$("$ROOT/scripts/upstream_ws.sh")"
set +u
# shellcheck disable=SC1091
source "$UPSTREAM_DEVEL/setup.bash"
set -u
BUILD_DIR="$ROOT/build-$KIND"
if [ ! -f "$BUILD_DIR/Makefile" ] && [ ! -f "$BUILD_DIR/build.ninja" ]; then  # a failed or interrupted configure leaves no build files
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPYTHON_EXECUTABLE=/usr/bin/python3 \
        -DCMAKE_CXX_FLAGS="$FLAGS" -DCMAKE_EXE_LINKER_FLAGS="$FLAGS" -DCMAKE_SHARED_LINKER_FLAGS="$FLAGS" \
        >"$BUILD_DIR.configure.log" 2>&1 || { cat "$BUILD_DIR.configure.log" >&2; exit 1; }
fi
# shellcheck disable=SC2086
cmake --build "$BUILD_DIR" -j "${JOBS:-$(nproc)}" --target $TESTS fit_cloud
BIN_DIR="$BUILD_DIR/devel/lib/fruit_shape_completion"
passed=0; failed=0
for t in $TESTS; do
  # The sanitizer runtime stops the test with a report on the first error.
  if (cd "$BIN_DIR" && FSC_BIN_DIR="$BIN_DIR" FSC_SHARED_DATA="${FSC_SHARED_DATA:-$ROOT/../shared/data}" "./$t"); then
    passed=$((passed + 1))
  else
    failed=$((failed + 1)); echo "sanitize: $t FAILED" >&2
  fi
done
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
