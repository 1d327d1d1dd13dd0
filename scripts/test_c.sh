#!/usr/bin/env bash
# The C/C++/Fortran side of the test suite: install hocurve into a temporary
# prefix (scripts/install.sh), build c_tests/ against it with find_package as a
# user would, run ctest, check pkg-config, then run the tests under valgrind
# and, built a second time, under AddressSanitizer + UndefinedBehaviorSanitizer
# (LeakSanitizer included; the library's own allocations go through malloc, so
# its leaks are caught too). Then builds and tests examples/occt (gmsh's C++ API
# with OpenCASCADE; not under valgrind or the sanitizers, which would mostly
# check OpenCASCADE). Last, scripts/test_packaging.sh checks the package itself
# (exported symbols of libhocurve.a, find_package version rules, a C++ consumer
# through find_package, add_subdirectory and FetchContent, a relocated prefix
# with CMake and pkg-config).
#
# Usage: scripts/test_c.sh   (HOCURVE_SKIP_MEMCHECK=1 skips valgrind, HOCURVE_SKIP_ASAN=1 the sanitizers,
#                             HOCURVE_SKIP_OCCT=1 examples/occt, HOCURVE_SKIP_PACKAGING=1 the packaging checks)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/hocurve-c.XXXXXX")
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix
build=$work/build
jobs=$(nproc 2>/dev/null || echo 2)

"$root/scripts/install.sh" "$prefix"

memcheck=ON
[ "${HOCURVE_SKIP_MEMCHECK:-0}" = 1 ] && memcheck=OFF
cmake -S "$root/c_tests" -B "$build" -DCMAKE_PREFIX_PATH="$prefix" -DHOCURVE_TESTS_VALGRIND=$memcheck
cmake --build "$build" -j "$jobs"

# pkg-config gives what a Makefile user needs.
PKG_CONFIG_PATH=$prefix/lib/pkgconfig \
  cc "$root/c_tests/t000-version.c" -I"$root/c_tests" $(PKG_CONFIG_PATH=$prefix/lib/pkgconfig pkg-config --cflags --libs hocurve) \
  -Wl,-rpath,"$prefix/lib" -o "$work/t000-pkgconfig"
"$work/t000-pkgconfig" >/dev/null
echo "pkg-config build of t000-version: ok"

# Both passes run even if the first fails; the script fails if either did.
status=0
ctest --test-dir "$build" -L api -j "$jobs" --output-on-failure || status=1
if [ $memcheck = ON ]; then
  ctest --test-dir "$build" -L memcheck -j "$jobs" --output-on-failure || status=1
fi
if [ "${HOCURVE_SKIP_ASAN:-0}" != 1 ]; then
  asan=$work/build-asan
  cmake -S "$root/c_tests" -B "$asan" -DCMAKE_PREFIX_PATH="$prefix" -DHOCURVE_TESTS_SANITIZE=address
  cmake --build "$asan" -j "$jobs"
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir "$asan" -L api -j "$jobs" --output-on-failure || status=1
fi
if [ "${HOCURVE_SKIP_OCCT:-0}" != 1 ]; then
  occt=$work/build-occt
  cmake -S "$root/examples/occt" -B "$occt" -DCMAKE_PREFIX_PATH="$prefix"
  cmake --build "$occt" -j "$jobs"
  ctest --test-dir "$occt" -j "$jobs" --output-on-failure || status=1
fi
if [ "${HOCURVE_SKIP_PACKAGING:-0}" != 1 ]; then
  # Installs its own prefix (cargo's work is reused), so that it can move it.
  "$root/scripts/test_packaging.sh" || status=1
fi
exit $status
