#!/usr/bin/env bash
# The project's whole test run (the README's test command, and CI's):
#   0. system packages (scripts/apt_deps.sh; needs root or sudo, skipped when present)
#   1. cargo build --release     (the binary the Python suite drives), then
#      the README's main job, `cargo run --release -- demo`, into a temporary
#      directory: it must write its two meshes and its report
#   2. cargo test --release      (unit, integration and doc tests, header check)
#   3. pytest -q tests/python    (end-to-end: gmsh, meshio and VTK read what
#                                 hocurve writes; quality agrees with gmsh)
#   4. pip install ./python; pytest -q tests/python_pkg (the Python package)
#   5. scripts/test_c.sh         (install into a temp prefix; C, C++, Fortran
#                                 tests on TetGen/CGAL meshes via find_package;
#                                 ctest, then the same under valgrind and under
#                                 AddressSanitizer + UBSan + LeakSanitizer)
#   6. the distributed build (`--features mpi`, in target/mpi) and
#      pytest -q tests/mpi: mpirun -np 1..4 hocurve-mpi against hocurve, and
#      C and Fortran programs giving each process its share of a mesh
#      (hoc_mesh_create_distributed) against hocurve
#   7. scripts/fuzz.sh           (cargo-fuzz: the .msh reader and the C ABI call
#                                 sequence, HOCURVE_FUZZ_SECONDS each, default
#                                 60; HOCURVE_SKIP_FUZZ=1 skips it)
# The demo and steps 2-7 all run even if one fails; the exit status is non-zero if
# anything failed. The Python venv is made (or reused) by setup_python.sh.
set -uo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"
venv="${HOCURVE_VENV:-$repo/.venv}"
export HOCURVE_VENV="$venv"

step() { printf '\n==> %s\n' "$*"; }

step "system packages"
if ! "$repo/scripts/apt_deps.sh"; then
    echo "test_all: scripts/apt_deps.sh failed (run it as root once)" >&2
    exit 1
fi

step "cargo build --release"
if ! cargo build --release; then
    echo "test_all: cargo build --release failed" >&2
    exit 1
fi

step "the main job: cargo run --release -- demo"
demo_dir="$(mktemp -d)"
if cargo run --release -- demo --output-dir "$demo_dir" && [ -s "$demo_dir/demo-2d.vtu" ] &&
    [ -s "$demo_dir/demo-3d.vtu" ] && [ -s "$demo_dir/demo-report.json" ]; then
    demo_rc=0
else
    echo "test_all: the demo did not write demo-2d.vtu, demo-3d.vtu and demo-report.json" >&2
    demo_rc=1
fi
rm -rf "$demo_dir"

step "cargo test --release"
cargo test --release
cargo_rc=$?

step "python venv ($venv)"
if ! "$repo/scripts/setup_python.sh"; then
    echo "test_all: scripts/setup_python.sh failed" >&2
    exit 1
fi

step "pytest -q tests/python"
HOCURVE_BIN="${HOCURVE_BIN:-$repo/target/release/hocurve}" \
    "$venv/bin/python" -m pytest -q -p no:cacheprovider tests/python
py_rc=$?
if [ "$py_rc" -eq 5 ]; then
    echo "test_all: pytest collected no tests" >&2
fi

step "Python package: pip install ./python; pytest -q tests/python_pkg"
# maturin (pinned in the venv, no build isolation) runs as a command: the venv's bin first on PATH.
if PATH="$venv/bin:$PATH" "$venv/bin/python" -m pip install --quiet --no-build-isolation "$repo/python"; then
    "$venv/bin/python" -m pytest -q -p no:cacheprovider tests/python_pkg
    pkg_rc=$?
else
    echo "test_all: pip install ./python failed" >&2
    pkg_rc=1
fi

step "C, C++ and Fortran tests (scripts/test_c.sh)"
"$repo/scripts/test_c.sh"
c_rc=$?

step "distributed build and tests: cargo build --release --features mpi; pytest -q tests/mpi"
# In a target directory of its own: the default build's library links no MPI.
if CARGO_TARGET_DIR="$repo/target/mpi" cargo build --release --features mpi; then
    "$venv/bin/python" -m pytest -q -p no:cacheprovider tests/mpi
    mpi_rc=$?
else
    echo "test_all: the distributed build failed" >&2
    mpi_rc=1
fi

fuzz_rc=0
if [ "${HOCURVE_SKIP_FUZZ:-0}" != 1 ]; then
    step "fuzzing (scripts/fuzz.sh ${HOCURVE_FUZZ_SECONDS:-60})"
    "$repo/scripts/fuzz.sh" "${HOCURVE_FUZZ_SECONDS:-60}"
    fuzz_rc=$?
fi

step "summary"
echo "demo:       $([ $demo_rc -eq 0 ] && echo ok || echo FAILED)"
echo "cargo test: $([ $cargo_rc -eq 0 ] && echo ok || echo "FAILED (exit $cargo_rc)")"
echo "pytest:     $([ $py_rc -eq 0 ] && echo ok || echo "FAILED (exit $py_rc)")"
echo "Python pkg: $([ $pkg_rc -eq 0 ] && echo ok || echo "FAILED (exit $pkg_rc)")"
echo "C tests:    $([ $c_rc -eq 0 ] && echo ok || echo "FAILED (exit $c_rc)")"
echo "MPI:        $([ $mpi_rc -eq 0 ] && echo ok || echo "FAILED (exit $mpi_rc)")"
echo "fuzzing:    $([ "${HOCURVE_SKIP_FUZZ:-0}" = 1 ] && echo skipped || { [ $fuzz_rc -eq 0 ] && echo ok || echo "FAILED (exit $fuzz_rc)"; })"
[ "$demo_rc" -eq 0 ] && [ "$cargo_rc" -eq 0 ] && [ "$py_rc" -eq 0 ] && [ "$pkg_rc" -eq 0 ] && [ "$c_rc" -eq 0 ] && [ "$mpi_rc" -eq 0 ] && [ "$fuzz_rc" -eq 0 ]
