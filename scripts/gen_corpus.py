#!/usr/bin/env python3
"""Robustness corpus: linear tet meshes of analytic cavities in a box, made by
three mesh generators, with a manifest saying how to curve each one.

    .venv/bin/python scripts/gen_corpus.py --out DIR [--quick] [--only SUBSTR ...]

writes DIR/<case>.msh (gmsh MSH 4.1 ASCII, linear tetrahedra, boundary
triangles with one elementary tag per surface, circle edges of cylinders as
line elements on their curve's tag) and DIR/manifest.json:

    {"corpus": 1, "quick": bool, "gmsh": "4.15.x", "tetgen": "...", "cases": [
       {"name", "file", "generator", "shape", "params", "sizes", "surface",
        "geometry": ["TAG=SHAPE", ...],   # the --geometry arguments of `hocurve curve`
        "cells", "vertices", "boundary_facets", "feature_edges", "quick", "note"}, ...]}

Shapes (all cavities centred at the origin, box [-B, B]^3):
  sphere   sphere of radius r
  torus    torus of radii R, r about the z axis (a thin one, r << R, is the
           anisotropic stand-in for an ellipsoid: there is no ellipsoid shape)
  cylhole  cylinder of radius r along z through the whole box: the cylinder,
           the two holed box faces z = +-B (planes) and the two circles where
           they meet (feature curves, circle3)
  cylcav   finite cylinder cavity |z| <= hz, radius r, with flat caps (planes)
           and its two rim circles (circle3)
and, TetGen only, an anisotropic sphere: a latitude-longitude triangulation
of the sphere ("uvsphere") whose triangles are long in one direction.

Generators:
  gmsh    OpenCASCADE boolean box - cavity, meshed by gmsh in 3D (Frontal-
          Delaunay surfaces, Delaunay volume). Sizes: Mesh.MeshSizeMax h,
          Mesh.MeshSizeMin hmin, and Mesh.MeshSizeFromCurvature n (n elements
          per 2 pi of curvature radius; 0 = off).
  tetgen  Debian's `tetgen -pq1.4a<vol>YQ` on a closed surface triangulation
          written as .smesh (facet marker = surface tag; `Y` keeps every
          boundary vertex ours, on the surface). The surface comes from gmsh's
          2D mesh of the same OCC model ("gmsh"), or is built here with every
          vertex on the surface to rounding: an icosphere, a latitude-longitude
          sphere, a parametric torus grid, each with a structured box.
  cgal    CGAL Mesh_3 of the implicit labelled domain box - cavity (labels:
          0 outside the box, 1 the domain, 2 the cavity), the box's 12 edges
          protected as polyline features; a small C++ program
          (scripts/corpus_cgal.cpp) built once with g++ into the cache
          directory (--cache, default target/corpus-tools). Surface vertices,
          found by bisection, are snapped onto the exact surface (and box
          planes) by closed-form closest point.

Every generator is deterministic (gmsh: one thread, Mesh.RandomSeed 1;
TetGen is deterministic; CGAL: the domain's CGAL::Random(0), and perturbation
and exudation without Mesh_3's default time limit, see corpus_cgal.cpp), so
the corpus is the same on every machine with the same generator versions.
"""
import argparse
import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CGAL_SOURCE = REPO / "scripts" / "corpus_cgal.cpp"

# Tags of the surfaces built here (TetGen's own surfaces, CGAL): the curved
# surface and the box. gmsh-made models keep gmsh's entity tags.
CURVED_TAG = 1
BOX_TAG = 2


def case(name, generator, shape, params, sizes, surface=None, quick=False, note=""):
    return {
        "name": name,
        "generator": generator,
        "shape": shape,
        "params": params,
        "sizes": sizes,
        "surface": surface or generator,
        "quick": quick,
        "note": note,
    }


def sagitta(chord, radius):
    """Distance of a chord's midpoint from a circle of the radius (CGAL's facet_distance for facets of that size)."""
    return round(chord * chord / (8 * radius), 6)


