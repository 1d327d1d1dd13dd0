"""hocurve: valid high-order curved triangle and tetrahedral meshes.

Give it a linear mesh (numpy arrays, a meshio mesh or the current gmsh
model), the geometry its boundary lies on (built-in shapes, or any Python
function that projects points), and an order from 1 to 10; it returns the
curved mesh with its quality, every cell certified valid or an error.

    >>> import numpy as np, hocurve
    >>> mesh = hocurve.Mesh(vertices, cells)            # (n, 2|3) floats, (m, 3|4) ints
    >>> mesh.set_boundary(facets, tags)                 # (k, dim) ints, (k,) ints
    >>> mesh.set_shapes({7: "sphere:0,0,0,0.5"})        # or mesh.set_projector(f)
    >>> result = mesh.run(order=4)
    >>> result.nodes, result.cells, result.quality["min_q3"]

The engine is the Rust library hocurve (the same as its C ABI and command
line); a run releases the GIL, and Ctrl-C cancels it cleanly.
"""

from __future__ import annotations

import contextlib
import json
import sys
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterator, Mapping, Optional, Sequence, Union

import numpy as np

from . import _native

__version__: str = _native.__version__

__all__ = [
    "Mesh",
    "Result",
    "HocurveError",
    "InvalidInputError",
    "ProjectionError",
    "SolverError",
    "InvalidElementError",
    "FileError",
    "CancelledError",
    "demo_mesh",
    "from_meshio",
    "to_meshio",
]


class HocurveError(Exception):
    """An error of hocurve. ``status`` names its kind: ``invalid-input``,
    ``projection``, ``solver``, ``invalid-element``, ``io`` or ``cancelled``.
    When a Python projector raised, that exception is the ``__cause__``."""

    status: str = "error"

    def __init__(self, message: str, status: Optional[str] = None):
        super().__init__(message)
        if status is not None:
            self.status = status


class InvalidInputError(HocurveError, ValueError):
    """The mesh, an array or an option is malformed."""

    status = "invalid-input"


class ProjectionError(HocurveError):
    """The projector failed (or raised) or returned a non-finite point."""

    status = "projection"


class SolverError(HocurveError):
    """A linear solve or a Newton iteration failed."""

    status = "solver"


class InvalidElementError(HocurveError):
    """The mesh could not be made valid: a cell stays inverted."""

    status = "invalid-element"


class FileError(HocurveError, OSError):
    """A file could not be written."""

    status = "io"


class CancelledError(HocurveError):
    """The progress callback asked the run to stop."""

    status = "cancelled"


_BY_STATUS = {
    c.status: c
    for c in (InvalidInputError, ProjectionError, SolverError, InvalidElementError, FileError, CancelledError)
}


@contextlib.contextmanager
def _errors() -> Iterator[None]:
    """Turn the native module's error into the matching HocurveError subclass."""
    try:
        yield
    except _native.HocurveError as e:
        status = getattr(e, "status", "error")
        message = str(e.args[1]) if len(e.args) > 1 else str(e)
        raise _BY_STATUS.get(status, HocurveError)(message, status) from e.__cause__


Projector = Callable[[int, int, np.ndarray], Any]
"""``projector(entity_dim, tag, points)``: the closest points on entity
(``entity_dim``, ``tag``) to ``points``, an (k, 3) float array (z = 0 in 2D);
returns an array-like of the same shape."""

ProgressCallback = Callable[[str, int, int], Optional[bool]]
"""``progress(stage, step, total)``: stage is ``elevate``, ``project``,
``increment`` (step of total), ``quality`` or ``optimize``; returning False
cancels the run."""


