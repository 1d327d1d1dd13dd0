"""Curve the current gmsh model's mesh: ``hocurve.gmsh.curve_model``.

The Python twin of ``hocurve-occt``: the model's linear mesh is curved with
``gmsh.model.getClosestPoint`` as the projector, and the curved mesh is
written back into the model, so that ``gmsh.write("part.msh")`` saves it.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from . import HocurveError, InvalidInputError, Mesh, Result

_LINEAR = {1: 1, 2: 2, 3: 4}  # entity dim -> gmsh type of its linear simplex
_FAMILY = {1: "line", 2: "triangle", 3: "tetrahedron"}


def _gmsh() -> Any:
    import gmsh

    if not gmsh.isInitialized():
        raise InvalidInputError("gmsh is not initialised: call gmsh.initialize() and mesh a model first")
    return gmsh


def _multi(gmsh: Any, dim: int, order: int) -> Tuple[int, np.ndarray]:
    """gmsh's element type of dimension ``dim`` and ``order``, and the
    barycentric multi-index (times the order) of each of its local nodes."""
    etype = gmsh.model.mesh.getElementType(_FAMILY[dim], order)
    _, _, _, n, local, _ = gmsh.model.mesh.getElementProperties(etype)
    xi = np.reshape(local, (n, dim))
    if dim == 1:
        xi = (xi + 1.0) / 2.0  # gmsh's line is [-1, 1], its simplices have corners 0 and 1
    bary = np.column_stack([1.0 - xi.sum(axis=1), xi])
    return etype, np.rint(bary * order).astype(np.int64)


def _projector(gmsh: Any):
    def project(entity_dim: int, tag: int, points: np.ndarray) -> np.ndarray:
        closest, _ = gmsh.model.getClosestPoint(entity_dim, tag, points.ravel())
        return np.reshape(closest, (-1, 3))

    return project


def curve_model(order: int, *, write_back: bool = True, **options: Any) -> Result:
    """Curve the current gmsh model's linear mesh at ``order`` and, with
    ``write_back``, replace the model's mesh by the curved one.

    Call it after ``gmsh.model.mesh.generate(dim)`` on a model whose
    entities have geometry (OpenCASCADE or built-in kernel). Cells are the
    mesh's triangles (2D) or tetrahedra (3D); every boundary curve or
    surface is projected onto with ``gmsh.model.getClosestPoint``.
    ``options`` are those of :meth:`hocurve.Mesh.run`; ``tangent_first``
    is True by default here, since ``getClosestPoint`` is slow (0.1 to
    0.4 ms a point on OpenCASCADE surfaces).

    The curved mesh replaces the model's: nodes and elements of every
    entity, at order ``order``, the boundary elements included, on the same
    entities (so physical groups still apply). hocurve may have changed
    the cells (boundary caps removed, cells flipped or split); the elements
    written are the curved mesh's. On error the model is left unchanged.
    """
    gmsh = _gmsh()
    dim = gmsh.model.getDimension()
    if dim not in (2, 3):
        raise InvalidInputError(f"the model has dimension {dim}: hocurve curves 2D and 3D meshes")
    model = _linear_model(gmsh, dim)
    mesh = Mesh(model["points"], model["cells"])
    if len(model["facets"]):
        mesh.set_boundary(model["facets"], model["facet_tags"])
    if dim == 3 and len(model["edges"]):
        mesh.set_feature_edges(model["edges"], model["edge_tags"])
    mesh.set_projector(_projector(gmsh))
    options["ordering"] = "gmsh"
    # getClosestPoint costs 0.1 to 0.4 ms a point on OpenCASCADE surfaces.
    options.setdefault("tangent_first", True)
    result = mesh.run(order, **options)
    if write_back:
        _write_back(gmsh, dim, order, model, result)
    return result


def _linear_model(gmsh: Any, dim: int) -> Dict[str, Any]:
    """The model's linear mesh: vertices (the nodes its cells use, in node
    order), cells and their entities, tagged facets and feature edges, and
    where each vertex node was classified."""
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.reshape(coords, (-1, 3))
    order = np.argsort(node_tags)
    node_tags, coords = node_tags[order], coords[order]

    def gather(d: int) -> Tuple[List[np.ndarray], List[int]]:
        conn, ents = [], []
        for _, tag in gmsh.model.getEntities(d):
            types, _, nodes = gmsh.model.mesh.getElements(d, tag)
            for t, n in zip(types, nodes):
                if t == 15:
                    continue
                if t != _LINEAR[d]:
                    name = gmsh.model.mesh.getElementProperties(t)[0]
                    raise InvalidInputError(
                        f"entity ({d}, {tag}) has {name} elements: curve_model needs the linear simplex "
                        "mesh (before gmsh.model.mesh.setOrder)"
                    )
                conn.append(np.reshape(np.asarray(n, dtype=np.int64), (-1, d + 1)))
                ents.append(np.full(len(conn[-1]), tag, dtype=np.int64))
        return conn, ents

    cconn, cents = gather(dim)
    if not cconn:
        raise InvalidInputError(f"the model has no {dim}D mesh: call gmsh.model.mesh.generate({dim}) first")
    cells_t = np.concatenate(cconn)
    used = np.unique(cells_t)
    pos = np.searchsorted(node_tags, used)
    if np.any(pos >= len(node_tags)) or np.any(node_tags[np.minimum(pos, len(node_tags) - 1)] != used):
        raise HocurveError("internal: an element uses a node gmsh did not list")
    index = {int(t): i for i, t in enumerate(used)}

    def local(conn_t: np.ndarray) -> np.ndarray:
        return np.vectorize(lambda t: index.get(int(t), -1), otypes=[np.int64])(conn_t)

    fconn, fents = gather(dim - 1)
    facets = local(np.concatenate(fconn)) if fconn else np.zeros((0, dim), dtype=np.int64)
    if np.any(facets < 0):
        raise InvalidInputError("a boundary element uses a node that no cell uses")
    edges = np.zeros((0, 2), dtype=np.int64)
    edge_tags = np.zeros(0, dtype=np.int64)
    if dim == 3:
        econn, eents = gather(1)
        if econn:
            edges = local(np.concatenate(econn))
            edge_tags = np.concatenate(eents)
            keep = np.all(edges >= 0, axis=1)
            edges, edge_tags = edges[keep], edge_tags[keep]
    where: Dict[int, Tuple[int, int]] = {}
    for d in range(dim + 1):
        for _, tag in gmsh.model.getEntities(d):
            tags_here, _, _ = gmsh.model.mesh.getNodes(d, tag)
            for t in tags_here:
                where.setdefault(int(t), (d, tag))
    points_elements = []
    for _, tag in gmsh.model.getEntities(0):
        types, _, nodes = gmsh.model.mesh.getElements(0, tag)
        for t, n in zip(types, nodes):
            if t == 15:
                points_elements.append((tag, np.asarray(n, dtype=np.int64)))
    return {
        "points": coords[pos][:, :dim],
        "vertex_tags": used,
        "vertex_entity": [where.get(int(t), (dim, int(cents[0][0]))) for t in used],
        "cells": local(cells_t),
        "cell_entity": np.concatenate(cents),
        "facets": facets,
        "facet_tags": np.concatenate(fents) if fents else np.zeros(0, dtype=np.int64),
        "edges": edges,
        "edge_tags": edge_tags,
        "points_elements": points_elements,
    }


def _write_back(gmsh: Any, dim: int, order: int, model: Dict[str, Any], result: Result) -> None:
    """Replace the model's mesh by the curved one (see curve_model)."""
    cells = result.cells
    n_nodes = len(result.nodes)
    nv = len(model["vertex_tags"])
    cell_entity = model["cell_entity"][result.input_cells]
    ents = result.node_entities
    # Node tags: the vertices keep theirs; every other node gets a new one.
    first_new = int(max(model["vertex_tags"].max(), gmsh.model.mesh.getMaxNodeTag())) + 1
    tags = np.concatenate([model["vertex_tags"], np.arange(first_new, first_new + n_nodes - nv, dtype=np.int64)])
    # Where each node is classified: a vertex where it was, a boundary node
    # on its entity, an interior node in the volume of (one of) its cells.
    owner: List[Optional[Tuple[int, int]]] = [None] * n_nodes
    for i in range(nv):
        owner[i] = tuple(model["vertex_entity"][i])
    for i in np.nonzero(ents[:, 0] >= 0)[0]:
        if i >= nv:
            owner[i] = (int(ents[i, 0]), int(ents[i, 1]))
    for c, ent in zip(cells, cell_entity):
        for i in c:
            if owner[i] is None:
                owner[i] = (dim, int(ent))
    by_entity: Dict[Tuple[int, int], List[int]] = defaultdict(list)
    for i, o in enumerate(owner):
        by_entity[o].append(i)
    xyz = result.nodes if dim == 3 else np.column_stack([result.nodes, np.zeros(n_nodes)])

    cell_type, cell_multi = _multi(gmsh, dim, order)
    facet_type, facet_multi = _multi(gmsh, dim - 1, order)
    facet_index = {tuple(m): k for k, m in enumerate(facet_multi)}
    # Boundary facets of the curved mesh: cell faces seen once, each with its
    # nodes in gmsh's order for the facet's element type.
    seen: Dict[Tuple[int, ...], Optional[np.ndarray]] = {}
    for c in cells:
        verts = c[: dim + 1]
        for j in range(dim + 1):
            others = [k for k in range(dim + 1) if k != j]
            key = tuple(sorted(int(verts[k]) for k in others))
            if key in seen:
                seen[key] = None
                continue
            on_face = np.nonzero(cell_multi[:, j] == 0)[0]
            facet = np.empty(len(facet_multi), dtype=np.int64)
            for k in on_face:
                facet[facet_index[tuple(cell_multi[k, others])]] = c[k]
            seen[key] = facet
    boundary = [f for f in seen.values() if f is not None]
    old_facet_tag = {tuple(sorted(map(int, f))): int(t) for f, t in zip(model["facets"], model["facet_tags"])}

    def facet_entity(f: np.ndarray) -> Optional[int]:
        for i in f[dim:]:
            if ents[i, 0] == dim - 1:
                return int(ents[i, 1])
        return old_facet_tag.get(tuple(sorted(map(int, f[:dim]))))

    facets_by_tag: Dict[int, List[np.ndarray]] = defaultdict(list)
    untagged = []
    for f in boundary:
        t = facet_entity(f)
        if t is None:
            untagged.append(f)
        else:
            facets_by_tag[t].append(f)
    if untagged:
        raise HocurveError(
            f"{len(untagged)} boundary facets of the curved mesh lie on no model entity; the model is unchanged"
        )
    lines_by_tag: Dict[int, List[np.ndarray]] = defaultdict(list)
    if dim == 3:
        line_type, line_multi = _multi(gmsh, 1, order)
        line_index = {tuple(m): k for k, m in enumerate(line_multi)}
        old_edge_tag = {tuple(sorted(map(int, e))): int(t) for e, t in zip(model["edges"], model["edge_tags"])}
        done = set()
        for f in boundary:
            for a, b in ((0, 1), (1, 2), (2, 0)):
                key = tuple(sorted((int(f[a]), int(f[b]))))
                if key in done:
                    continue
                done.add(key)
                others = [a, b]
                on_edge = [k for k in range(len(facet_multi)) if facet_multi[k, 3 - a - b] == 0]
                line = np.empty(len(line_multi), dtype=np.int64)
                for k in on_edge:
                    line[line_index[tuple(facet_multi[k, others])]] = f[k]
                inner = [i for i in line[2:] if ents[i, 0] == 1]
                tag = int(ents[inner[0], 1]) if inner else old_edge_tag.get(key)
                if tag is not None:
                    lines_by_tag[tag].append(line)

    gmsh.model.mesh.clear()
    for (d, t), nodes in sorted(by_entity.items()):
        nodes = np.asarray(nodes)
        gmsh.model.mesh.addNodes(d, t, tags[nodes].tolist(), xyz[nodes].ravel().tolist())
    for ent in np.unique(cell_entity):
        mine = cells[cell_entity == ent]
        gmsh.model.mesh.addElementsByType(int(ent), cell_type, [], tags[mine].ravel().tolist())
    for t, fs in sorted(facets_by_tag.items()):
        gmsh.model.mesh.addElementsByType(t, facet_type, [], tags[np.asarray(fs)].ravel().tolist())
    if dim == 3:
        for t, ls in sorted(lines_by_tag.items()):
            gmsh.model.mesh.addElementsByType(t, line_type, [], tags[np.asarray(ls)].ravel().tolist())
    for t, nodes in model["points_elements"]:
        gmsh.model.mesh.addElementsByType(t, 15, [], nodes.tolist())
