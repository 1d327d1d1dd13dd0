#!/usr/bin/env python3
"""How much sagitta a stack of thin layers under a flat face can absorb, by order.

    .venv/bin/python bench/layer_stack.py [--sides 12,24] [--ratios 0.3,0.45,0.5,0.7,0.9] [--orders 2,3,4]

A 2D annulus: the wall is the regular N-gon inscribed in a circle of radius
0.5 (curved onto the circle), the outer boundary the same N-gon pushed
radially out by T and left flat (no geometry), and between them 10 layers
of triangles growing by 1.3 (each quadrilateral of the extrusion split by
one diagonal). The wall's edges bulge out by their sagitta
s = 0.5 (1 - cos(pi / N)), which the whole stack has to absorb under the
fixed flat face: T is chosen so that s / T takes each ratio asked. Each
mesh is curved by `hocurve curve` with its defaults at each order; the
table shows min Q3, or FAIL when hocurve refuses the mesh (some cell
certified invalid after the optimisation).

With the vertices fixed, a quadratic triangle of such a layer of thickness
t, whose bottom and top edges bulge by e and e' (and the diagonal between
them by d, moved along the normal only), has det J > 0 only if
e - t/4 < d < e' + t/4, so the layers can share at most s < T/2 in all;
cubic and higher elements come close to the geometric limit s < T. This
script measures where hocurve's limits are.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile


def make(gmsh, path, sides, thickness, layers=10, growth=1.3):
    """The annulus of `layers` layers of triangles between the wall N-gon and its flat copy `thickness` out."""
    widths = [growth**k for k in range(layers)]
    heights = [0.0]
    for w in widths:
        heights.append(heights[-1] + w)
    z = [thickness * h / heights[-1] for h in heights]

    def node(i, k):
        return 1 + i % sides + sides * k

    coords = []
    for k in range(layers + 1):
        for i in range(sides):
            a = 2 * math.pi * i / sides
            coords += [(0.5 + z[k]) * math.cos(a), (0.5 + z[k]) * math.sin(a), 0.0]
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.model.add("stack")
        gmsh.model.addDiscreteEntity(1, 1)  # the wall
        gmsh.model.addDiscreteEntity(1, 2)  # the flat outer face
        gmsh.model.addDiscreteEntity(2, 1, [1, 2])
        gmsh.model.mesh.addNodes(2, 1, list(range(1, len(coords) // 3 + 1)), coords)
        triangles = []
        for k in range(layers):
            for i in range(sides):
                a, b, c, d = node(i, k), node(i + 1, k), node(i + 1, k + 1), node(i, k + 1)
                triangles += [a, b, d, b, c, d]
        gmsh.model.mesh.addElementsByType(1, 2, [], triangles)
        gmsh.model.mesh.addElementsByType(1, 1, [], [n for i in range(sides) for n in (node(i, 0), node(i + 1, 0))])
        gmsh.model.mesh.addElementsByType(
            2, 1, [], [n for i in range(sides) for n in (node(i + 1, layers), node(i, layers))])
        gmsh.write(path)
    finally:
        gmsh.finalize()


def curve(binary, mesh, order, work):
    report = os.path.join(work, "report.json")
    if os.path.exists(report):
        os.remove(report)
    args = [binary, "curve", mesh, "--order", str(order), "--geometry", "1=circle:0,0,0.5",
            "--output", os.path.join(work, "curved.msh"), "--report", report]
    run = subprocess.run(args, capture_output=True, text=True)
    if run.returncode != 0:
        return "FAIL"
    return f"{json.load(open(report))['min_q3']:.3f}"


def main():
    import gmsh

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--hocurve", default=os.path.join(root, "target", "release", "hocurve"))
    ap.add_argument("--sides", default="12,24")
    ap.add_argument("--ratios", default="0.3,0.45,0.5,0.7,0.9")
    ap.add_argument("--orders", default="2,3,4")
    a = ap.parse_args()
    orders = [int(p) for p in a.orders.split(",")]
    print(f"{'N':>3} {'s/T':>5} {'s':>8} {'T':>8} " + " ".join(f"{'p = ' + str(p):>6}" for p in orders))
    with tempfile.TemporaryDirectory() as work:
        mesh = os.path.join(work, "stack.msh")
        for sides in [int(n) for n in a.sides.split(",")]:
            sagitta = 0.5 * (1 - math.cos(math.pi / sides))
            for ratio in [float(r) for r in a.ratios.split(",")]:
                make(gmsh, mesh, sides, sagitta / ratio)
                cells = " ".join(f"{curve(a.hocurve, mesh, p, work):>6}" for p in orders)
                print(f"{sides:>3} {ratio:5.2f} {sagitta:8.5f} {sagitta / ratio:8.5f} {cells}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
