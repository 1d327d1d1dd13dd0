#!/usr/bin/env python3
"""Boundary layers made by gmsh, curved by hocurve's iterative solver.

    .venv/bin/python bench/gmsh_layers.py [--out DIR] [--orders 2,3,4] [--hocurve BIN ...]

Makes five meshes with gmsh's own boundary-layer tools (not hocurve's
built-in layer cases) and curves each with `hocurve curve --solver
iterative` at every order, printing the PCG iterations of every increment,
the fallbacks, min Q3 and certified-invalid cells:

- `bl2d-iso`, `bl2d-100`, `bl2d-1000`: the square [-2, 2]² minus a disk of
  radius 0.5, triangles of size 0.05 (Frontal-Delaunay), with a BoundaryLayer
  field on the circle (triangles, growth 1.3, 0.3 thick) whose first layer
  is 0.05 / 100 or 0.05 / 1000; `iso` has no layer.
- `bl3d-100`, `bl3d-1000`: the surface of a sphere of radius 0.5 meshed at
  size 0.15 and extruded outwards by `extrudeBoundaryLayer` in 15 layers
  growing by 1.3 from 0.15 / 100 or 0.15 / 1000, not recombined (tetrahedra).
  The extrusion's outer surface is curved as the sphere it lies on
  (radius 0.5 + the layers' thickness); `--outer straight` leaves it flat.

Several `--hocurve` binaries (for example the versions before and after a
change) are run one after the other on each case. gmsh runs on one thread
with fixed options, so the meshes are the same on every run.
"""

import argparse
import json
import math
import os
import subprocess
import sys

CASES = ["bl2d-iso", "bl2d-100", "bl2d-1000", "bl3d-100", "bl3d-1000"]


def mesh_2d(gmsh, path, first):
    """Square minus a disk, with gmsh's BoundaryLayer field on the circle (none if `first` is None)."""
    occ = gmsh.model.occ
    box = occ.addRectangle(-2, -2, 0, 4, 4)
    disk = occ.addDisk(0, 0, 0, 0.5, 0.5)
    out, _ = occ.cut([(2, box)], [(2, disk)])
    occ.synchronize()
    curves = [c for _, c in gmsh.model.getBoundary(out, oriented=False)]
    circle = [c for c in curves if abs(occ.getMass(1, c) - math.pi) < 1e-6]
    if first is not None:
        f = gmsh.model.mesh.field.add("BoundaryLayer")
        gmsh.model.mesh.field.setNumbers(f, "CurvesList", circle)
        gmsh.model.mesh.field.setNumber(f, "Size", first)
        gmsh.model.mesh.field.setNumber(f, "Ratio", 1.3)
        gmsh.model.mesh.field.setNumber(f, "Thickness", 0.3)
        gmsh.model.mesh.field.setNumber(f, "Quads", 0)
        gmsh.model.mesh.field.setAsBoundaryLayer(f)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.05)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.model.mesh.generate(2)
    gmsh.write(path)
    return [f"{circle[0]}=circle:0,0,0.5"], None


def mesh_3d(gmsh, path, first):
    """A sphere's surface extruded outwards in 15 layers of tetrahedra."""
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.15)
    s = gmsh.model.occ.addSphere(0, 0, 0, 0.5)
    gmsh.model.occ.synchronize()
    surface = abs(gmsh.model.getBoundary([(3, s)])[0][1])
    gmsh.model.occ.remove([(3, s)])
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Geometry.ExtrudeReturnLateralEntities", 0)
    heights, t, total = [], first, 0.0
    for _ in range(15):
        total += t
        heights.append(total)
        t *= 1.3
    ext = gmsh.model.geo.extrudeBoundaryLayer([(2, surface)], [1] * 15, heights, False)
    gmsh.model.geo.synchronize()
    gmsh.model.mesh.generate(3)
    gmsh.write(path)
    top = [tag for dim, tag in ext if dim == 2][0]
    return [f"{surface}=sphere:0,0,0,0.5"], f"{top}=sphere:0,0,0,{0.5 + total:.9g}"


def make(case, path):
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.model.add(case)
        dim, stretch = case[2], case.split("-")[1]
        if dim == "2":
            return mesh_2d(gmsh, path, None if stretch == "iso" else 0.05 / float(stretch))
        return mesh_3d(gmsh, path, 0.15 / float(stretch))
    finally:
        gmsh.finalize()


def curve(binary, mesh, order, geometry, out):
    report = os.path.join(out, "report.json")
    args = [binary, "curve", mesh, "--order", str(order), "--solver", "iterative"]
    for g in geometry:
        args += ["--geometry", g]
    args += ["--output", os.path.join(out, "curved.msh"), "--report", report]
    run = subprocess.run(args, capture_output=True, text=True)
    if run.returncode != 0:
        return "error: " + (run.stderr.strip().splitlines() or ["?"])[-1]
    r = json.load(open(report))
    return (f"{r['system_dofs']:>8} {str(r['solver_iterations']):<34} {r['fallbacks']:>3} "
            f"{r['min_q3']:7.3f} {r['certified_invalid_elements']:>4} {r['seconds']['solve']:7.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--out", default=os.path.join(root, "bench", "out", "gmsh-layers"))
    ap.add_argument("--orders", default="2,3,4")
    ap.add_argument("--hocurve", action="append", help="binary to run (repeatable; default target/release/hocurve)")
    ap.add_argument("--outer", choices=["curved", "straight"], default="curved",
                    help="the 3D extrusion's outer surface on its sphere, or left flat")
    ap.add_argument("--only", nargs="*", help="only these cases")
    a = ap.parse_args()
    binaries = a.hocurve or [os.path.join(root, "target", "release", "hocurve")]
    os.makedirs(a.out, exist_ok=True)
    print(f"{'case':<10} {'p':>2} {'binary':<28} {'unknowns':>8} {'PCG iterations per increment':<34} "
          f"{'fb':>3} {'min_Q3':>7} {'inv':>4} {'solve_s':>7}")
    for case in CASES:
        if a.only and case not in a.only:
            continue
        mesh = os.path.join(a.out, case + ".msh")
        geometry, outer = make(case, mesh)
        if outer and a.outer == "curved":
            geometry.append(outer)
        for p in [int(x) for x in a.orders.split(",")]:
            for b in binaries:
                print(f"{case:<10} {p:>2} {b[-28:]:<28} {curve(b, mesh, p, geometry, a.out)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
