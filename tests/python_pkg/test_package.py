"""Tests of the Python package `hocurve` (python/): install it with
`pip install ./python`, then `pytest tests/python_pkg`.

The comparison with the command line needs `target/release/hocurve`
(`cargo build --release`, or HOCURVE_BIN); the STEP round trip makes its
own STEP file with gmsh's OpenCASCADE kernel, and also runs on the parts of
`../shared/cad/` when that directory exists.
"""

import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import gmsh
from gmsh_session import gmsh_session
import meshio
import numpy as np
import pytest

import hocurve
import hocurve.gmsh

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data"
SPHERE = DATA / "sphere_cavity_r06_gmsh.msh"  # gmsh, sphere of radius 0.6 on surface 7 in [-2, 2]^3
SPHERE_SHAPE = {7: "sphere:0,0,0,0.6"}
CAD = REPO.parent / "shared" / "cad"


def cli() -> Path:
    b = Path(os.environ.get("HOCURVE_BIN", REPO / "target" / "release" / "hocurve"))
    assert b.is_file(), f"{b} is missing: run `cargo build --release` or set HOCURVE_BIN"
    return b


def sphere_mesh(**kw) -> hocurve.Mesh:
    return hocurve.from_meshio(meshio.read(SPHERE), **kw)


def on_sphere(points: np.ndarray) -> np.ndarray:
    return 0.6 * points / np.linalg.norm(points, axis=1, keepdims=True)


def sphere_mesh_projected(project) -> hocurve.Mesh:
    """The sphere cavity with a Python projector for the sphere (surface 7),
    every other facet and feature edge held straight, as the command line
    does for tags without a shape."""
    mesh = sphere_mesh()
    mesh.set_projector(project)
    mesh.set_straight(2, [t for t in mesh.tags(2) if t != 7])
    mesh.set_straight(1, mesh.tags(1))
    return mesh


@pytest.mark.parametrize(
    "msh, geometry, order",
    [(DATA / "plate_hole_2d.msh", {5: "circle:1,0.5,0.25"}, 4), (SPHERE, SPHERE_SHAPE, 2)],
)
def test_the_same_mesh_as_the_command_line_bitwise(tmp_path, msh, geometry, order):
    out_cli, out_py = tmp_path / "cli.msh", tmp_path / "py.msh"
    args = [str(cli()), "curve", str(msh), "--order", str(order), "--output", str(out_cli)]
    for tag, shape in geometry.items():
        args += ["--geometry", f"{tag}={shape}"]
    subprocess.run(args, check=True, capture_output=True)
    mesh = hocurve.from_meshio(meshio.read(msh), shapes=geometry)
    result = mesh.run(order)
    mesh.write(out_py)
    assert out_py.read_bytes() == out_cli.read_bytes()
    assert result.valid and result.order == order
    npc = (order + 1) * (order + 2) // 2 if mesh.dim == 2 else (order + 1) * (order + 2) * (order + 3) // 6
    assert result.cells.shape == (len(result.cell_quality), npc)
    # Every node is used, and the summary is the cells' own.
    assert np.array_equal(np.unique(result.cells), np.arange(len(result.nodes)))
    assert result.quality["min_q3"] == pytest.approx(result.cell_quality[:, 2].min())


def test_the_built_in_2d_case_as_the_command_line_s_demo(tmp_path):
    subprocess.run([str(cli()), "demo", "--output-dir", str(tmp_path)], check=True, capture_output=True)
    mesh = hocurve.demo_mesh("cylinder-2d")
    result = mesh.run(4, progress=True)
    mesh.write(tmp_path / "py-2d.vtu")
    assert (tmp_path / "py-2d.vtu").read_bytes() == (tmp_path / "demo-2d.vtu").read_bytes()
    assert result.valid
    with pytest.raises(hocurve.InvalidInputError, match="unknown demo case"):
        hocurve.demo_mesh("sphere")


def test_a_projector_that_raises_leaves_the_mesh_unchanged():
    calls = []

    class Broken(Exception):
        pass

    def project(dim, tag, points):
        if calls:  # armed: the third projection raises
            calls.append(len(points))
            if len(calls) > 3:
                raise Broken(f"no CAD for tag {tag}")
        return on_sphere(points)

    mesh = sphere_mesh_projected(project)
    curved = mesh.run(2)
    calls.append(0)
    with pytest.raises(hocurve.ProjectionError) as info:
        mesh.run(3)
    assert isinstance(info.value.__cause__, Broken)
    assert "no CAD for tag 7" in str(info.value) and info.value.status == "projection"
    after = mesh.result()
    assert after.order == 2
    assert np.array_equal(after.nodes, curved.nodes) and np.array_equal(after.cells, curved.cells)
    assert after.report == curved.report


