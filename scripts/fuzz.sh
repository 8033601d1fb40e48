#!/usr/bin/env bash
# Fuzzes each file reader and each message the plugin parses with libFuzzer (clang,
# -fsanitize=fuzzer,address,undefined) for a fixed time, starting from the seeds in
# test/fuzz/seeds; not part of CI.
#   scripts/fuzz.sh [SECONDS_PER_TARGET=600] [TARGET...]
#   targets: cloud_file map_file scene_file camera_cloud pointcloud_with_roi
# Inputs that crash, leak, hang (> 10 s) or allocate more than 1 GiB land in build-fuzz/findings/.
# A summary line per target ends the run; the exit status is non-zero if any target failed.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECONDS_PER_TARGET="${1:-600}"
shift || true
TARGETS=("$@")
[ ${#TARGETS[@]} -gt 0 ] || TARGETS=(cloud_file map_file scene_file camera_cloud pointcloud_with_roi)
"$ROOT/scripts/setup.sh"
command -v clang++ >/dev/null || { echo "fuzz: clang++ is needed (apt-get install clang)" >&2; exit 2; }
export PATH="/usr/bin:$PATH"
UPSTREAM_DEVEL="$("$ROOT/scripts/upstream_ws.sh")"
set +u
# shellcheck disable=SC1091
source "$UPSTREAM_DEVEL/setup.bash"
set -u
BUILD_DIR="$ROOT/build-fuzz"
FLAGS="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
if [ ! -f "$BUILD_DIR/Makefile" ] && [ ! -f "$BUILD_DIR/build.ninja" ]; then  # a failed or interrupted configure leaves no build files
  CC=clang CXX=clang++ cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFSC_FUZZ=ON \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_CXX_FLAGS="$FLAGS" -DCMAKE_C_FLAGS="$FLAGS" \
      -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" \
      >"$BUILD_DIR.configure.log" 2>&1 || { cat "$BUILD_DIR.configure.log" >&2; exit 1; }
fi
cmake --build "$BUILD_DIR" -j "${JOBS:-$(nproc)}" --target "${TARGETS[@]/#/fuzz_}"
BIN_DIR="$BUILD_DIR/devel/lib/fruit_shape_completion"
failed=0
for t in "${TARGETS[@]}"; do
  corpus="$BUILD_DIR/corpus/$t" findings="$BUILD_DIR/findings/$t"
  mkdir -p "$corpus" "$findings"
  log="$BUILD_DIR/fuzz_$t.log"
  if UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ASAN_OPTIONS=detect_leaks=1 \
     "$BIN_DIR/fuzz_$t" -max_total_time="$SECONDS_PER_TARGET" -timeout=10 -rss_limit_mb=1024 \
       -malloc_limit_mb=1024 -max_len=4096 -print_final_stats=1 -artifact_prefix="$findings/" \
       "$corpus" "$ROOT/test/fuzz/seeds/$t" >"$log" 2>&1; then
    status="clean"
  else
    status="FAILED (see $log and $findings)"; failed=1
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo "?")
  echo "fuzz $t: $status, ${SECONDS_PER_TARGET} s, $runs inputs, coverage $cov edges, corpus $(ls "$corpus" | wc -l) files"
done
exit "$failed"