@dataclass
class Result:
    """A curved mesh, as a run returns it.

    ``nodes`` (n, dim) and ``cells`` (m, nodes per cell) are in ``ordering``
    (``gmsh``, ``vtk`` or ``native``; gmsh's and VTK's place the nodes at
    the equispaced positions their cells interpolate, the same curved
    geometry). ``cell_quality`` holds Q1, Q2, Q3 per cell; ``input_cells``
    maps each cell to the input cell it comes from (the repair may remove,
    split or flip cells). ``quality`` and ``report`` are the command line's
    JSON report as dicts.
    """

    order: int
    ordering: str
    nodes: np.ndarray
    cells: np.ndarray
    cell_quality: np.ndarray
    input_cells: np.ndarray
    node_entities: np.ndarray
    quality: Dict[str, Any] = field(repr=False)
    report: Dict[str, Any] = field(repr=False)

    @property
    def valid(self) -> bool:
        """True when no cell is certified invalid."""
        return self.quality["certified_invalid_elements"] == 0 and self.quality["invalid_elements"] == 0


def _int_array(a: Any, what: str, ndim: int) -> np.ndarray:
    arr = np.asarray(a)
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(f"{what} must be integers, got {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.int64)
    if arr.ndim != ndim:
        raise InvalidInputError(f"{what} must be a {ndim}-D array, got shape {arr.shape}")
    return arr


class Mesh:
    """A linear triangle (2D) or tetrahedral (3D) mesh to curve.

    ``vertices``: (n, 2) or (n, 3) floats; for triangles a third column must
    be all zero (a triangle mesh is a planar 2D mesh). ``cells``: (m, 3)
    triangles or (m, 4) tetrahedra, 0-based vertex indices. Cells are
    reoriented where needed; a malformed mesh raises InvalidInputError.
    """

    def __init__(self, vertices: Any, cells: Any):
        cells = _int_array(cells, "cells", 2)
        if cells.shape[1] not in (3, 4):
            raise InvalidInputError(f"cells must have 3 (triangles) or 4 (tetrahedra) columns, got {cells.shape[1]}")
        dim = cells.shape[1] - 1
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] not in (2, 3):
            raise InvalidInputError(f"vertices must be an (n, 2) or (n, 3) array, got shape {v.shape}")
        if dim == 2 and v.shape[1] == 3:
            if np.any(v[:, 2] != 0.0):
                raise InvalidInputError("a triangle mesh is planar: its vertices' z must be 0")
            v = v[:, :2]
        if dim == 3 and v.shape[1] != 3:
            raise InvalidInputError("tetrahedra need 3 coordinates per vertex")
        with _errors():
            self._native = _native.NativeMesh(np.ascontiguousarray(v), cells)
        # Tags given, per entity dimension, and the ones held straight: the
        # caller's, and with built-in shapes those that have none.
        self._tags: Dict[int, set] = {}
        self._straight: Dict[int, set] = {}
        self._shapes: Optional[Dict[int, str]] = None
        self._applied: Dict[int, set] = {}

    @property
    def dim(self) -> int:
        """2 for triangles, 3 for tetrahedra."""
        return self._native.dim

    def set_boundary(self, facets: Any, tags: Any) -> None:
        """The boundary facets (edges in 2D, triangles in 3D), (k, dim), and
        the tag of the geometric entity each lies on, (k,)."""
        f = _int_array(facets, "facets", 2)
        t = np.ascontiguousarray(_int_array(tags, "tags", 1), dtype=np.int32)
        with _errors():
            self._native.set_boundary(f, t)
        self._tags[self.dim - 1] = set(t.tolist())
        self._straight.pop(self.dim - 1, None)
        self._applied.pop(self.dim - 1, None)

    def set_feature_edges(self, edges: Any, tags: Any) -> None:
        """3D: edges where two surfaces meet, (k, 2), and their curve tags (k,)."""
        e = _int_array(edges, "edges", 2)
        t = np.ascontiguousarray(_int_array(tags, "tags", 1), dtype=np.int32)
        with _errors():
            self._native.set_feature_edges(e, t)
        self._tags[1] = set(t.tolist())
        self._straight.pop(1, None)
        self._applied.pop(1, None)

    def tags(self, entity_dim: int) -> list:
        """The tags given to the facets (``entity_dim`` = dim - 1) or to the
        feature edges (1), sorted."""
        return sorted(self._tags.get(int(entity_dim), ()))

    def set_straight(self, entity_dim: int, tags: Sequence[int]) -> None:
        """Hold the entities ``(entity_dim, tag)`` straight (no projection);
        replaces the earlier list for ``entity_dim``."""
        with _errors():
            self._native.set_straight(int(entity_dim), sorted(int(t) for t in tags))
        self._straight[int(entity_dim)] = {int(t) for t in tags}
        self._applied[int(entity_dim)] = {int(t) for t in tags}

    def set_shapes(self, shapes: Mapping[int, str]) -> None:
        """The built-in analytic geometry: ``{tag: shape}`` with shapes in the
        command line's syntax, e.g. ``"sphere:0,0,0,0.5"``, ``"circle:0,0,1"``,
        ``"cylinder:px,py,pz,ax,ay,az,r"``, ``"torus:cx,cy,cz,R,r"``,
        ``"plane:px,py,pz,nx,ny,nz"``, ``"line:px,py,pz,dx,dy,dz"``,
        ``"naca4:0012,1,0,0"``. Replaces any projector. As with the command
        line, facets and feature edges whose tag has no shape stay straight."""
        with _errors():
            self._native.set_shapes([(int(t), str(s)) for t, s in shapes.items()])
        self._shapes = {int(t): str(s) for t, s in shapes.items()}

    def set_projector(self, projector: Projector) -> None:
        """Any geometry: ``projector(entity_dim, tag, points)`` returns the
        closest points on entity (``entity_dim``, ``tag``) to ``points``
        ((k, 3) floats). It is called with the GIL held, from one thread at a
        time. If it raises, the run fails with ProjectionError (the
        exception as its cause) and the mesh is left as it was."""
        if not callable(projector):
            raise InvalidInputError("the projector must be callable")
        with _errors():
            self._native.set_projector(projector)
        self._shapes = None

    def run(
        self,
        order: int,
        *,
        increments: int = 10,
        formulation: str = "ile",
        material: Optional[str] = None,
        young: float = 1e5,
        poisson: float = 0.45,
        spacing: str = "optimal",
        solver: str = "auto",
        caps: str = "remove",
        retry: bool = True,
        repair: bool = True,
        adaptive: Optional[bool] = None,
        max_splits: int = 6,
        condense: bool = True,
        optimize: bool = True,
        tangent_first: bool = False,
        tolerance: float = 1e-5,
        max_iterations: int = 30,
        threads: int = 0,
        ordering: str = "gmsh",
        progress: Union[None, bool, ProgressCallback] = None,
    ) -> Result:
        """Curve the mesh at ``order`` (1 to 10) and return the result.

        The options and defaults are the command line's (``hocurve curve``):
        ``formulation`` ``linear``, ``ile``, ``iil``, ``cil`` or
        ``nonlinear``; ``material`` ``linear``, ``neo-hookean``,
        ``mooney-rivlin``, ... (default by formulation); ``caps`` ``remove``
        or ``keep``; ``solver`` ``auto``, ``direct`` or ``iterative``;
        ``adaptive`` None (by formulation), True or False; ``threads`` 0 for
        one per core, at most 4096. ``tangent_first``: for a slow projector, the
        optimisation's sliding nodes are projected after each pass and at
        every step only where that is not enough (a fifth to a third of the
        projector calls on parts that need sliding; as valid, the quality
        floor sometimes lower). ``progress``: True shows a tqdm bar when tqdm is
        installed (a line per stage on stderr otherwise), or a callable
        ``progress(stage, step, total)`` that returns False to cancel.

        On error the mesh is unchanged and a HocurveError subclass is raised;
        Ctrl-C raises KeyboardInterrupt after the run has stopped cleanly.
        """
        if caps not in ("remove", "keep"):
            raise InvalidInputError(f"unknown caps '{caps}' (remove or keep)")
        with _errors():
            for d, tags in self._tags.items():
                held = set(self._straight.get(d, ()))
                if self._shapes is not None:
                    held |= {t for t in tags if (d, t) not in _shape_entities(self._shapes)}
                # Applied only when it changes: it makes the mesh the straight one.
                if held != self._applied.get(d, set()):
                    self._native.set_straight(d, sorted(held))
                    self._applied[d] = held
            self._native.configure(
                int(order), spacing, formulation, material, float(young), float(poisson), float(tolerance),
                int(max_iterations), adaptive, int(max_splits), caps == "remove", bool(retry), bool(repair),
                bool(condense), bool(optimize), bool(tangent_first), solver, int(threads),
            )
        with _progress(progress, increments) as callback, _interruptible(), _errors():
            self._native.run(int(increments), callback)
        return self.result(ordering)

    def result(self, ordering: str = "gmsh") -> Result:
        """The current mesh (straight before a run, curved after one)."""
        with _errors():
            n = self._native
            report = n.report_json()
            cells = n.cells(ordering)
            return Result(
                order=_order(n.dim, cells.shape[1]),
                ordering=ordering,
                nodes=n.nodes(ordering),
                cells=cells,
                cell_quality=n.cell_quality(),
                input_cells=n.input_cells(),
                node_entities=n.node_entities(),
                quality=json.loads(n.quality_json()),
                report=json.loads(report) if report is not None else {},
            )

    def write(self, path: str) -> None:
        """Write the current mesh to ``path``: ``.msh`` (gmsh MSH 4.1) or
        ``.vtu`` (VTK Lagrange cells), with Q1 and Q3 per cell, as the
        command line does. The file appears whole or not at all."""
        with _errors():
            self._native.write(str(path))