def test_a_projector_returning_the_wrong_shape_is_a_clean_error():
    mesh = sphere_mesh_projected(lambda dim, tag, points: points[:, :2])
    with pytest.raises(hocurve.ProjectionError, match=r"expected \(\d+, 3\)"):
        mesh.run(2)


def test_a_python_projector_gives_the_analytic_shape_s_mesh():
    by_shape = sphere_mesh(shapes=SPHERE_SHAPE).run(2)
    by_python = sphere_mesh_projected(lambda dim, tag, p: on_sphere(p)).run(2)
    assert by_python.valid
    assert np.abs(by_python.nodes - by_shape.nodes).max() < 1e-9


def test_bad_input_raises_invalid_input():
    with pytest.raises(hocurve.InvalidInputError):
        hocurve.Mesh(np.zeros((3, 2)), [[0, 1, 5]])
    with pytest.raises(hocurve.InvalidInputError):
        hocurve.Mesh(np.zeros((3, 2)), [[0.0, 1.0, 2.0]])
    mesh = sphere_mesh(shapes=SPHERE_SHAPE)
    with pytest.raises(hocurve.InvalidInputError, match="order"):
        mesh.run(11)
    with pytest.raises(hocurve.InvalidInputError):
        mesh.run(2, formulation="elastic")
    with pytest.raises(hocurve.InvalidInputError):
        mesh.set_shapes({7: "ellipsoid:1,2,3"})


def test_the_gil_is_released_during_a_run():
    mesh = sphere_mesh(shapes=SPHERE_SHAPE)
    ticks = [0]
    running = threading.Event()

    def count():
        while not running.is_set():
            time.sleep(0.001)
        while running.is_set():
            ticks[0] += 1

    t = threading.Thread(target=count)
    t.start()
    running.set()
    start = ticks[0]
    mesh.run(4, increments=2)
    during = ticks[0] - start
    running.clear()
    t.join()
    # A thread held off by the GIL would get a tick per switch interval at most.
    assert during > 100_000, during


@pytest.mark.parametrize("killing", [False, True])
def test_ctrl_c_cancels_the_run_and_keeps_the_mesh(killing):
    # gmsh.initialize() leaves SIGINT killing the process (SIG_DFL), even
    # after gmsh.finalize(); a run still turns Ctrl-C into KeyboardInterrupt.
    previous = signal.signal(signal.SIGINT, signal.SIG_DFL if killing else signal.default_int_handler)
    mesh = sphere_mesh(shapes=SPHERE_SHAPE)
    before = mesh.result()
    stages = []

    def progress(stage, step, total):
        stages.append(stage)
        if stage == "increment" and step == 1:
            os.kill(os.getpid(), signal.SIGINT)

    try:
        with pytest.raises(KeyboardInterrupt):
            mesh.run(4, progress=progress)
        assert signal.getsignal(signal.SIGINT) == (signal.SIG_DFL if killing else signal.default_int_handler)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert "increment" in stages
    after = mesh.result()
    assert np.array_equal(after.nodes, before.nodes) and after.report == {}


def test_a_progress_callback_that_returns_false_cancels():
    mesh = sphere_mesh(shapes=SPHERE_SHAPE)
    with pytest.raises(hocurve.CancelledError):
        mesh.run(2, progress=lambda stage, step, total: stage != "increment")


def test_meshio_round_trip(tmp_path):
    result = sphere_mesh(shapes=SPHERE_SHAPE).run(3)
    m = hocurve.to_meshio(result)
    assert m.cells[0].type == "tetra20"
    path = tmp_path / "curved.msh"
    meshio.write(path, m, file_format="gmsh")
    back = meshio.read(path)
    assert np.array_equal(back.cells[0].data, result.cells)
    assert np.allclose(back.points, result.nodes)
    # gmsh reads it as 20-node tetrahedra, valid by its own Jacobian bounds.
    with gmsh_session():
        gmsh.open(str(path))
        types, tags, _ = gmsh.model.mesh.getElements(3)
        assert list(types) == [gmsh.model.mesh.getElementType("tetrahedron", 3)]
        q = gmsh.model.mesh.getElementQualities(tags[0], "minSJ")
        assert len(q) == len(result.cells) and q.min() > 0
    # 2D: the z column is added for meshio and dropped on the way back in.
    plate = hocurve.from_meshio(meshio.read(DATA / "plate_hole_2d.msh"), shapes={5: "circle:1,0.5,0.25"})
    m2 = hocurve.to_meshio(plate.run(2))
    assert m2.cells[0].type == "triangle6" and m2.points.shape[1] == 3


