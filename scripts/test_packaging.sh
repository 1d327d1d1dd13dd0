#!/usr/bin/env bash
# Checks of the installed package and of the CMake build (docs/packaging.md),
# with the C++ project tests/cmake_consumer (curves a disc through hocurve.hpp,
# once against libhocurve.so, once against libhocurve.a):
#
#   layout     the installed files, the .so links and SONAME, the CLI
#   symbols    libhocurve.a defines only hoc_* globals, the same set
#              libhocurve.so exports
#   version    find_package(hocurve V) accepts and refuses what
#              SameMinorVersion says (0.x: only 0.<minor>.* is compatible)
#   package    the consumer with find_package from the install
#   subdir     the consumer with add_subdirectory(<checkout>)
#   fetch      the consumer with FetchContent (FETCHCONTENT_SOURCE_DIR_HOCURVE)
#   relocate   the prefix moved elsewhere (the original gone): no file names
#              the old prefix, the consumer builds and runs with find_package,
#              and with pkg-config (shared, and static with Libs.private)
#
# Every check runs even if an earlier one failed; the exit status is non-zero
# if any failed.
#
# Usage: scripts/test_packaging.sh [PREFIX]
#   Without PREFIX, installs into a temporary prefix with scripts/install.sh.
#   With PREFIX (an existing install), uses it as is and relocates a copy.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/hocurve-packaging.XXXXXX")
trap 'rm -rf "$work"' EXIT
jobs=$(nproc 2>/dev/null || echo 2)
consumer=$root/tests/cmake_consumer
cargo_target=${CARGO_TARGET_DIR:-$root/target}

failed=()
pass() { echo "ok:   $*"; }
fail() { echo "FAIL: $*"; failed+=("$1"); }
# run LOG CMD...: run quietly, show the log if it fails.
run() {
  local log=$1; shift
  if "$@" >"$log" 2>&1; then return 0; fi
  echo "---- $* (exit $?; $log):"; tail -n 40 "$log"; echo "----"
  return 1
}

version=$(sed -n 's/^version *= *"\([^"]*\)".*/\1/p' "$root/Cargo.toml" | head -n 1)
IFS=. read -r major minor patch <<<"$version"
# The ABI version in the SONAME: the major, or 0.minor while the major is 0.
abi=$major
[ "$major" -eq 0 ] && abi="0.$minor"