def cases():
    """Every case of the corpus; those with quick=True make the CI subset."""
    out = []
    g = out.append
    # --- gmsh: sweep of radius and elements per circle (box [-1,1]^3, h = 0.5);
    # h = 1 (a coarse box, 100-300 tets) for the CI subset.
    for r in (0.25, 0.5, 0.75):
        for n in (6, 10, 20):
            g(case(f"gmsh-sphere-r{r}-n{n}", "gmsh", "sphere", {"B": 1.0, "r": r}, {"h": 0.5, "hmin": 0.02, "n": n}))
    for r in (0.25, 0.5, 0.75):
        g(case(f"gmsh-sphere-r{r}-n6-h1", "gmsh", "sphere", {"B": 1.0, "r": r}, {"h": 1.0, "hmin": 0.02, "n": 6},
               quick=True))
    # Box [-2,2]^3 with only Mesh.CharacteristicLengthMax 0.5 / Min 0.1 (no
    # point sizes, no curvature sizing): the meshes a first user makes.
    for r in (0.3, 0.6, 1.0, 1.6):
        g(case(f"gmsh-sphere-big-r{r}", "gmsh", "sphere", {"B": 2.0, "r": r},
               {"h": 0.5, "hmin": 0.1, "n": 0, "point_sizes": False},
               note="CharacteristicLengthMax 0.5, Min 0.1 only"))
    for r, n in ((0.3, 6), (0.3, 12), (0.15, 6), (0.15, 12)):
        g(case(f"gmsh-torus-R0.6-r{r}-n{n}", "gmsh", "torus", {"B": 1.0, "R": 0.6, "r": r},
               {"h": 0.5, "hmin": 0.02, "n": n}, note="thin torus: anisotropic curvature" if r < 0.2 else ""))
    g(case("gmsh-torus-R0.6-r0.3-n6-h1", "gmsh", "torus", {"B": 1.0, "R": 0.6, "r": 0.3},
           {"h": 1.0, "hmin": 0.02, "n": 6}, quick=True))
    # Coarser still: 4 and 5 elements per turn of curvature. With their caps
    # removed, some cells end invalid after every stage at p = 2, 3; the run
    # is then made again with the caps kept.
    for R, r, n, h in ((0.6, 0.3, 4, 0.5), (0.6, 0.3, 5, 0.5), (0.6, 0.3, 4, 1.0), (0.5, 0.35, 4, 0.5),
                       (0.5, 0.35, 5, 0.5)):
        g(case(f"gmsh-torus-R{R}-r{r}-n{n}" + ("-h1" if h == 1.0 else ""), "gmsh", "torus",
               {"B": 1.0, "R": R, "r": r}, {"h": h, "hmin": 0.02, "n": n}, quick=(n, h) == (4, 1.0),
               note="coarse: the run that removed caps ends invalid, the one with them kept does not"))
    for r, n in ((0.3, 6), (0.3, 12), (0.6, 6), (0.6, 12)):
        g(case(f"gmsh-cylhole-r{r}-n{n}", "gmsh", "cylhole", {"B": 1.0, "r": r}, {"h": 0.5, "hmin": 0.02, "n": n}))
    g(case("gmsh-cylhole-r0.4-n6-h1", "gmsh", "cylhole", {"B": 1.0, "r": 0.4}, {"h": 1.0, "hmin": 0.02, "n": 6},
           quick=True))
    for r, n in ((0.3, 6), (0.3, 12), (0.5, 6), (0.5, 12)):
        g(case(f"gmsh-cylcav-r{r}-n{n}", "gmsh", "cylcav", {"B": 1.0, "r": r, "hz": 0.4},
               {"h": 0.5, "hmin": 0.02, "n": n}))
    g(case("gmsh-cylcav-r0.5-n6-h1", "gmsh", "cylcav", {"B": 1.0, "r": 0.5, "hz": 0.4},
           {"h": 1.0, "hmin": 0.02, "n": 6}, quick=True))
    # --- TetGen on gmsh's surface mesh of the same models.
    for shape, params, n, h, quick in (
        ("sphere", {"B": 1.0, "r": 0.5}, 6, 0.5, False),
        ("sphere", {"B": 1.0, "r": 0.5}, 12, 0.5, False),
        ("sphere", {"B": 1.0, "r": 0.5}, 6, 1.0, True),
        ("torus", {"B": 1.0, "R": 0.6, "r": 0.3}, 8, 0.5, False),
        ("cylhole", {"B": 1.0, "r": 0.4}, 8, 0.5, False),
        ("cylcav", {"B": 1.0, "r": 0.4, "hz": 0.4}, 8, 0.5, False),
        ("cylcav", {"B": 1.0, "r": 0.4, "hz": 0.4}, 6, 1.0, True),
    ):
        tag = "-".join(f"{k}{v}" for k, v in params.items() if k != "B")
        g(case(f"tetgen-{shape}-{tag}-n{n}" + ("-h1" if h == 1.0 else ""), "tetgen", shape, params,
               {"h": h, "hmin": 0.02, "n": n, "q": 1.4}, surface="gmsh", quick=quick))
    # --- TetGen on surfaces built here, every vertex on the surface.
    for level in (0, 1, 2):
        g(case(f"tetgen-icosphere-r0.5-l{level}", "tetgen", "sphere", {"B": 1.0, "r": 0.5},
               {"level": level, "box_cells": 3, "q": 1.4, "h": 0.5}, surface="icosphere", quick=level == 1,
               note="icosahedron subdivided %d times: ~%d edges around a great circle" % (level, 5 * 2 ** level)))
    for n_lon, n_lat, h in ((24, 4, 0.5), (6, 12, 0.5), (32, 3, 0.5), (16, 4, 1.0)):
        g(case(f"tetgen-uvsphere-r0.5-{n_lon}x{n_lat}" + ("-h1" if h == 1.0 else ""), "tetgen", "sphere",
               {"B": 1.0, "r": 0.5}, {"n_lon": n_lon, "n_lat": n_lat, "box_cells": round(1.5 / h), "q": 1.4, "h": h},
               surface="uvsphere", quick=h == 1.0,
               note="latitude-longitude sphere: stretched surface triangles, fans at the poles"))
    for n_major, n_minor in ((8, 4), (16, 6), (24, 8)):
        g(case(f"tetgen-torusgrid-R0.6-r0.2-{n_major}x{n_minor}", "tetgen", "torus",
               {"B": 1.0, "R": 0.6, "r": 0.2},
               {"n_major": n_major, "n_minor": n_minor, "box_cells": 3, "q": 1.4, "h": 0.5},
               surface="torusgrid", quick=(n_major, n_minor) == (8, 4),
               note="parametric torus grid: %d segments around the tube" % n_minor))
    # --- CGAL Mesh_3, implicit domain (not in the CI subset: building the
    # mesher takes a minute of compiler time).
    for fs in (0.3, 0.15):
        g(case(f"cgal-sphere-r0.5-fs{fs}", "cgal", "sphere", {"B": 1.0, "r": 0.5},
               {"facet_size": fs, "facet_distance": sagitta(fs, 0.5), "cell_size": 0.5, "edge_size": 0.4}))
    for fs in (0.2, 0.12):
        g(case(f"cgal-torus-R0.6-r0.25-fs{fs}", "cgal", "torus", {"B": 1.0, "R": 0.6, "r": 0.25},
               {"facet_size": fs, "facet_distance": sagitta(fs, 0.25), "cell_size": 0.5, "edge_size": 0.4}))
    return out


