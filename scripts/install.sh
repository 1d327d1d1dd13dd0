#!/usr/bin/env bash
# Build hocurve in release mode and install the C library into PREFIX:
#
#   PREFIX/lib/libhocurve.so.X.Y.Z   (SONAME libhocurve.so.X)
#   PREFIX/lib/libhocurve.so.X -> libhocurve.so.X.Y.Z,  libhocurve.so -> libhocurve.so.X
#   PREFIX/lib/libhocurve.a
#   PREFIX/include/hocurve.h, hocurve.hpp, hocurve.f90
#   PREFIX/lib/cmake/hocurve/hocurveConfig.cmake, hocurveConfigVersion.cmake
#   PREFIX/lib/pkgconfig/hocurve.pc
#   PREFIX/share/doc/hocurve/metis/   (licence notices of the embedded METIS)
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

version=$(sed -n 's/^version *= *"\([^"]*\)".*/\1/p' "$root/Cargo.toml" | head -n 1)
major=${version%%.*}
rest=${version#*.}
minor=${rest%%.*}
# System libraries a Rust staticlib needs on x86_64-linux-gnu, as printed by
# `cargo rustc --release --lib --crate-type staticlib -- --print native-static-libs`.
native_libs=${HOCURVE_NATIVE_STATIC_LIBS:-"-lgcc_s -lutil -lrt -lpthread -lm -ldl -lc"}
native_libs_cmake=$(printf '%s\n' $native_libs | sed 's/^-l//' | paste -sd ';' -)

(cd "$root" && cargo build --release --lib)
target=${CARGO_TARGET_DIR:-$root/target}/release

for f in "$target/libhocurve.so" "$target/libhocurve.a" "$root/include/hocurve.h"; do
  [ -f "$f" ] || { echo "install.sh: missing $f" >&2; exit 1; }
done

install -d "$prefix/lib" "$prefix/include" "$prefix/lib/cmake/hocurve" "$prefix/lib/pkgconfig"

so="libhocurve.so.$version"
install -m 755 "$target/libhocurve.so" "$prefix/lib/$so"
soname=$(readelf -d "$prefix/lib/$so" | sed -n 's/.*(SONAME).*\[\(.*\)\]/\1/p')
if [ "$soname" != "libhocurve.so.$major" ]; then
  # build.rs sets it with -Wl,-soname; this is the fallback for a build without it.
  if command -v patchelf >/dev/null 2>&1; then
    patchelf --set-soname "libhocurve.so.$major" "$prefix/lib/$so"
  else
    echo "install.sh: $so has SONAME '${soname}', expected libhocurve.so.$major, and there is no patchelf" >&2
    exit 1
  fi
fi
ln -sfn "$so" "$prefix/lib/libhocurve.so.$major"
ln -sfn "libhocurve.so.$major" "$prefix/lib/libhocurve.so"
install -m 644 "$target/libhocurve.a" "$prefix/lib/libhocurve.a"

install -m 644 "$root/include/hocurve.h" "$root/include/hocurve.hpp" "$root/include/hocurve.f90" \
  "$prefix/include/"
# The libraries embed METIS (Apache-2.0): its notices go with them.
install -d "$prefix/share/doc/hocurve/metis"
install -m 644 "$root/third_party/metis/README.md" "$root/third_party/metis/LICENSE-Apache-2.0.txt" \
  "$prefix/share/doc/hocurve/metis/"
install -m 644 "$root/third_party/metis/metis/LICENSE" "$prefix/share/doc/hocurve/metis/LICENSE-METIS"
install -m 644 "$root/third_party/metis/GKlib/LICENSE.txt" "$prefix/share/doc/hocurve/metis/LICENSE-GKlib"

subst() {
  sed -e "s|@VERSION@|$version|g" -e "s|@VERSION_MAJOR@|$major|g" -e "s|@VERSION_MINOR@|$minor|g" \
    -e "s|@SOVERSION@|$major|g" -e "s|@PREFIX@|$prefix|g" -e "s|@NATIVE_LIBS@|$native_libs|g" \
    -e "s|@NATIVE_LIBS_CMAKE@|$native_libs_cmake|g" "$1" >"$2"
}
subst "$root/cmake/hocurveConfig.cmake.in" "$prefix/lib/cmake/hocurve/hocurveConfig.cmake"
subst "$root/cmake/hocurveConfigVersion.cmake.in" "$prefix/lib/cmake/hocurve/hocurveConfigVersion.cmake"
subst "$root/cmake/hocurve.pc.in" "$prefix/lib/pkgconfig/hocurve.pc"

echo "hocurve $version installed into $prefix"
