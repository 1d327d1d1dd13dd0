"""The C ABI's distributed mesh (hoc_mesh_create_distributed) under mpirun,
against the serial `hocurve curve`.

Each process of `mpirun -np N distributed` (tests/mpi/distributed.c, and the
same through the C++ wrapper and the Fortran module; linked
with the library built with the `mpi` feature) gives hocurve its own share
of a gmsh mesh (its cells, every vertex they use with its global id, its
boundary facets) and its own projector (a circle or sphere). The
shares are cut here, two ways: slabs along x, so that process 0 projects
onto the curved boundary itself; and shells around the curved boundary,
outermost first, so that process 0 holds none of it and every projection
goes to another process. Then:

- the shares together are the serial run's mesh: every cell once, each
  node within 1e-4 of the smallest edge of the serial node (the elastic
  stage alone; with the optimisation, no invalid cell and min Q3 within
  0.01, as for `hocurve-mpi`);
- the global node indices are consistent: a node held by several
  processes has one index and one position, every index of the whole mesh
  is held, and its owner is the lowest process holding it;
- the quality figures are the whole mesh's, the same on every process;
- a projector that fails on one process fails the run on every process
  with the same status and message, and leaves every share as it was.
"""
import math
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from test_mpi import BIN, MPIRUN, REPO, read_msh_nodes_and_cells, serial, smallest_edge

MPI_LIB = Path(os.environ.get("HOCURVE_MPI_LIB", REPO / "target" / "mpi" / "release"))
HOC_OK, HOC_ERROR_NULL_POINTER, HOC_ERROR_INVALID_ARGUMENT, HOC_ERROR_PROJECTION = 0, 1, 2, 4
NODE_TOL = 1e-4

CASES = {
    "plate-2d": ("plate_hole_2d.msh", 5, (1.0, 0.5, 0.0, 0.25), "circle:1,0.5,0.25"),
    "sphere-caps": ("sphere_cavity_cap_gmsh.msh", 7, (0.0, 0.0, 0.0, 0.6), "sphere:0,0,0,0.6"),
}


@pytest.fixture(scope="module")
def programs(tmp_path_factory):
    """distributed.c, .cpp (hocurve.hpp) and .f90 (the hocurve module), linked with the library built with MPI."""
    mpicc, mpicxx, mpif90 = shutil.which("mpicc"), shutil.which("mpicxx"), shutil.which("mpif90")
    assert mpicc and mpicxx and mpif90, "mpicc, mpicxx or mpif90 not found (Debian: libopenmpi-dev, g++, gfortran)"
    assert (MPI_LIB / "libhocurve.so").is_file(), f"{MPI_LIB}/libhocurve.so: build with --features mpi"
    d = tmp_path_factory.mktemp("bin")
    # The library's file as its soname (libhocurve.so.MAJOR.MINOR) names it.
    soname = subprocess.run(["objdump", "-p", str(MPI_LIB / "libhocurve.so")], capture_output=True, text=True,
                            check=True).stdout.split("SONAME")[1].split()[0]
    (d / soname).symlink_to(MPI_LIB / "libhocurve.so")
    link = [str(MPI_LIB / "libhocurve.so"), f"-Wl,-rpath,{d}", "-lm"]
    here = REPO / "tests" / "mpi"
    subprocess.run([mpicc, "-std=c99", "-Wall", "-Werror", "-O1", str(here / "distributed.c"), "-I",
                    str(REPO / "include"), *link, "-o", str(d / "distributed")], check=True)
    subprocess.run([mpicxx, "-std=c++17", "-Wall", "-Werror", "-O1", str(here / "distributed.cpp"), "-I",
                    str(REPO / "include"), *link, "-o", str(d / "distributed_cpp")], check=True)
    subprocess.run([mpif90, "-std=f2008", "-Wall", "-Werror",
                    "-Wno-unused-dummy-argument", "-O1", "-J", str(d), str(REPO / "include" / "hocurve.f90"),
                    str(here / "distributed.f90"), *link, "-o", str(d / "distributed_f")], check=True)
    return {"c": d / "distributed", "c++": d / "distributed_cpp", "fortran": d / "distributed_f"}


