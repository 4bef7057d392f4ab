#!/usr/bin/env bash
# AddressSanitizer + UndefinedBehaviorSanitizer build of everything but the CGAL/OpenVDB
# meshing target (its templates take too long to compile instrumented on 2 cores) and the live
# viewer (its Beast server and browser test are covered by the Release run), and the test
# suite under it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
BUILD_DIR=${BUILD_DIR:-build-asan}
# -g1 (line tables only): reports keep file:line; full debug info made the instrumented
# Eigen-heavy files compile about 15% slower. The compiler is the default (gcc): a clang tree
# that also built the fuzz targets would save run-fuzzers.sh its own build, but the tests draw
# random vectors as Vec3(u(rng), u(rng), u(rng)), whose order is unspecified: under clang they
# get other blades, jitter and perturbations, and four tests written around gcc's fail there.
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DINCISE_SANITIZE=ON \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG" \
  -DINCISE_WITH_CGAL=OFF -DINCISE_WITH_VIEW=OFF -DINCISE_BUILD_BENCH=OFF >/dev/null
cmake --build "$BUILD_DIR" -j "${JOBS:-$(nproc)}"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# The cut torture test runs 10,000 steps in Release; fewer instrumented.
export INCISE_TORTURE_STEPS=${INCISE_TORTURE_STEPS:-500}
# The graded stuffing test meshes 300 random shapes in Release; 40 instrumented (300 took 467 s).
export INCISE_STUFFING_INPUTS=${INCISE_STUFFING_INPUTS:-40}
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "${JOBS:-$(nproc)}" --timeout 1200