if [ $# -ge 1 ]; then
  prefix=$(cd "$1" && pwd)
  own_prefix=0
else
  prefix=$work/prefix
  own_prefix=1
  if ! run "$work/install.log" "$root/scripts/install.sh" "$prefix"; then
    echo "test_packaging: scripts/install.sh failed" >&2
    exit 1
  fi
fi
echo "test_packaging: hocurve $version in $prefix"

# --- layout -------------------------------------------------------------------
layout_ok=1
for f in include/hocurve.h include/hocurve.hpp include/hocurve.f90 lib/libhocurve.a "lib/libhocurve.so.$version" \
  lib/cmake/hocurve/hocurveConfig.cmake lib/cmake/hocurve/hocurveConfigVersion.cmake lib/pkgconfig/hocurve.pc \
  bin/hocurve share/doc/hocurve/metis/LICENSE-METIS; do
  [ -f "$prefix/$f" ] || { echo "missing $prefix/$f"; layout_ok=0; }
done
[ "$(readlink "$prefix/lib/libhocurve.so.$abi")" = "libhocurve.so.$version" ] || { echo "bad libhocurve.so.$abi link"; layout_ok=0; }
[ "$(readlink "$prefix/lib/libhocurve.so")" = "libhocurve.so.$abi" ] || { echo "bad libhocurve.so link"; layout_ok=0; }
soname=$(readelf -d "$prefix/lib/libhocurve.so.$version" 2>/dev/null | sed -n 's/.*(SONAME).*\[\(.*\)\]/\1/p')
[ "$soname" = "libhocurve.so.$abi" ] || { echo "SONAME '$soname'"; layout_ok=0; }
[ "$("$prefix/bin/hocurve" --version 2>&1)" = "hocurve $version" ] || { echo "bin/hocurve --version fails"; layout_ok=0; }
if [ $layout_ok = 1 ]; then pass "layout (libhocurve.so.$version, SONAME $soname, links, headers, CLI)"; else fail layout; fi

# --- symbols ------------------------------------------------------------------
# nm -g --defined-only: global (and weak) symbols the archive defines.
nm -g --defined-only "$prefix/lib/libhocurve.a" >"$work/static.nm" 2>"$work/nm.err"; nm_rc=$?
nm -D --defined-only "$prefix/lib/libhocurve.so.$version" >"$work/shared.nm" 2>>"$work/nm.err" || nm_rc=$?
awk 'NF == 3 {print $3}' "$work/static.nm" | sort -u >"$work/static.syms"
awk 'NF == 3 {print $3}' "$work/shared.nm" | sort -u >"$work/shared.syms"
n_static=$(wc -l <"$work/static.syms")
others=$(grep -v '^hoc_' "$work/static.syms" | head -n 5)
if [ "$nm_rc" -ne 0 ]; then
  fail symbols "nm failed (exit $nm_rc): $(head -n 3 "$work/nm.err")"
elif [ "$n_static" -eq 0 ] || ! grep -qx hoc_version "$work/static.syms"; then
  fail symbols "libhocurve.a defines no hoc_version ($n_static globals)"
elif [ -n "$others" ]; then
  fail symbols "libhocurve.a defines $(grep -vc '^hoc_' "$work/static.syms") non-hoc_ globals, e.g. $(echo $others)"
elif ! cmp -s "$work/static.syms" "$work/shared.syms"; then
  fail symbols "libhocurve.a and libhocurve.so define different symbols: $(diff "$work/static.syms" "$work/shared.syms" | head -n 5 | tr '\n' ' ')"
else
  pass "symbols (libhocurve.a: $n_static globals, all hoc_*, the same as libhocurve.so exports)"
fi

# --- version ------------------------------------------------------------------
# find_version LOG ARGS: does find_package(hocurve ARGS REQUIRED) configure?
find_version() {
  rm -rf "$work/fv"
  cmake -S "$consumer/find_version" -B "$work/fv" -DCMAKE_PREFIX_PATH="$prefix" "-DHOCURVE_FIND_ARGS=$1" >"$work/fv.log" 2>&1
}
next_minor="$major.$((minor + 1))"
accept=("$major.$minor" "$version" "$version;EXACT" "$major.$minor...<$next_minor")
refuse=("$next_minor" "$((major + 1))" "$major.$minor.$((patch + 1))")
# SameMinorVersion: a bare major asks for <major>.0.
[ "$minor" -ne 0 ] && refuse+=("$major")
version_ok=1
for r in "${accept[@]}"; do
  if ! find_version "$r"; then echo "find_package(hocurve ${r//;/ }) refused:"; tail -n 15 "$work/fv.log"; version_ok=0; fi
done
for r in "${refuse[@]}"; do
  if find_version "$r"; then
    echo "find_package(hocurve ${r//;/ }) accepted $version"; version_ok=0
  elif ! grep -q "hocurveConfig.cmake, version: $version" "$work/fv.log"; then
    # Refused, but not for its version (the package was not even found).
    echo "find_package(hocurve ${r//;/ }) failed for another reason:"; tail -n 15 "$work/fv.log"; version_ok=0
  fi
done
# Every find_package(hocurve N.M) this checkout ships (tests, examples, docs)
# must ask for the version being built, or the next bump leaves one behind.
stale=$(cd "$root" && git ls-files 2>/dev/null | grep -E '(CMakeLists\.txt|\.cmake|\.md)$' \
  | xargs grep -nE 'find_package\(hocurve [0-9]+\.[0-9]+[.0-9]* REQUIRED' 2>/dev/null \
  | grep -vE "find_package\(hocurve $major\.$minor[ .)]" || true)
if [ -n "$stale" ]; then
  echo "find_package(hocurve ...) asks for another version than $major.$minor:"; echo "$stale"; version_ok=0
fi
if [ $version_ok = 1 ]; then
  pass "version ($version accepted for: ${accept[*]//;/ }; refused for: ${refuse[*]})"
else
  fail version
fi

# --- consumers ----------------------------------------------------------------
# build_consumer NAME BUILD_DIR CMAKE_ARGS...: configure, build, run both
# programs; their output in $consumer_out, what failed in $consumer_err.
build_consumer() {
  local name=$1 build=$2 exe; shift 2
  consumer_out="" consumer_err=""
  if ! run "$work/$name-configure.log" cmake -S "$consumer" -B "$build" "$@"; then
    consumer_err="configure"; return 1
  fi
  if ! run "$work/$name-build.log" cmake --build "$build" -j "$jobs"; then
    consumer_err="build"; return 1
  fi
  for exe in consumer consumer_static; do
    if ! consumer_out=$("$build/$exe" 2>&1); then
      echo "$consumer_out"; consumer_err="$exe failed"; return 1
    fi
  done
}
consume() {
  if build_consumer "$@"; then pass "$1: $consumer_out"; else fail "$1" "$consumer_err"; fi
}
consume package "$work/package" -DHOCURVE_CONSUMER_MODE=package -DCMAKE_PREFIX_PATH="$prefix"
consume subdir "$work/subdir" -DHOCURVE_CONSUMER_MODE=subdirectory -DHOCURVE_SOURCE_DIR="$root" \
  -DHOCURVE_CARGO_TARGET_DIR="$cargo_target"
consume fetch "$work/fetch" -DHOCURVE_CONSUMER_MODE=fetchcontent -DFETCHCONTENT_SOURCE_DIR_HOCURVE="$root" \
  -DHOCURVE_CARGO_TARGET_DIR="$cargo_target"

# --- relocate -----------------------------------------------------------------
moved=$work/elsewhere/deeper/hocurve-copy
mkdir -p "$(dirname "$moved")"
cp -a "$prefix" "$moved"
hidden=""
if [ $own_prefix = 1 ]; then
  # The original goes away, so nothing can quietly fall back on it.
  hidden=$work/prefix.hidden
  mv "$prefix" "$hidden"
fi
relocate_ok=1
if grep -rl -a -F -- "$prefix" "$moved" >"$work/stale"; then
  echo "files in the copy name the original prefix: $(tr '\n' ' ' <"$work/stale")"
  relocate_ok=0
fi
if build_consumer relocate-cmake "$work/moved-cmake" -DHOCURVE_CONSUMER_MODE=package -DCMAKE_PREFIX_PATH="$moved"; then
  # The targets must point into the copy.
  if grep -v -F -- " $moved/" "$work/moved-cmake/hocurve-paths.txt" | grep -q .; then
    echo "the consumer used files outside the copy:"; cat "$work/moved-cmake/hocurve-paths.txt"; relocate_ok=0
  fi
else
  echo "find_package from the copy: $consumer_err"; relocate_ok=0
fi
pcpath=$moved/lib/pkgconfig
cflags=$(PKG_CONFIG_PATH=$pcpath pkg-config --cflags hocurve 2>&1)
libs=$(PKG_CONFIG_PATH=$pcpath pkg-config --libs hocurve 2>&1)
static_libs=$(PKG_CONFIG_PATH=$pcpath pkg-config --libs --static hocurve 2>&1)
pc_version=$(PKG_CONFIG_PATH=$pcpath pkg-config --modversion hocurve 2>&1)
case "$cflags $libs" in
  *"$moved"*) ;;
  *) echo "pkg-config does not point into the copy: $cflags $libs"; relocate_ok=0 ;;