def read_msh(path):
    """(dim, {tag: xyz}, cells as vertex tags, [(facet vertex tags, entity tag)]) of a gmsh 4.1 file."""
    nodes, cells = read_msh_nodes_and_cells(path)
    dim = len(cells[0]) - 1
    lines = Path(path).read_text().split("\n")
    facets = []
    i = lines.index("$Elements") + 2
    while lines[i] != "$EndElements":
        edim, etag, _, n = map(int, lines[i].split())
        if edim == dim - 1:
            facets += [([int(t) for t in l.split()[1:]], etag) for l in lines[i + 1 : i + 1 + n]]
        i += 1 + n
    return dim, nodes, cells, facets


def partition(dim, nodes, cells, n, how, centre):
    """The process of each cell: `n` slabs along x, or `n` shells by distance to `centre`, outermost first."""
    def key(c):
        x = [sum(nodes[v][j] for v in c) / len(c) for j in range(3)]
        return x[0] if how == "slabs" else -math.dist(x[:dim], centre[:dim])
    order = sorted(range(len(cells)), key=lambda k: key(cells[k]))
    part = [0] * len(cells)
    for rank_, k in enumerate(order):
        part[k] = rank_ * n // len(cells)
    return part


def write_shares(d, dim, nodes, cells, facets, part, n, tag, shape):
    """DIR/part.R.txt for each process (see distributed.c)."""
    face_of = {}
    for k, c in enumerate(cells):
        for skip in range(dim + 1):
            face_of[frozenset(c[:skip] + c[skip + 1 :])] = k
    holders = set()
    for r in range(n):
        mine = [c for c, p in zip(cells, part) if p == r]
        verts = sorted({v for c in mine for v in c})
        local = {v: k for k, v in enumerate(verts)}
        fs = [(f, t) for f, t in facets if t == tag and part[face_of[frozenset(f)]] == r]
        if fs:
            holders.add(r)
        lines = [f"{dim} {len(verts)} {len(mine)} {len(fs)} 1"]
        lines += [f"{v} " + " ".join(repr(x) for x in nodes[v][:dim]) for v in verts]
        lines += [" ".join(str(local[v]) for v in c) for c in mine]
        lines += [" ".join(str(local[v]) for v in f) + f" {t}" for f, t in fs]
        lines.append(f"{tag} " + " ".join(repr(x) for x in shape))
        (d / f"part.{r}.txt").write_text("\n".join(lines) + "\n")
    return min(holders)