# ----------------------------------------------------------------------------
# Shapes: the --geometry strings

def fmt(x):
    x = round(float(x), 12)
    if x == int(x):
        return str(int(x))
    return repr(x)


def shape_arg(kind, *vals):
    return f"{kind}:" + ",".join(fmt(v) for v in vals)


def curved_shape(c):
    p = c["params"]
    if c["shape"] == "sphere":
        return shape_arg("sphere", 0, 0, 0, p["r"])
    if c["shape"] == "torus":
        return shape_arg("torus", 0, 0, 0, p["R"], p["r"])
    if c["shape"] in ("cylhole", "cylcav"):
        return shape_arg("cylinder", 0, 0, 0, 0, 0, 1, p["r"])
    raise ValueError(c["shape"])


def cap_height(c):
    """z of the planes (and circles) of a cylinder case."""
    return c["params"]["B"] if c["shape"] == "cylhole" else c["params"]["hz"]


# ----------------------------------------------------------------------------
# MSH 4.1 writer (ASCII): one volume (tag 1), surfaces and curves by tag.

def orient(coords, tets):
    out = []
    for t in tets:
        a, b, c, d = (coords[i] for i in t)
        u = [b[k] - a[k] for k in range(3)]
        v = [c[k] - a[k] for k in range(3)]
        w = [d[k] - a[k] for k in range(3)]
        det = (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
               + u[2] * (v[0] * w[1] - v[1] * w[0]))
        out.append((t[0], t[1], t[3], t[2]) if det < 0 else tuple(t))
    return out