esac
[ "$pc_version" = "$version" ] || { echo "pkg-config --modversion: $pc_version"; relocate_ok=0; }
if run "$work/pc-shared.log" c++ -std=c++17 "$consumer/consumer.cpp" -DHOCURVE_EXPECTED_VERSION="\"$version\"" \
  $cflags $libs -o "$work/pc-consumer"; then
  if ! out=$(LD_LIBRARY_PATH=$moved/lib "$work/pc-consumer" 2>&1); then
    echo "$out"; echo "pkg-config shared build fails to run"; relocate_ok=0
  fi
else
  echo "pkg-config shared build fails"; relocate_ok=0
fi
# Static: libhocurve.a by -l, the system libraries from Libs.private.
static_flags=${static_libs/-lhocurve/-Wl,-Bstatic -lhocurve -Wl,-Bdynamic}
if run "$work/pc-static.log" c++ -std=c++17 "$consumer/consumer.cpp" -DHOCURVE_EXPECTED_VERSION="\"$version\"" \
  $cflags $static_flags -o "$work/pc-consumer-static"; then
  if readelf -d "$work/pc-consumer-static" | grep -q 'NEEDED.*libhocurve'; then
    echo "the pkg-config static build needs libhocurve.so"; relocate_ok=0
  elif ! out=$("$work/pc-consumer-static" 2>&1); then
    echo "$out"; echo "pkg-config static build fails to run"; relocate_ok=0
  fi
else
  echo "pkg-config static build fails ($static_flags)"; relocate_ok=0
fi
[ "$("$moved/bin/hocurve" --version 2>&1)" = "hocurve $version" ] || { echo "the moved CLI fails"; relocate_ok=0; }
if [ -n "$hidden" ]; then mv "$hidden" "$prefix"; fi
if [ $relocate_ok = 1 ]; then
  pass "relocate (copy in ${moved#"$work"/}, original $([ -n "$hidden" ] && echo removed || echo kept): no stale path; find_package, pkg-config shared and static build and run)"
else
  fail relocate
fi

echo
if [ ${#failed[@]} -eq 0 ]; then
  echo "test_packaging: all checks passed"
  exit 0
fi
echo "test_packaging: FAILED: ${failed[*]}"
exit 1
