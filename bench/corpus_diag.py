#!/usr/bin/env python3
"""Which cells make a corpus run fail, and what they look like.

    .venv/bin/python bench/corpus_diag.py CASE P [--out DIR]

Curves DIR/meshes/CASE.msh (the corpus from bench/corpus.py, default
bench/out/corpus) at order P with the defaults but `--adaptive off`, so
hocurve hands back the mesh with its invalid cells instead of stopping, then
finds the cells whose det J is <= 0 at some point of an order-8 lattice
(gmsh's Jacobians of the curved output) and describes each from its linear
cell: how many corners lie on the curved surface, which faces are boundary
faces (entity tags), the angle between the normals of two boundary faces
that share an edge (a boundary cap when both are on the same surface), and
the height of the vertex opposite each boundary face over that face's
longest edge (a flat cell is low). A summary counts the cells by kind.
"""
import argparse
import itertools
import json
import math
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
import corpus  # noqa: E402


def distance(shape, p):
    kind, vals = shape.split(":")
    v = [float(x) for x in vals.split(",")]
    x, y, z = p
    if kind == "sphere":
        return abs(math.dist(p, v[:3]) - v[3])
    if kind == "torus" and len(v) == 5:
        rho = math.hypot(x - v[0], y - v[1]) - v[3]
        return abs(math.hypot(rho, z - v[2]) - v[4])
    if kind == "cylinder":
        a = np.array(v[3:6]) / np.linalg.norm(v[3:6])
        d = np.array(p) - np.array(v[:3])
        return abs(np.linalg.norm(d - np.dot(d, a) * a) - v[6])
    if kind == "plane":
        n = np.array(v[3:6]) / np.linalg.norm(v[3:6])
        return abs(np.dot(np.array(p) - np.array(v[:3]), n))
    return math.inf


def inverted_cells(gmsh, curved, q=8):
    """(corner coordinates, min det J) of every cell of `curved` with det J <= 0 at a lattice point."""
    gmsh.open(str(curved))
    et = gmsh.model.mesh.getElementTypes(3)[0]
    nn = gmsh.model.mesh.getElementProperties(et)[3]
    tags, nodes = gmsh.model.mesh.getElementsByType(et)
    ntag, xyz, _ = gmsh.model.mesh.getNodes()
    where = {int(t): i for i, t in enumerate(ntag)}
    pts = [(i / q, j / q, k / q) for i in range(q + 1) for j in range(q + 1) for k in range(q + 1) if i + j + k <= q]
    _jac, det, _ = gmsh.model.mesh.getJacobians(et, list(itertools.chain(*pts)))
    det = np.array(det).reshape(len(tags), len(pts))
    nodes = np.array(nodes, dtype=np.int64).reshape(len(tags), nn)
    out = []
    for b in np.where(det.min(axis=1) <= 0)[0]:
        corners = [tuple(xyz[3 * where[int(n)]:3 * where[int(n)] + 3]) for n in nodes[b][:4]]
        u, v, w = pts[int(det[b].argmin())]
        bary = (1 - u - v - w, u, v, w)  # gmsh's corners 0..3 are at (0,0,0), (1,0,0), (0,1,0), (0,0,1)
        out.append((corners, float(det[b].min()), int(b), [k for k in range(4) if abs(bary[k]) < 1e-12]))
    gmsh.clear()
    return out, len(tags)


def boundary_faces(gmsh, linear):
    """{frozenset of 3 rounded corner coordinates: surface tag} of the linear mesh."""
    gmsh.open(str(linear))
    ntag, xyz, _ = gmsh.model.mesh.getNodes()
    at = {int(t): tuple(np.round(xyz[3 * i:3 * i + 3], 10)) for i, t in enumerate(ntag)}
    faces = {}
    for _d, t in gmsh.model.getEntities(2):
        for et, _ets, ns in zip(*gmsh.model.mesh.getElements(2, t)):
            for i in range(0, len(ns), 3):
                faces[frozenset(at[int(n)] for n in ns[i:i + 3])] = t
    gmsh.clear()
    return faces


def where(zero, bf):
    """Where the lattice minimum of det J is: interior, on a face (boundary tag or interior), edge, vertex."""
    if not zero:
        return "inside the cell"
    if len(zero) == 1:
        k = zero[0]
        return f"on boundary face {bf[k]}" if k in bf else "on an interior face"
    if len(zero) == 2:
        ends = [k for k in range(4) if k not in zero]
        on = [bf[k] for k in zero if k in bf]  # faces containing the edge are those opposite the zero corners
        return f"on an edge ({'of boundary faces ' + str(sorted(on)) if on else 'interior'})" if ends else ""
    return "at a corner"