def write_msh(path, coords, tets, tris, lines=()):
    """coords: list of (x,y,z); tets: 0-based 4-tuples; tris: (a,b,c,tag); lines: (a,b,tag).

    Only vertices used by the tets are written (renumbered in first-use order)."""
    used = {}
    for t in tets:
        for v in t:
            if v not in used:
                used[v] = len(used)
    for e in list(tris) + list(lines):
        for v in e[:-1]:
            if v not in used:
                raise ValueError(f"boundary element uses vertex {v}, which is in no tet")
    xyz = [None] * len(used)
    for old, new in used.items():
        xyz[new] = coords[old]
    tets = orient(xyz, [tuple(used[v] for v in t) for t in tets])
    surf = {}
    for a, b, c, tag in tris:
        surf.setdefault(tag, []).append((used[a], used[b], used[c]))
    curv = {}
    for a, b, tag in lines:
        curv.setdefault(tag, []).append((used[a], used[b]))

    def bbox(elems):
        pts = [xyz[v] for e in elems for v in e]
        return " ".join(f"{min(p[k] for p in pts):.17g}" for k in range(3)) + " " + " ".join(
            f"{max(p[k] for p in pts):.17g}" for k in range(3))

    w = []
    w.append("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
    w.append(f"$Entities\n0 {len(curv)} {len(surf)} 1\n")
    for tag in sorted(curv):
        w.append(f"{tag} {bbox(curv[tag])} 1 {tag} 0\n")
    for tag in sorted(surf):
        w.append(f"{tag} {bbox(surf[tag])} 1 {tag} 0\n")
    w.append(f"1 {bbox(tets)} 1 1 {len(surf)} " + " ".join(str(t) for t in sorted(surf)) + "\n")
    w.append("$EndEntities\n")
    n = len(xyz)
    w.append(f"$Nodes\n1 {n} 1 {n}\n3 1 0 {n}\n")
    w.append("".join(f"{i + 1}\n" for i in range(n)))
    w.append("".join(f"{p[0]:.17g} {p[1]:.17g} {p[2]:.17g}\n" for p in xyz))
    w.append("$EndNodes\n")
    blocks = [(1, tag, 1, curv[tag]) for tag in sorted(curv)] + [(2, tag, 2, surf[tag]) for tag in sorted(surf)]
    blocks.append((3, 1, 4, tets))
    total = sum(len(b[3]) for b in blocks)
    w.append(f"$Elements\n{len(blocks)} {total} 1 {total}\n")
    k = 1
    for dim, tag, etype, elems in blocks:
        w.append(f"{dim} {tag} {etype} {len(elems)}\n")
        for e in elems:
            w.append(f"{k} " + " ".join(str(v + 1) for v in e) + "\n")
            k += 1
    w.append("$EndElements\n")
    Path(path).write_text("".join(w))
    return {"cells": len(tets), "vertices": n, "boundary_facets": sum(len(v) for v in surf.values()),
            "feature_edges": sum(len(v) for v in curv.values())}


# ----------------------------------------------------------------------------
# gmsh: OCC models, 3D meshes, and 2D surface meshes for TetGen

def gmsh_start():
    import gmsh

    if not gmsh.isInitialized():
        gmsh.initialize(["-noenv"], readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.Verbosity", 1)
    gmsh.option.setNumber("General.NumThreads", 1)
    return gmsh


def gmsh_model(gmsh, c):
    """Builds the OCC model of case c; returns (geometry args, hole point or None)."""
    p = c["params"]
    B = p["B"]
    occ = gmsh.model.occ
    gmsh.model.add(c["name"])
    box = occ.addBox(-B, -B, -B, 2 * B, 2 * B, 2 * B)
    if c["shape"] == "sphere":
        tool = occ.addSphere(0, 0, 0, p["r"])
        hole = (0.0, 0.0, 0.0)
    elif c["shape"] == "torus":
        tool = occ.addTorus(0, 0, 0, p["R"], p["r"])
        hole = (p["R"], 0.0, 0.0)
    elif c["shape"] == "cylhole":
        tool = occ.addCylinder(0, 0, -B - 1, 0, 0, 2 * B + 2, p["r"])
        hole = None
    elif c["shape"] == "cylcav":
        tool = occ.addCylinder(0, 0, -p["hz"], 0, 0, 2 * p["hz"], p["r"])
        hole = (0.0, 0.0, 0.0)
    else:
        raise ValueError(c["shape"])
    occ.cut([(3, box)], [(3, tool)])
    occ.synchronize()
    geometry = []
    kind = {"sphere": "Sphere", "torus": "Torus", "cylhole": "Cylinder", "cylcav": "Cylinder"}[c["shape"]]
    curved = [t for d, t in gmsh.model.getEntities(2) if gmsh.model.getType(d, t) == kind]
    if len(curved) != 1:
        raise RuntimeError(f"{c['name']}: expected one {kind} surface, got {curved}")
    geometry.append(f"{curved[0]}={curved_shape(c)}")
    if c["shape"] in ("cylhole", "cylcav"):
        zc = cap_height(c)
        eps = 1e-6
        for d, t in gmsh.model.getEntities(2):
            if gmsh.model.getType(d, t) != "Plane":
                continue
            x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(d, t)
            if abs(z1 - z0) < eps and abs(abs(z0) - zc) < eps:
                s = 1.0 if z0 > 0 else -1.0
                geometry.append(f"{t}={shape_arg('plane', 0, 0, s * zc, 0, 0, 1)}")
        circles = 0
        for d, t in gmsh.model.getEntities(1):
            if gmsh.model.getType(d, t) != "Circle":
                continue
            x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(d, t)
            if abs(z1 - z0) < eps and abs(abs(z0) - zc) < eps:
                s = 1.0 if z0 > 0 else -1.0
                geometry.append(f"{t}={shape_arg('circle3', 0, 0, s * zc, 0, 0, 1, c['params']['r'])}")
                circles += 1
        if circles != 2:
            raise RuntimeError(f"{c['name']}: expected two rim circles, got {circles}")
    return geometry, hole


def gmsh_sizes(gmsh, s):
    """Mesh options; unless point_sizes is False, every model point gets size h
    too (gmsh's own default point size would otherwise cap the size near 0.35
    whatever MeshSizeMax says)."""
    if s.get("point_sizes", True):
        gmsh.model.mesh.setSize(gmsh.model.getEntities(0), s["h"])
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.option.setNumber("Mesh.MeshSizeMax", s["h"])
    gmsh.option.setNumber("Mesh.MeshSizeMin", s["hmin"])
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", s.get("n", 0))
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)


def mesh_arrays(gmsh, dim):
    """(coords by node tag, tets, tris with tags, lines with tags), from the current model."""
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    index = {int(t): i for i, t in enumerate(tags)}
    coords = [tuple(xyz[3 * i:3 * i + 3]) for i in range(len(tags))]
    tets, tris, lines = [], [], []
    for d, t in gmsh.model.getEntities():
        if d == 0:
            continue
        for et, _ets, nodes in zip(*gmsh.model.mesh.getElements(d, t)):
            if d == 3 and et == 4:
                tets += [tuple(index[int(v)] for v in nodes[i:i + 4]) for i in range(0, len(nodes), 4)]
            elif d == 2 and et == 2:
                tris += [(index[int(nodes[i])], index[int(nodes[i + 1])], index[int(nodes[i + 2])], t)
                         for i in range(0, len(nodes), 3)]
            elif d == 1 and et == 1:
                lines += [(index[int(nodes[i])], index[int(nodes[i + 1])], t) for i in range(0, len(nodes), 2)]
            else:
                raise RuntimeError(f"unexpected element type {et} on ({d}, {t})")
    return coords, tets, tris, lines


def gen_gmsh(c, path, work):
    gmsh = gmsh_start()
    try:
        geometry, _hole = gmsh_model(gmsh, c)
        gmsh_sizes(gmsh, c["sizes"])
        gmsh.model.mesh.generate(3)
        coords, tets, tris, lines = mesh_arrays(gmsh, 3)
    finally:
        gmsh.model.remove()
    stats = write_msh(path, coords, tets, tris, lines)
    return geometry, stats


# ----------------------------------------------------------------------------
# Surfaces built here (every vertex on the exact surface to rounding)

def icosphere(level, r):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
         (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = [tuple(float(x) for x in p) for p in v]
    for _ in range(level):
        mid = {}

        def m(a, b):
            k = (min(a, b), max(a, b))
            if k not in mid:
                v.append(tuple((v[a][i] + v[b][i]) / 2 for i in range(3)))
                mid[k] = len(v) - 1
            return mid[k]

        g = []
        for a, b, cc in f:
            ab, bc, ca = m(a, b), m(b, cc), m(cc, a)
            g += [(a, ab, ca), (b, bc, ab), (cc, ca, bc), (ab, bc, ca)]
        f = g
    out = []
    for p in v:
        n = math.sqrt(sum(x * x for x in p))
        out.append(tuple(x / n * r for x in p))
    return out, f


def uvsphere(n_lon, n_lat, r):
    v = [(0.0, 0.0, r), (0.0, 0.0, -r)]
    ring = []
    for i in range(1, n_lat):
        th = math.pi * i / n_lat
        row = []
        for j in range(n_lon):
            ph = 2 * math.pi * j / n_lon
            v.append((r * math.sin(th) * math.cos(ph), r * math.sin(th) * math.sin(ph), r * math.cos(th)))
            row.append(len(v) - 1)
        ring.append(row)
    f = []
    for j in range(n_lon):
        j1 = (j + 1) % n_lon
        f.append((0, ring[0][j], ring[0][j1]))
        f.append((1, ring[-1][j1], ring[-1][j]))
        for i in range(n_lat - 2):
            a, b, cc, d = ring[i][j], ring[i][j1], ring[i + 1][j1], ring[i + 1][j]
            f += [(a, d, cc), (a, cc, b)]
    return v, f


def torusgrid(n_major, n_minor, R, r):
    v, f = [], []
    for i in range(n_major):
        u = 2 * math.pi * i / n_major
        for j in range(n_minor):
            w = 2 * math.pi * j / n_minor
            v.append(((R + r * math.cos(w)) * math.cos(u), (R + r * math.cos(w)) * math.sin(u), r * math.sin(w)))
    for i in range(n_major):
        for j in range(n_minor):
            a = i * n_minor + j
            b = ((i + 1) % n_major) * n_minor + j
            cc = ((i + 1) % n_major) * n_minor + (j + 1) % n_minor
            d = i * n_minor + (j + 1) % n_minor
            # Alternate the diagonal so the grid has no preferred direction.
            f += [(a, b, cc), (a, cc, d)] if (i + j) % 2 == 0 else [(a, b, d), (b, cc, d)]
    return v, f


def box_surface(n, h):
    ids, v, f = {}, [], []

    def vertex(i, j, k):
        key = (i, j, k)
        if key not in ids:
            v.append((-h + 2 * h * i / n, -h + 2 * h * j / n, -h + 2 * h * k / n))
            ids[key] = len(v) - 1
        return ids[key]

    for axis in range(3):
        for side in (0, 1):
            for a in range(n):
                for b in range(n):
                    def at(da, db):
                        c = [0, 0, 0]
                        c[axis] = side * n
                        c[(axis + 1) % 3] = a + da
                        c[(axis + 2) % 3] = b + db
                        return vertex(*c)
                    p00, p10, p11, p01 = at(0, 0), at(1, 0), at(1, 1), at(0, 1)
                    if (a + b) % 2 == 0:
                        f += [(p00, p10, p11), (p00, p11, p01)]
                    else:
                        f += [(p00, p10, p01), (p10, p11, p01)]
    return v, f


# ----------------------------------------------------------------------------
# TetGen

def tetgen_version():
    """TetGen's package version (the binary has no version switch)."""
    try:
        r = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "tetgen"], capture_output=True, text=True,
                           timeout=30)
        if r.returncode == 0 and r.stdout.strip():
            return "tetgen " + r.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return "tetgen"


