#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan+UBSan) and runs each for FUZZ_SECONDS seconds
# (default 20), starting from the seed corpora in fuzz/corpus/. Prints executions and
# crashes per target; exits 1 if any target crashed (artifacts are kept in the work dir).
#   FUZZ_SECONDS=60 scripts/run-fuzzers.sh            # all targets
#   scripts/run-fuzzers.sh vtu gmsh                    # some targets
# Env: FUZZ_BUILD_DIR (default /tmp/incise-fuzz-build; CI passes build-sanitize, whose
#      scripts/sanitize.sh configuration has the targets), FUZZ_WORK_DIR (default a mktemp dir),
#      FUZZ_MAX_LEN (default 16384).
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECONDS_PER_TARGET="${FUZZ_SECONDS:-20}"
BUILD="${FUZZ_BUILD_DIR:-/tmp/incise-fuzz-build}"
WORK="${FUZZ_WORK_DIR:-$(mktemp -d /tmp/incise-fuzz-work.XXXXXX)}"
MAX_LEN="${FUZZ_MAX_LEN:-16384}"
mkdir -p "$WORK"
ALL_TARGETS=(gmsh medit vtk vtu tetgen surface scene cut change frame)
if [ $# -gt 0 ]; then TARGETS=("$@"); else TARGETS=("${ALL_TARGETS[@]}"); fi

if [ ! -f "$BUILD/build.ninja" ]; then
  CXX=clang++ cmake -S "$ROOT" -B "$BUILD" -G Ninja -DINCISE_FUZZ=ON -DINCISE_WITH_CGAL=OFF -DINCISE_WITH_VIEW=OFF \
    -DINCISE_BUILD_TESTS=OFF -DINCISE_BUILD_BENCH=OFF >"$WORK/cmake.log" 2>&1 ||
    { cat "$WORK/cmake.log"; echo "run-fuzzers: cmake failed" >&2; exit 1; }
fi
ninja -C "$BUILD" "${TARGETS[@]/#/fuzz_}" >"$WORK/build.log" 2>&1 ||
  { tail -40 "$WORK/build.log"; echo "run-fuzzers: build failed" >&2; exit 1; }

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$ROOT/fuzz/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
failed=0
printf '%-10s %12s %8s  %s\n' target executions crashes artifacts
for t in "${TARGETS[@]}"; do
  corpus="$WORK/corpus_$t"
  mkdir -p "$corpus"
  log="$WORK/$t.log"
  # A cut script (up to 24 blade moves, instrumented) takes seconds; a reader input far less.
  timeout=10; [ "$t" = cut ] && timeout=30
  "$BUILD/fuzz/fuzz_$t" -max_total_time="$SECONDS_PER_TARGET" -max_len="$MAX_LEN" -timeout="$timeout" \
    -rss_limit_mb=2048 -malloc_limit_mb=1024 -print_final_stats=1 -artifact_prefix="$WORK/$t-" \
    "$corpus" "$ROOT/fuzz/corpus/$t" >"$log" 2>&1
  rc=$?
  execs=$(grep -E '^stat::number_of_executed_units' "$log" | awk '{print $2}' | tail -1)
  [ -z "$execs" ] && execs=$(grep -oE 'Done [0-9]+ runs' "$log" | awk '{print $2}' | tail -1)
  crashes=$(find "$WORK" -maxdepth 1 -name "$t-*" -type f | wc -l)
  if [ $rc -ne 0 ] && [ "$crashes" -eq 0 ]; then crashes=1; fi
  printf '%-10s %12s %8s  %s\n' "$t" "${execs:-?}" "$crashes" \
    "$( [ "$crashes" -gt 0 ] && echo "$WORK/$t-* (log: $log)")"
  [ "$crashes" -gt 0 ] && failed=1
done
echo "work dir: $WORK"
exit $failed
