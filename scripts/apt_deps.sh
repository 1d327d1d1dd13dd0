#!/usr/bin/env bash
# System packages for the C/C++/Fortran tests (scripts/test_c.sh): compilers,
# CMake, valgrind, the mesh generators the test fixtures use (TetGen, CGAL), and
# gmsh's C++ API with OpenCASCADE for examples/occt (libgmsh-dev). binutils
# (g++ pulls it in; named because the CMake build itself runs ld -r, objcopy,
# ar and readelf on libhocurve.a, and scripts/test_packaging.sh runs nm) and
# pkg-config for the packaging checks. OpenMPI, PETSc and libclang (for the
# `mpi` crate's bindings) for the distributed build, hocurve-mpi.
set -euo pipefail
packages=(cmake g++ gfortran pkg-config binutils valgrind
  tetgen libtet1.5-dev libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  libgmsh-dev openmpi-bin libopenmpi-dev petsc-dev libclang-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y --no-install-recommends "${missing[@]}"
fi
