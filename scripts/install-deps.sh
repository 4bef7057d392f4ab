#!/usr/bin/env bash
# Installs every Debian package incise's build, tests, benchmarks and demo need.
# Idempotent: packages already present are skipped; runs as root or through sudo.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config
  clang libclang-rt-14-dev               # fuzzers (libFuzzer) and sanitizers
  libeigen3-dev libcgal-dev libcgal-demo # meshing; libcgal-demo ships the sample data
  libopenvdb-dev libtbb-dev libassimp-dev zlib1g-dev libgmp-dev libmpfr-dev libboost-dev
  catch2 libcli11-dev nlohmann-json3-dev libbenchmark-dev
  libsuitesparse-dev                     # CHOLMOD: the Cholesky preconditioner's factorization
  libopenblas0-pthread                   # optimized BLAS under CHOLMOD (Debian's default is the reference one)
  tetgen gmsh                            # peers: cross-format tests and benchmarks
  calculix-ccx                           # ccx: the quadratic tets' C3D10 comparison (tests/sim)
  python3 python3-meshio python3-numpy   # meshio cross-check of every written format
  pybind11-dev python3-dev python3-pytest # Python bindings and their tests
  chromium chromium-driver python3-selenium # the viewer's browser test (headless, tests/view)
  petsc-dev openmpi-bin                  # the distributed solver backend (PETSc 3.18 over OpenMPI) and mpirun
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

# Node.js and npm install the viewer page's packages (three.js, view/web/package-lock.json).
# A Node.js from elsewhere that brings its own npm is kept (Debian's npm would conflict with it).
if ! command -v node >/dev/null 2>&1; then missing+=(nodejs); fi
if ! command -v npm >/dev/null 2>&1; then missing+=(npm); fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present" >&2
else
  echo "install-deps: installing ${missing[*]}" >&2
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# The viewer page's JavaScript packages, exactly as locked; skipped when node_modules already
# matches the lock (npm writes its own copy of the lock there after an install).
WEB="$(cd "$(dirname "$0")/.." && pwd)/view/web"
if [ -f "$WEB/package-lock.json" ]; then
  if ! cmp -s "$WEB/package-lock.json" "$WEB/node_modules/.package-lock-source.json" 2>/dev/null; then
    echo "install-deps: npm ci in view/web" >&2
    (cd "$WEB" && npm ci --no-audit --no-fund --ignore-scripts >&2)
    cp "$WEB/package-lock.json" "$WEB/node_modules/.package-lock-source.json"
  fi
fi
