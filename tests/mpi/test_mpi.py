"""`mpirun -np N hocurve-mpi curve ...` against the serial `hocurve curve`.

For N = 1, 2, 3 and 4 processes (oversubscribed on a 2-core machine) and
p = 2..5, on a 2D gmsh plate with a hole, a 3D gmsh sphere cavity whose
repair removes a cap, and a gmsh cylinder cavity with feature curves (its
rims, circle3):

- the elastic stage alone (`--optimize off`) must give the serial run's
  mesh: every node within 1e-4 of the smallest edge of the mesh (the
  solvers stop at a relative residual of 1e-5: PETSc's CG with GAMG there,
  the built-in direct or PCG solver here), the same invalid-cell counts
  (zero) and min Q3 within 1e-4;
- with the defaults (the optimisation on, which runs on rank 0 from the
  elastic stage's mesh), the same invalid-cell counts (zero) and min Q3
  within 0.01: the optimisation's path follows differences within the
  solver's tolerance (measured: 0.004 on the sphere cavity at p = 5).

Then a run that cannot succeed must fail the same way on every process,
leave no output, and say so once.

The binaries are target/release/hocurve and HOCURVE_MPI_BIN, by default
target/mpi/release/hocurve-mpi (scripts/test_all.sh builds it with
`CARGO_TARGET_DIR=target/mpi cargo build --release --features mpi`, apart
from the default build, whose library links no MPI); mpirun is OpenMPI's.
"""
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))
BIN = REPO / "target" / "release"
MPI_BIN = Path(os.environ.get("HOCURVE_MPI_BIN", REPO / "target" / "mpi" / "release" / "hocurve-mpi"))
MPIRUN = shutil.which("mpirun")

# Node distance to the serial run, relative to the smallest edge, and min
# Q3's difference, for the elastic stage alone and with the optimisation.
NODE_TOL = 1e-4
Q3_TOL = {"off": 1e-4, "on": 1e-2}


def read_msh_nodes_and_cells(path):
    """({tag: (x, y, z)}, [vertex tags of each cell]) of an ASCII gmsh 4.1 file."""
    lines = Path(path).read_text().split("\n")
    nodes, cells = {}, []
    i = 0
    while i < len(lines):
        if lines[i] == "$Nodes":
            blocks = int(lines[i + 1].split()[0])
            i += 2
            for _ in range(blocks):
                dim, _tag, _param, n = map(int, lines[i].split())
                tags = [int(t) for t in lines[i + 1 : i + 1 + n]]
                xyz = [tuple(map(float, l.split())) for l in lines[i + 1 + n : i + 1 + 2 * n]]
                nodes.update(zip(tags, xyz))
                i += 1 + 2 * n
            continue
        if lines[i] == "$Elements":
            blocks = int(lines[i + 1].split()[0])
            i += 2
            for _ in range(blocks):
                dim, _tag, _etype, n = map(int, lines[i].split())
                for l in lines[i + 1 : i + 1 + n]:
                    if dim >= 2:
                        cells.append((dim, [int(t) for t in l.split()[1:]]))
                i += 1 + n
            continue
        i += 1
    top = max(d for d, _ in cells)
    return nodes, [c[: top + 1] for d, c in cells if d == top]


def smallest_edge(nodes, cells):
    h = math.inf
    for c in cells:
        for a in range(len(c)):
            for b in range(a + 1, len(c)):
                h = min(h, math.dist(nodes[c[a]], nodes[c[b]]))
    return h