def run_tetgen(coords, tris, hole, s, work, name):
    """coords: vertices; tris: (a, b, c, marker). Returns (coords, tets, faces with markers)."""
    base = str(Path(work) / name)  # names have dots: no with_suffix
    out = [f"{len(coords)} 3 0 0\n"]
    out += [f"{i + 1} {p[0]:.17g} {p[1]:.17g} {p[2]:.17g}\n" for i, p in enumerate(coords)]
    out.append(f"{len(tris)} 1\n")
    out += [f"3 {a + 1} {b + 1} {c + 1} {m}\n" for a, b, c, m in tris]
    if hole is None:
        out.append("0\n")
    else:
        out.append(f"1\n1 {hole[0]:.17g} {hole[1]:.17g} {hole[2]:.17g}\n")
    out.append("0\n")
    Path(base + ".smesh").write_text("".join(out))
    vol = 0.12 * s["h"] ** 3  # a regular tet of edge h
    switches = f"-pq{s.get('q', 1.4)}a{vol:.6g}YQ"
    if shutil.which("tetgen") is None:
        raise RuntimeError("the `tetgen` binary is not on PATH: install Debian's tetgen (scripts/apt_deps.sh)")
    r = subprocess.run(["tetgen", switches, base + ".smesh"], capture_output=True, text=True, timeout=600)
    res = base + ".1"
    if r.returncode != 0 or not Path(res + ".ele").exists():
        raise RuntimeError(f"tetgen {switches} failed ({r.returncode}): {r.stdout[-2000:]} {r.stderr[-2000:]}")

    def rows(ext):
        lines = [l.split("#")[0].split() for l in Path(res + ext).read_text().splitlines()]
        return [l for l in lines if l]

    node = rows(".node")
    nv = int(node[0][0])
    first = int(node[1][0])
    xyz = [(float(l[1]), float(l[2]), float(l[3])) for l in node[1:1 + nv]]
    ele = rows(".ele")
    tets = [tuple(int(x) - first for x in l[1:5]) for l in ele[1:1 + int(ele[0][0])]]
    face = rows(".face")
    if int(face[0][1]) != 1:
        raise RuntimeError("tetgen wrote no boundary markers")
    faces = [(int(l[1]) - first, int(l[2]) - first, int(l[3]) - first, int(l[4])) for l in face[1:1 + int(face[0][0])]]
    # Input vertices keep their index (TetGen numbers its own after ours).
    if len(xyz) < len(coords) or any(max(abs(xyz[i][k] - coords[i][k]) for k in range(3)) > 1e-12
                                     for i in range(len(coords))):
        raise RuntimeError("tetgen moved or renumbered input vertices")
    return xyz, tets, faces