def _step_part(path: Path) -> None:
    """A box with a cylindrical hole and a spherical dimple, written as STEP."""
    gmsh.model.add("part")
    box = gmsh.model.occ.addBox(0, 0, 0, 4, 3, 2)
    hole = gmsh.model.occ.addCylinder(2, 1.5, -1, 0, 0, 4, 0.7)
    dimple = gmsh.model.occ.addSphere(0, 0, 2, 1.0)
    gmsh.model.occ.cut([(3, box)], [(3, hole), (3, dimple)])
    gmsh.model.occ.synchronize()
    gmsh.write(str(path))
    gmsh.model.remove()


def _curve_step(path: Path, size: float, order: int, out: Path) -> hocurve.Result:
    gmsh.model.add("curved")
    gmsh.model.occ.importShapes(str(path))
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.model.mesh.generate(3)
    result = hocurve.gmsh.curve_model(order)
    gmsh.write(str(out))
    return result


def _check_written(out: Path, result: hocurve.Result, order: int) -> None:
    """The model's mesh after write-back: the curved cells, valid by gmsh's
    own measure, and boundary elements of the same order whose nodes lie on
    their surface."""
    gmsh.model.add("check")
    gmsh.merge(str(out))
    tet = gmsh.model.mesh.getElementType("tetrahedron", order)
    tri = gmsh.model.mesh.getElementType("triangle", order)
    types, tags, _ = gmsh.model.mesh.getElements(3)
    assert list(types) == [tet]
    assert len(tags[0]) == len(result.cells)
    assert gmsh.model.mesh.getElementQualities(tags[0], "minSJ").min() > 0
    types2, _, _ = gmsh.model.mesh.getElements(2)
    assert list(types2) == [tri]
    gmsh.model.remove()


def test_gmsh_model_round_trip_on_a_step_part(tmp_path):
    with gmsh_session():
        step = tmp_path / "part.step"
        _step_part(step)
        out = tmp_path / "part-p2.msh"
        result = _curve_step(step, 0.6, 2, out)
        assert result.valid
        # Boundary nodes sit on their surfaces in the model written back.
        for dim, tag in gmsh.model.getEntities(2):
            nodes, coords, _ = gmsh.model.mesh.getNodes(dim, tag, includeBoundary=True)
            closest, _ = gmsh.model.getClosestPoint(dim, tag, coords)
            assert np.abs(np.asarray(closest) - coords).max() < 1e-6, (dim, tag)
        types, _, _ = gmsh.model.mesh.getElements(2)
        assert list(types) == [gmsh.model.mesh.getElementType("triangle", 2)]
        gmsh.model.remove()
        _check_written(out, result, 2)


def test_gmsh_model_round_trip_in_2d():
    with gmsh_session():
        gmsh.model.add("plate")
        plate = gmsh.model.occ.addRectangle(0, 0, 0, 2, 1)
        hole = gmsh.model.occ.addDisk(1, 0.5, 0, 0.25, 0.25)
        gmsh.model.occ.cut([(2, plate)], [(2, hole)])
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.15)
        gmsh.model.mesh.generate(2)
        n_before = len(gmsh.model.mesh.getElements(2)[1][0])
        result = hocurve.gmsh.curve_model(3)
        assert result.valid and result.nodes.shape[1] == 2 and len(result.cells) == n_before
        types, tags, _ = gmsh.model.mesh.getElements(2)
        assert list(types) == [gmsh.model.mesh.getElementType("triangle", 3)]
        assert gmsh.model.mesh.getElementQualities(tags[0], "minSJ").min() > 0
        for _, tag in gmsh.model.getEntities(1):
            types, _, _ = gmsh.model.mesh.getElements(1, tag)
            assert list(types) == [gmsh.model.mesh.getElementType("line", 3)]
            _, coords, _ = gmsh.model.mesh.getNodes(1, tag, includeBoundary=True)
            closest, _ = gmsh.model.getClosestPoint(1, tag, coords)
            # gmsh's nodes are the equispaced points of the curve, which the
            # engine interpolates at Gauss-Lobatto points: off the circle by
            # the interpolation error (5e-5 here), where a straight edge's
            # midpoint would be h^2 / 8r = 0.011 off.
            assert np.abs(np.asarray(closest) - coords).max() < 1e-3, tag


@pytest.mark.skipif(not CAD.is_dir(), reason=f"{CAD} (the benchmark STEP parts) is not here")
@pytest.mark.parametrize("part, size", [("screw.step", 1.5), ("component8.step", 2.5)])
def test_gmsh_model_round_trip_on_a_benchmark_part(tmp_path, part, size):
    with gmsh_session():
        out = tmp_path / "out.msh"
        result = _curve_step(CAD / part, size, 2, out)
        assert result.valid
        gmsh.model.remove()
        _check_written(out, result, 2)
