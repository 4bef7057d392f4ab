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
  python3 python3-meshio python3-numpy   # meshio cross-check of every written format
  pybind11-dev python3-dev python3-pytest # Python bindings and their tests
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present" >&2
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}" >&2
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
