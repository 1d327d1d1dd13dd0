"""meshio meshes in and out: ``hocurve.from_meshio`` and ``hocurve.to_meshio``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping, Optional

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import meshio

    from . import Mesh, Projector, Result

# meshio keeps gmsh's node order for high-order simplices except for the
# 10-node tetrahedron, which it holds in VTK's order (its last two edge
# nodes swapped; meshio.gmsh._gmsh_to_meshio_order).
_GMSH_TO_MESHIO = {"tetra10": [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]}

_TAG_KEYS = ("gmsh:geometrical", "gmsh:physical")


def _block_tags(mesh: "meshio.Mesh", i: int, tag_key: Optional[str]) -> Optional[np.ndarray]:
    keys = (tag_key,) if tag_key else _TAG_KEYS
    for k in keys:
        if k in mesh.cell_data:
            return np.asarray(mesh.cell_data[k][i], dtype=np.int64)
    return None


def from_meshio(
    mesh: "meshio.Mesh",
    shapes: Optional[Mapping[int, str]] = None,
    projector: Optional["Projector"] = None,
    tag_key: Optional[str] = None,
) -> "Mesh":
    """A :class:`hocurve.Mesh` from a linear meshio mesh.

    Cells are the ``tetra`` blocks (3D) or, if there are none, the
    ``triangle`` blocks (2D). Boundary facets are the ``triangle`` blocks in
    3D and the ``line`` blocks in 2D; in 3D the ``line`` blocks are feature
    edges. Their tags come from the cell data ``tag_key``, by default
    ``gmsh:geometrical`` (the entity tags, as the command line uses) or else
    ``gmsh:physical``. Vertices are the points the cells use, in their
    order, as ``hocurve curve`` numbers a gmsh file's nodes. ``shapes`` or
    ``projector`` are handed to :meth:`Mesh.set_shapes` or
    :meth:`Mesh.set_projector`.
    """
    from . import InvalidInputError, Mesh

    types = [b.type for b in mesh.cells]
    dim = 3 if "tetra" in types else 2 if "triangle" in types else 0
    if dim == 0:
        raise InvalidInputError(
            f"no linear tetra or triangle cells in the meshio mesh (cell types {sorted(set(types))})"
        )
    cell_type, facet_type = ("tetra", "triangle") if dim == 3 else ("triangle", "line")
    blocks = list(enumerate(mesh.cells))
    cells = np.concatenate([np.asarray(b.data, dtype=np.int64) for _, b in blocks if b.type == cell_type])
    used = np.unique(cells)
    index = np.full(len(mesh.points), -1, dtype=np.int64)
    index[used] = np.arange(len(used))
    points = np.asarray(mesh.points, dtype=np.float64)[used]
    if dim == 2:
        if points.shape[1] == 3 and np.any(points[:, 2] != 0.0):
            raise InvalidInputError("a triangle mesh is planar: its points' z must be 0")
        points = points[:, :2]

    def gathered(kind: str) -> Optional[tuple]:
        conn, tags = [], []
        for i, b in blocks:
            if b.type != kind:
                continue
            t = _block_tags(mesh, i, tag_key)
            if t is None:
                raise InvalidInputError(
                    f"the {kind} cells have no tags: give tag_key, or cell data "
                    "gmsh:geometrical or gmsh:physical"
                )
            conn.append(np.asarray(b.data, dtype=np.int64))
            tags.append(t)
        if not conn:
            return None
        c = index[np.concatenate(conn)]
        if np.any(c < 0):
            raise InvalidInputError(f"a {kind} cell uses a point that is in no {cell_type} cell")
        return c, np.concatenate(tags)

    out = Mesh(points, index[cells])
    facets = gathered(facet_type)
    if facets is not None:
        out.set_boundary(*facets)
    if dim == 3:
        edges = gathered("line")
        if edges is not None:
            out.set_feature_edges(*edges)
    if shapes is not None:
        out.set_shapes(shapes)
    if projector is not None:
        out.set_projector(projector)
    return out


def to_meshio(result: "Result") -> "meshio.Mesh":
    """The curved mesh of a :class:`hocurve.Result` as a meshio mesh: one
    block of high-order cells (``triangle6``, ``tetra10``, ``tetra20``, ...)
    in meshio's node order, with the cell data ``q1`` and ``q3`` and the
    input cell of each cell (``input_cell``). The result must be in gmsh
    ordering (the default of :meth:`Mesh.run`)."""
    import meshio

    from . import InvalidInputError

    if result.ordering != "gmsh":
        raise InvalidInputError(f"to_meshio needs a result in gmsh ordering, got {result.ordering}")
    dim = result.nodes.shape[1]
    npc = result.cells.shape[1]
    base = "triangle" if dim == 2 else "tetra"
    kind = base if result.order == 1 else f"{base}{npc}"
    cells = result.cells
    if kind in _GMSH_TO_MESHIO:
        cells = cells[:, _GMSH_TO_MESHIO[kind]]
    points = result.nodes
    if dim == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    return meshio.Mesh(
        points,
        [(kind, cells)],
        cell_data={
            "q1": [result.cell_quality[:, 0]],
            "q3": [result.cell_quality[:, 2]],
            "input_cell": [result.input_cells],
        },
    )

