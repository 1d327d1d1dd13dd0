#!/usr/bin/env bash
# Build hocurve in release mode and install the C library into PREFIX:
#
#   PREFIX/lib/libhocurve.so.X.Y.Z   (SONAME libhocurve.so.X)
#   PREFIX/lib/libhocurve.so.X -> libhocurve.so.X.Y.Z,  libhocurve.so -> libhocurve.so.X
#   PREFIX/lib/libhocurve.a          (exports only the hoc_* functions)
#   PREFIX/include/hocurve.h, hocurve.hpp, hocurve.f90
#   PREFIX/lib/cmake/hocurve/hocurveConfig.cmake, hocurveConfigVersion.cmake
#   PREFIX/lib/pkgconfig/hocurve.pc
#   PREFIX/bin/hocurve               (the command-line tool)
#   PREFIX/share/doc/hocurve/metis/  (licence notices of the embedded METIS)
#
# A thin wrapper around the top-level CMakeLists.txt (docs/packaging.md):
#   cmake -S . -B BUILD && cmake --build BUILD && cmake --install BUILD --prefix PREFIX
# BUILD is $HOCURVE_BUILD_DIR, else a temporary directory. cargo's target
# directory is $CARGO_TARGET_DIR, else the checkout's target/ (the one plain
# `cargo build --release` uses, so its work is reused).
#
# Usage: scripts/install.sh PREFIX
set -euo pipefail

if [ $# -ne 1 ]; then
  echo "usage: $0 PREFIX" >&2
  exit 2
fi
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$1"
prefix=$(cd "$1" && pwd)

if [ -n "${HOCURVE_BUILD_DIR:-}" ]; then
  build=$HOCURVE_BUILD_DIR
else
  build=$(mktemp -d "${TMPDIR:-/tmp}/hocurve-install.XXXXXX")
  trap 'rm -rf "$build"' EXIT
fi

args=(-DHOCURVE_CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}")
# The system libraries libhocurve.a needs are asked of rustc; this overrides them.
if [ -n "${HOCURVE_NATIVE_STATIC_LIBS:-}" ]; then
  args+=(-DHOCURVE_NATIVE_STATIC_LIBS="$HOCURVE_NATIVE_STATIC_LIBS")
fi
cmake -S "$root" -B "$build" "${args[@]}" >/dev/null
cmake --build "$build"
cmake --install "$build" --prefix "$prefix" >/dev/null

version=$(sed -n 's/^set(PACKAGE_VERSION "\(.*\)")$/\1/p' "$prefix/lib/cmake/hocurve/hocurveConfigVersion.cmake")
echo "hocurve $version installed into $prefix"