def demo_mesh(name: str) -> Mesh:
    """One of the command line's demonstration cases, ready to run, as
    ``hocurve demo`` curves it: ``"cylinder-2d"`` (a cylinder in a channel
    with a boundary layer of stretching 100) or ``"sphere-3d"`` (a spherical
    cavity in a box)."""
    with _errors():
        vertices, cells, facets, ftags, edges, etags, shapes, _ = _native.demo_case(name)
    mesh = Mesh(vertices, cells)
    if len(facets):
        mesh.set_boundary(facets, ftags)
    if len(edges):
        mesh.set_feature_edges(edges, etags)
    mesh.set_shapes(dict(shapes))
    return mesh


_CURVES = ("circle", "circle3", "line", "naca4")


def _shape_entities(shapes: Mapping[int, str]) -> set:
    """(entity dim, tag) of each shape: curves are entities of dimension 1."""
    return {(1 if s.split(":", 1)[0].strip().lower() in _CURVES else 2, t) for t, s in shapes.items()}


def _order(dim: int, nodes_per_cell: int) -> int:
    for p in range(1, 11):
        n = (p + 1) * (p + 2) // 2 if dim == 2 else (p + 1) * (p + 2) * (p + 3) // 6
        if n == nodes_per_cell:
            return p
    raise HocurveError(f"no order has {nodes_per_cell} nodes per cell in {dim}D")