def describe(corners, faces, curved_shapes, zero=()):
    key = [tuple(np.round(c, 10)) for c in corners]
    on = sum(any(distance(s, c) < 1e-7 for s in curved_shapes) for c in corners)
    bf = {}
    for k in range(4):
        t = faces.get(frozenset(key[j] for j in range(4) if j != k))
        if t is not None:
            bf[k] = t
    parts = [f"{on}/4 corners on the curved surface", f"{len(bf)} boundary face(s) {sorted(bf.values())}"]
    P = [np.array(c) for c in corners]
    normals = {}
    for k, t in bf.items():
        f = [P[j] for j in range(4) if j != k]
        n = np.cross(f[1] - f[0], f[2] - f[0])
        normals[k] = n / np.linalg.norm(n)
        h = abs(np.dot(P[k] - f[0], normals[k]))
        e = max(np.linalg.norm(f[i] - f[j]) for i in range(3) for j in range(i + 1, 3))
        parts.append(f"height over face {t}: {h / e:.2f} x its longest edge")
    parts.append("det J lowest " + where(list(zero), bf))
    kind = f"{len(bf)} boundary faces"
    if len(bf) == 2:
        (k1, t1), (k2, t2) = bf.items()
        # Outward normals of the two faces: away from the opposite vertex.
        n1 = normals[k1] * (-1 if np.dot(P[k1] - P[(k1 + 1) % 4], normals[k1]) > 0 else 1)
        n2 = normals[k2] * (-1 if np.dot(P[k2] - P[(k2 + 1) % 4], normals[k2]) > 0 else 1)
        ang = math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(n1, n2))))))
        parts.append(f"normals of the two boundary faces {ang:.0f} degrees apart")
        kind = ("cap (2 faces on one surface, normals %s 45 degrees apart)" % ("<=" if ang <= 45 else ">")
                if t1 == t2 else "2 boundary faces on different surfaces (at a feature edge)")
    elif len(bf) == 1:
        kind = "1 boundary face"
    elif not bf:
        kind = "no boundary face, %d corners on the surface" % on
    return kind, "; ".join(parts)


def main(argv=None):
    ap = argparse.ArgumentParser(description="Describe the inverted cells of one corpus run.")
    ap.add_argument("case")
    ap.add_argument("order", type=int)
    ap.add_argument("--out", default=str(REPO / "bench" / "out" / "corpus"))
    a = ap.parse_args(argv)
    mesh_dir = Path(a.out) / "meshes"
    manifest = corpus.ensure_corpus(mesh_dir, only=[a.case])
    case = next(c for c in manifest["cases"] if c["name"] == a.case)
    curved_shapes = [g.split("=", 1)[1] for g in case["geometry"]
                     if g.split("=", 1)[1].split(":")[0] in ("sphere", "torus", "cylinder")]
    import gmsh

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "curved.msh"
        args = [str(corpus.hocurve_bin()), "curve", str(mesh_dir / case["file"]), "--order", str(a.order)]
        for g in case["geometry"]:
            args += ["--geometry", g]
        args += ["--adaptive", "off", "--output", str(out), "--report", str(Path(tmp) / "r.json")]
        r = subprocess.run(args, capture_output=True, text=True)
        if r.returncode != 0:
            print(f"hocurve failed even with --adaptive off: {corpus.error_line(r.stderr)}")
            return 1
        rep = json.loads((Path(tmp) / "r.json").read_text())
        gmsh.initialize(["-noenv"], readConfigFiles=False)
        gmsh.option.setNumber("General.Terminal", 0)
        bad, n = inverted_cells(gmsh, out)
        faces = boundary_faces(gmsh, mesh_dir / case["file"])
        gmsh.finalize()
    print(f"{a.case} p={a.order} --adaptive off: {n} cells ({rep['removed_caps']} caps removed), "
          f"certified-invalid {rep['certified_invalid_elements']}, min Q3 {rep['min_q3']:.3f}; "
          f"{len(bad)} with det J <= 0 at a lattice point:")
    kinds = Counter()
    for corners, dmin, cell, zero in bad:
        kind, text = describe(corners, faces, curved_shapes, zero)
        kinds[kind] += 1
        print(f"  cell {cell}: min det J {dmin:.2e}; {text}")
    for kind, k in kinds.most_common():
        print(f"  {k} x {kind}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
