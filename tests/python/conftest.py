"""Shared fixtures for the end-to-end tests of the `hocurve` binary.

The binary is `target/release/hocurve` (override with HOCURVE_BIN); the suite
stops at once with a clear message when it is missing. gmsh is initialised
once per session; each test builds its own model and clears it afterwards.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

REPO = Path(__file__).resolve().parents[2]


def hocurve_bin() -> Path:
    return Path(os.environ.get("HOCURVE_BIN", REPO / "target" / "release" / "hocurve"))


def pytest_sessionstart(session):
    b = hocurve_bin()
    if not (b.is_file() and os.access(b, os.X_OK)):
        pytest.exit(
            f"hocurve binary not found at {b}: run `cargo build --release` first "
            "or set HOCURVE_BIN to the binary",
            returncode=3,
        )


class Hocurve:
    """Runs the binary; `run` returns the CompletedProcess, `ok` also checks exit 0."""

    def __init__(self, path: Path):
        self.path = path

    def run(self, *args, timeout=600):
        return subprocess.run(
            [str(self.path), *map(str, args)], capture_output=True, text=True, timeout=timeout
        )

    def ok(self, *args, timeout=600):
        r = self.run(*args, timeout=timeout)
        assert r.returncode == 0, (
            f"hocurve {' '.join(map(str, args))} exited {r.returncode}\n"
            f"stdout:\n{r.stdout}\nstderr:\n{r.stderr}"
        )
        return r

    def curve(self, msh, order, geometry, output, report, *extra):
        args = ["curve", msh, "--order", order]
        for g in geometry:
            args += ["--geometry", g]
        args += ["--output", output, "--report", report, *extra]
        self.ok(*args)
        return json.loads(Path(report).read_text())


@pytest.fixture(scope="session")
def hocurve():
    return Hocurve(hocurve_bin())


@pytest.fixture(scope="session")
def gmsh_session():
    import gmsh

    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    yield gmsh
    gmsh.finalize()


@pytest.fixture
def gmsh(gmsh_session):
    gmsh_session.clear()
    yield gmsh_session
    gmsh_session.clear()
    # Plugin views outlive models: drop them too.
    for v in gmsh_session.view.getTags():
        gmsh_session.view.remove(v)