def gen_tetgen(c, path, work):
    s, p = c["sizes"], c["params"]
    lines = []
    if c["surface"] == "gmsh":
        gmsh = gmsh_start()
        try:
            geometry, hole = gmsh_model(gmsh, c)
            gmsh_sizes(gmsh, s)
            gmsh.model.mesh.generate(2)
            coords, _t, tris, lines = mesh_arrays(gmsh, 2)
        finally:
            gmsh.model.remove()
    else:
        if c["surface"] == "icosphere":
            sv, sf = icosphere(s["level"], p["r"])
            hole = (0.0, 0.0, 0.0)
        elif c["surface"] == "uvsphere":
            sv, sf = uvsphere(s["n_lon"], s["n_lat"], p["r"])
            hole = (0.0, 0.0, 0.0)
        elif c["surface"] == "torusgrid":
            sv, sf = torusgrid(s["n_major"], s["n_minor"], p["R"], p["r"])
            hole = (p["R"], 0.0, 0.0)
        else:
            raise ValueError(c["surface"])
        bv, bf = box_surface(s["box_cells"], p["B"])
        coords = list(sv) + list(bv)
        off = len(sv)
        tris = [(a, b, cc, CURVED_TAG) for a, b, cc in sf] + [(a + off, b + off, cc + off, BOX_TAG) for a, b, cc in bf]
        geometry = [f"{CURVED_TAG}={curved_shape(c)}"]
    xyz, tets, faces = run_tetgen(coords, tris, hole, s, work, c["name"])
    markers = {t[3] for t in tris}
    bad = {f[3] for f in faces} - markers
    if bad:
        raise RuntimeError(f"tetgen boundary faces with unknown markers {bad}")
    stats = write_msh(path, xyz, tets, faces, lines)
    if stats["boundary_facets"] != len(tris):
        raise RuntimeError(f"tetgen changed the surface: {stats['boundary_facets']} faces for {len(tris)}")
    return geometry, stats