def serial(args, out):
    r = subprocess.run([str(BIN / "hocurve"), "curve", *args, "--output", out / "s.msh", "--report", out / "s.json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return json.loads((out / "s.json").read_text())


def distributed(n, args, out, name="m"):
    cmd = [MPIRUN, "--allow-run-as-root", "--oversubscribe", "-np", str(n), str(MPI_BIN), "curve", *args,
           "--output", out / f"{name}.msh", "--report", out / f"{name}.json"]
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=600)


def cylinder_cavity(tmp_path_factory):
    """The corpus's small gmsh cylinder cavity (feature curves: its two rims)."""
    d = tmp_path_factory.mktemp("cyl")
    r = subprocess.run([sys.executable, str(REPO / "scripts" / "gen_corpus.py"), "--out", str(d), "--only",
                        "gmsh-cylcav-r0.5-n6-h1"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    case = json.loads((d / "manifest.json").read_text())["cases"][0]
    geometry = [a for g in case["geometry"] for a in ("--geometry", g)]
    return [str(d / case["file"]), *geometry]


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    data = REPO / "tests" / "data"
    return {
        "plate-2d": [str(data / "plate_hole_2d.msh"), "--geometry", "5=circle:1,0.5,0.25"],
        "sphere-caps": [str(data / "sphere_cavity_cap_gmsh.msh"), "--geometry", "7=sphere:0,0,0,0.6"],
        "cylinder-features": cylinder_cavity(tmp_path_factory),
    }


@pytest.fixture(scope="module", autouse=True)
def binaries():
    assert MPIRUN, "mpirun not found (Debian: openmpi-bin)"
    for b in (BIN / "hocurve", MPI_BIN):
        assert b.is_file(), f"{b} not found: see this file's docstring for how to build it"


@pytest.mark.parametrize("optimize", ["off", "on"])
@pytest.mark.parametrize("case", ["plate-2d", "sphere-caps", "cylinder-features"])
@pytest.mark.parametrize("order", [2, 3, 4, 5])
def test_distributed_run_gives_the_serial_mesh(cases, case, order, optimize, tmp_path):
    args = [*cases[case], "--order", str(order), "--optimize", optimize]
    s = serial(args, tmp_path)
    s_nodes, s_cells = read_msh_nodes_and_cells(tmp_path / "s.msh")
    h = smallest_edge(s_nodes, s_cells)
    if case == "sphere-caps":
        assert s["removed_caps"] + s["repair"]["surface_caps"] > 0, "the case is meant to remove caps"
    for n in (1, 2, 3, 4):
        r = distributed(n, args, tmp_path)
        assert r.returncode == 0, f"np {n}:\n{r.stderr}"
        m = json.loads((tmp_path / "m.json").read_text())
        assert m["ranks"] == n
        assert m["linear_solver"] == "petsc-cg-pmg"
        assert all(i > 0 for i in m["solver_iterations"]), m["solver_iterations"]
        assert m["cells"] == s["cells"] and m["nodes"] == s["nodes"]
        assert m["invalid_elements"] == s["invalid_elements"] == 0
        assert m["certified_invalid_elements"] == s["certified_invalid_elements"] == 0
        assert abs(m["min_q3"] - s["min_q3"]) < Q3_TOL[optimize], (n, m["min_q3"], s["min_q3"])
        m_nodes, _ = read_msh_nodes_and_cells(tmp_path / "m.msh")
        assert m_nodes.keys() == s_nodes.keys()
        worst = max(math.dist(m_nodes[t], s_nodes[t]) for t in s_nodes) / h
        print(f"{case} p={order} optimize {optimize} np={n}: max node distance {worst:.2e} h, "
              f"min Q3 {m['min_q3']:.4f} (serial {s['min_q3']:.4f}), iterations {m['solver_iterations']}")
        if optimize == "off":
            assert worst < NODE_TOL, (n, worst)


def test_an_elastic_stage_that_stops_short_stops_where_the_serial_one_does(tmp_path):
    # The gmsh sphere cavity of radius 0.6 at p = 3: adaptive stepping gives
    # up at load 0.9 on cell 1862; the rest of the load comes from the first
    # increment's solution (gathered from every process) and the
    # optimisation untangles the cell.
    args = [str(REPO / "tests" / "data" / "sphere_cavity_r06_gmsh.msh"), "--geometry", "7=sphere:0,0,0,0.6",
            "--order", "3"]
    s = serial(args, tmp_path)
    assert s["elastic_stop"] is not None and s["optimization"]["invalid_before"] > 0
    for n in (1, 2, 3, 4):
        r = distributed(n, args, tmp_path)
        assert r.returncode == 0, f"np {n}:\n{r.stderr}"
        m = json.loads((tmp_path / "m.json").read_text())
        assert m["step_backs"] == s["step_backs"] and m["load_fractions"] == s["load_fractions"]
        assert m["elastic_stop"] == s["elastic_stop"]
        assert m["certified_invalid_elements"] == 0
        assert abs(m["min_q3"] - s["min_q3"]) < Q3_TOL["on"], (n, m["min_q3"], s["min_q3"])


def test_a_failing_run_fails_alike_on_every_process_and_writes_nothing(cases, tmp_path):
    # One increment, no step back, no optimisation: the sphere cavity with
    # its caps kept inverts a cell in the elastic stage.
    args = [*cases["sphere-caps"], "--order", "3", "--increments", "1", "--adaptive", "on", "--max-splits", "0",
            "--optimize", "off", "--caps", "keep", "--repair", "off", "--retry", "off"]
    s = subprocess.run([str(BIN / "hocurve"), "curve", *args, "--output", tmp_path / "s.msh"],
                       capture_output=True, text=True, timeout=600)
    assert s.returncode != 0, "the serial run was expected to fail"
    for n in (2, 3):
        r = distributed(n, args, tmp_path)
        assert r.returncode != 0
        assert not (tmp_path / "m.msh").exists() and not (tmp_path / "m.json").exists()
        errors = [l for l in r.stderr.splitlines() if l.startswith("error")]
        assert errors == [e.replace("hocurve: error:", "error (rank 0):") for e in s.stderr.splitlines()
                          if e.startswith("hocurve: error")], r.stderr


@pytest.mark.parametrize("case", ["plate-2d", "sphere-caps"])
def test_partitioned_output_is_the_gathered_mesh_in_one_part_per_process(cases, case, tmp_path):
    gmsh = pytest.importorskip("gmsh")
    args = [*cases[case], "--order", "3"]
    for n in (2, 3):
        r = distributed(n, args, tmp_path, name="whole")
        assert r.returncode == 0, r.stderr
        r = distributed(n, [*args, "--partitioned", "on"], tmp_path, name="parts")
        assert r.returncode == 0, r.stderr
        whole_nodes, whole_cells = read_msh_nodes_and_cells(tmp_path / "whole.msh")
        gmsh.initialize()
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.open(str(tmp_path / "parts.msh"))
            assert gmsh.model.getNumberOfPartitions() == n
            dim = gmsh.model.getDimension()
            parts = [(t, gmsh.model.getPartitions(dim, t)) for _, t in gmsh.model.getEntities(dim)]
            parts = [(t, list(p)) for t, p in parts if len(p) > 0]
            assert sorted(p[0] for _, p in parts) == list(range(1, n + 1)), parts
            cells = {}
            for t, _ in parts:
                assert gmsh.model.getParent(dim, t) == (dim, 1)
                _, tags, nodes = gmsh.model.mesh.getElements(dim, t)
                npc = len(nodes[0]) // len(tags[0])
                for e, k in zip(tags[0], range(0, len(nodes[0]), npc)):
                    cells[int(e)] = [int(v) for v in nodes[0][k : k + dim + 1]]
            assert len(cells) == len(whole_cells) and sorted(cells) == list(range(1, len(whole_cells) + 1))
            assert all(cells[e + 1] == c for e, c in enumerate(whole_cells))
            tags, xyz, _ = gmsh.model.mesh.getNodes()
            assert sorted(int(t) for t in tags) == sorted(whole_nodes)
            for k, t in enumerate(tags):
                assert math.dist(xyz[3 * k : 3 * k + 3], whole_nodes[int(t)]) < 1e-12
        finally:
            gmsh.finalize()
    r = subprocess.run([str(BIN / "hocurve"), "curve", *args, "--partitioned", "on", "--output", tmp_path / "s.msh"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode != 0 and "only hocurve-mpi" in r.stderr, r.stderr
