#!/usr/bin/env bash
# Create (idempotently) the Python venv used by the end-to-end tests and the
# sample generators: ${HOCURVE_VENV:-<repo>/.venv} with the pinned packages of
# tests/python/requirements.txt (gmsh, meshio, numpy, pytest, vtk).
#
# Re-running is cheap: when the venv already holds exactly the pinned set
# (recorded in .venv/.hocurve-requirements), nothing is downloaded.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${HOCURVE_VENV:-$repo/.venv}"
req="$repo/tests/python/requirements.txt"
python="${PYTHON:-python3}"
stamp="$venv/.hocurve-requirements"

if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && cmp -s "$req" "$stamp"; then
    echo "setup_python: $venv is up to date"
    exit 0
fi

if [ ! -x "$venv/bin/python" ]; then
    echo "setup_python: creating $venv with $("$python" --version 2>&1)"
    if ! "$python" -m venv "$venv"; then
        echo "setup_python: '$python -m venv' failed; on Debian install python3-venv" >&2
        exit 1
    fi
fi

export PIP_DISABLE_PIP_VERSION_CHECK=1
"$venv/bin/python" -m pip install --quiet --requirement "$req"

# The gmsh wheel ships libgmsh.so; check it loads (it needs libGLU/libX* only
# through its own bundled copies on x86_64 manylinux wheels).
"$venv/bin/python" - <<'PY'
import gmsh, meshio, numpy, vtk, pytest
gmsh.initialize(["-noenv"], readConfigFiles=False)
v = gmsh.option.getString("General.Version")
gmsh.finalize()
print(f"setup_python: gmsh {v}, meshio {meshio.__version__}, numpy {numpy.__version__}, "
      f"vtk {vtk.vtkVersion.GetVTKVersion()}, pytest {pytest.__version__}")
PY
cp "$req" "$stamp"