# ----------------------------------------------------------------------------
# CGAL

def cgal_tool(cache):
    """Path of the compiled CGAL mesher (built once per source hash)."""
    src = CGAL_SOURCE.read_bytes()
    key = hashlib.sha256(src).hexdigest()[:12]
    cache = Path(cache)
    exe = cache / f"corpus_cgal-{key}"
    if exe.exists():
        return exe
    cache.mkdir(parents=True, exist_ok=True)
    cxx = os.environ.get("CXX", "g++")
    tmp = exe.with_suffix(".tmp")
    cmd = [cxx, "-std=c++17", "-O2", "-DNDEBUG", "-frounding-math", str(CGAL_SOURCE), "-o",
           str(tmp), "-lgmp", "-lmpfr"]
    print(f"gen_corpus: building {exe.name} ({' '.join(cmd)})", file=sys.stderr, flush=True)
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"building the CGAL mesher failed:\n{r.stderr[-4000:]}")
    tmp.rename(exe)
    return exe


def gen_cgal(c, path, work, cache):
    exe = cgal_tool(cache)
    s, p = c["sizes"], c["params"]
    out = Path(work) / (c["name"] + ".txt")
    shape = [c["shape"], fmt(p["B"])] + ([fmt(p["r"])] if c["shape"] == "sphere" else [fmt(p["R"]), fmt(p["r"])])
    cmd = [str(exe), *shape, fmt(s["facet_size"]), fmt(s["facet_distance"]), fmt(s["cell_size"]),
           fmt(s["edge_size"]), str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1200)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr[-2000:]}")
    toks = out.read_text().split()
    k = 0

    def take(n):
        nonlocal k
        v = toks[k:k + n]
        k += n
        return v

    nv, nt, nf = (int(x) for x in take(3))
    coords = [tuple(float(x) for x in take(3)) for _ in range(nv)]
    tets = [tuple(int(x) for x in take(4)) for _ in range(nt)]
    tris = [tuple(int(x) for x in take(4)) for _ in range(nf)]
    stats = write_msh(path, coords, tets, tris)
    stats["max_surface_error"] = float(r.stdout.split("max_surface_error")[1].split()[0]) if "max_surface_error" in r.stdout else None
    return [f"{CURVED_TAG}={curved_shape(c)}"], stats