def run(program, d, dim, n, order, optimize, fail_rank=-1, *more):
    """Each process's output (see distributed.c)."""
    r = subprocess.run([MPIRUN, "--allow-run-as-root", "--oversubscribe", "-np", str(n), str(program), str(d),
                        str(order), str(int(optimize == "on")), str(fail_rank), *map(str, more)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    outs = []
    for rank_ in range(n):
        lines = (d / f"out.{rank_}.txt").read_text().split("\n")
        out = {"status": int(lines[0]), "message": lines[1], "unchanged": lines[2] == "1"}
        if out["status"] == HOC_OK:
            nn, nc, _, q3, inv, cinv, *report = lines[3].split()
            nn, nc = int(nn), int(nc)
            out.update(min_q3=float(q3), invalid=int(inv), certified_invalid=int(cinv),
                       report=tuple(map(int, report)))
            out["nodes"] = [(int(v[0]), int(v[1]), tuple(map(float, v[2:]))) for v in
                            (l.split() for l in lines[4 : 4 + nn])]
            out["cells"] = []
            for l in lines[4 + nn : 4 + nn + nc]:
                v = l.split()
                xyz = [float(x) for x in v[dim + 1 :]]
                out["cells"].append((tuple(int(x) for x in v[: dim + 1]), [xyz[k : k + dim] for k in range(0, len(xyz), dim)]))
        outs.append(out)
    return outs


def serial_cells(path, dim, input_nodes, facets):
    """{vertex ids of a cell: its nodes in gmsh's order} of the serial run's output. Its
    vertices keep the input's numbers (tags 1..n there, every one a vertex of a cell):
    checked on the boundary vertices, which the elastic stage does not move."""
    nodes, _ = read_msh_nodes_and_cells(path)
    assert sorted(input_nodes) == list(range(1, len(input_nodes) + 1))
    assert all(nodes[v] == input_nodes[v] for f, _ in facets for v in f)
    lines = Path(path).read_text().split("\n")
    cells = {}
    i = lines.index("$Elements") + 2
    while lines[i] != "$EndElements":
        edim, _, _, n = map(int, lines[i].split())
        if edim == dim:
            for l in lines[i + 1 : i + 1 + n]:
                tags = [int(t) for t in l.split()[1:]]
                cells[frozenset(tags[: dim + 1])] = [nodes[t][:dim] for t in tags]
        i += 1 + n
    return cells


@pytest.mark.parametrize("how", ["slabs", "shells"])
@pytest.mark.parametrize("optimize", ["off", "on"])
@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("order", [2, 4])
def test_the_shares_together_are_the_serial_mesh(programs, case, order, optimize, how, tmp_path):
    against_serial(programs["c"], case, order, optimize, how, tmp_path)


@pytest.mark.parametrize("case, order, optimize, how", [("sphere-caps", 2, "off", "shells"),
                                                        ("plate-2d", 4, "on", "slabs")])
@pytest.mark.parametrize("lang", ["c++", "fortran"])
def test_the_cpp_and_fortran_interfaces_give_the_same_shares(programs, lang, case, order, optimize, how, tmp_path):
    against_serial(programs[lang], case, order, optimize, how, tmp_path)


def against_serial(program, case, order, optimize, how, tmp_path):
    """Curve `case`'s shares (cut `how`) on 1, 2 and 3 processes with `program`; compare with the serial run."""
    name, tag, shape, spec = CASES[case]
    msh = REPO / "tests" / "data" / name
    dim, nodes, cells, facets = read_msh(msh)
    s = serial([str(msh), "--geometry", f"{tag}={spec}", "--order", str(order), "--optimize", optimize], tmp_path)
    s_nodes, s_cells = read_msh_nodes_and_cells(tmp_path / "s.msh")
    h = smallest_edge(s_nodes, s_cells)
    expected = serial_cells(tmp_path / "s.msh", dim, nodes, facets) if optimize == "off" else None
    for n in (1, 2, 3):
        part = partition(dim, nodes, cells, n, how, shape)
        holder = write_shares(tmp_path, dim, nodes, cells, facets, part, n, tag, shape)
        assert how == "slabs" or n == 1 or holder > 0, "the shells are meant to keep the boundary off process 0"
        outs = run(program, tmp_path, dim, n, order, optimize)
        assert all(o["status"] == HOC_OK for o in outs), [o["message"] for o in outs]
        # The whole mesh's figures, the same everywhere.
        for key in ("min_q3", "invalid", "certified_invalid", "report"):
            assert len({o[key] for o in outs}) == 1, (key, [o[key] for o in outs])
        q = outs[0]
        assert q["invalid"] == q["certified_invalid"] == 0 == s["invalid_elements"]
        assert abs(q["min_q3"] - s["min_q3"]) < (1e-4 if optimize == "off" else 1e-2), (q["min_q3"], s["min_q3"])
        assert sum(len(o["cells"]) for o in outs) == s["cells"]
        if q["report"]:
            # The run's figures on every process, the serial run's (the solves' count aside:
            # PETSc's, not the built-in solver's, decide nothing the counts depend on).
            taken, backs, solves, fallbacks, caps, ran = q["report"]
            assert (taken, backs, caps) == (len(s["load_fractions"]), len(s["step_backs"]), s["removed_caps"])
            assert solves == len(s["solver_iterations"]) and fallbacks == 0
            assert ran == int(s["optimization"]["ran"])
        # Global node indices: one position per index, every index held, the owner the lowest holder.
        position, holders, owners = {}, {}, {}
        for r, o in enumerate(outs):
            for g, owner, x in o["nodes"]:
                assert position.setdefault(g, x) == x, (g, position[g], x)
                holders.setdefault(g, set()).add(r)
                owners.setdefault(g, set()).add(owner)
        assert sorted(holders) == list(range(s["nodes"]))
        assert all(owners[g] == {min(holders[g])} for g in holders)
        if expected is not None:
            worst = 0.0
            for o in outs:
                for ids, xs in o["cells"]:
                    ref = expected[frozenset(ids)]
                    worst = max(worst, max(math.dist(a, b) for a, b in zip(xs, ref)) / h)
            print(f"{case} p={order} {how} np={n}: max node distance {worst:.2e} h")
            assert worst < NODE_TOL, (n, worst)


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("lang", ["c", "c++", "fortran"])
def test_a_projector_failing_on_one_process_fails_the_run_alike_everywhere(programs, lang, case, tmp_path):
    name, tag, shape, _ = CASES[case]
    dim, nodes, cells, facets = read_msh(REPO / "tests" / "data" / name)
    for n, how in ((2, "shells"), (3, "slabs")):
        part = partition(dim, nodes, cells, n, how, shape)
        holder = write_shares(tmp_path, dim, nodes, cells, facets, part, n, tag, shape)
        outs = run(programs[lang], tmp_path, dim, n, 3, "on", fail_rank=holder)
        assert all(o["status"] == HOC_ERROR_PROJECTION for o in outs), [o["status"] for o in outs]
        assert len({o["message"] for o in outs}) == 1, [o["message"] for o in outs]
        assert f"process {holder}" in outs[0]["message"] or holder == 0, outs[0]["message"]
        assert "callback returned 7" in outs[0]["message"], outs[0]["message"]
        assert all(o["unchanged"] for o in outs)


def test_a_setting_refused_on_one_process_is_refused_on_all(programs, tmp_path):
    # Process 1 alone asks for 0 increments: no process is left waiting for it.
    name, tag, shape, _ = CASES["plate-2d"]
    dim, nodes, cells, facets = read_msh(REPO / "tests" / "data" / name)
    write_shares(tmp_path, dim, nodes, cells, facets, partition(dim, nodes, cells, 3, "slabs", shape), 3, tag, shape)
    outs = run(programs["c"], tmp_path, dim, 3, 2, "on", -1, 1)
    assert [o["status"] for o in outs] == [HOC_ERROR_INVALID_ARGUMENT] * 3
    assert {o["message"] for o in outs} == {"invalid input: increments must be >= 1"}
    assert all(o["unchanged"] for o in outs)


def test_a_null_handle_address_on_one_process_fails_the_create_on_all(programs, tmp_path):
    # Process 2 alone passes NULL for the handle's address: no process is left waiting.
    name, tag, shape, _ = CASES["plate-2d"]
    dim, nodes, cells, facets = read_msh(REPO / "tests" / "data" / name)
    write_shares(tmp_path, dim, nodes, cells, facets, partition(dim, nodes, cells, 3, "slabs", shape), 3, tag, shape)
    outs = run(programs["c"], tmp_path, dim, 3, 2, "on", -1, -1, 2)
    assert [o["status"] for o in outs] == [HOC_ERROR_NULL_POINTER] * 3
    assert {o["message"] for o in outs} == {"out is NULL"}
    assert all(o["unchanged"] for o in outs), "no handle is made"