@contextlib.contextmanager
def _interruptible() -> Iterator[None]:
    """Ctrl-C raises KeyboardInterrupt during a run, which then stops
    cleanly, even where SIGINT was left to kill the process (gmsh's
    ``initialize`` does that, and its ``finalize`` does not undo it)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) != signal.SIG_DFL:
        yield
        return
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_DFL)


@contextlib.contextmanager
def _progress(progress: Union[None, bool, ProgressCallback], increments: int) -> Iterator[Optional[ProgressCallback]]:
    """The callback to hand to the engine for ``progress``, and its clean-up."""
    if progress is None or progress is False:
        yield None
        return
    if callable(progress):
        yield progress
        return
    try:
        from tqdm.auto import tqdm
    except ImportError:

        def lines(stage: str, step: int, total: int) -> bool:
            detail = f" {step + 1}/{total}" if stage == "increment" else ""
            print(f"hocurve: {stage}{detail}", file=sys.stderr, flush=True)
            return True

        yield lines
        return
    bar = tqdm(total=max(int(increments), 1), desc="hocurve", unit="increment", leave=False)

    def update(stage: str, step: int, total: int) -> bool:
        if stage == "increment":
            bar.total = max(total, 1)
            bar.n = min(step, bar.total)
        bar.set_description(f"hocurve: {stage}")
        bar.refresh()
        return True

    try:
        yield update
    finally:
        bar.close()


from ._meshio import from_meshio, to_meshio  # noqa: E402  (needs Mesh and Result)