# ----------------------------------------------------------------------------

def generate(out_dir, quick=False, only=None, cache=None, log=sys.stderr):
    """Writes the meshes and manifest.json into out_dir; returns the manifest."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cache = Path(cache or os.environ.get("HOCURVE_CORPUS_CACHE", REPO / "target" / "corpus-tools"))
    selected = [c for c in cases() if (c["quick"] or not quick) and (not only or any(o in c["name"] for o in only))]
    manifest = {"corpus": 1, "quick": quick, "gmsh": None, "tetgen": None, "cases": []}
    with tempfile.TemporaryDirectory(prefix="hocurve-corpus-") as work:
        for c in selected:
            path = out_dir / f"{c['name']}.msh"
            gen = {"gmsh": gen_gmsh, "tetgen": gen_tetgen}.get(c["generator"])
            if gen:
                geometry, stats = gen(c, path, work)
            else:
                geometry, stats = gen_cgal(c, path, work, cache)
            entry = dict(c, file=path.name, geometry=geometry, **stats)
            manifest["cases"].append(entry)
            print(f"gen_corpus: {c['name']}: {stats['cells']} tets, {stats['vertices']} vertices, "
                  f"geometry {' '.join(geometry)}", file=log, flush=True)
    if any(c["generator"] != "cgal" for c in selected):
        g = gmsh_start()
        manifest["gmsh"] = g.option.getString("General.Version")
        g.finalize()
    if any(c["generator"] == "tetgen" for c in selected):
        manifest["tetgen"] = tetgen_version()
    (out_dir / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", help="output directory (meshes and manifest.json)")
    ap.add_argument("--quick", action="store_true", help="only the CI subset")
    ap.add_argument("--only", nargs="*", help="only cases whose name contains one of these")
    ap.add_argument("--cache", help="where the CGAL mesher is built (default target/corpus-tools)")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    a = ap.parse_args(argv)
    if a.list:
        for c in cases():
            print(f"{'Q' if c['quick'] else ' '} {c['name']}")
        return 0
    if not a.out:
        ap.error("--out DIR is required")
    generate(a.out, a.quick, a.only, a.cache)
    return 0


if __name__ == "__main__":
    sys.exit(main())
