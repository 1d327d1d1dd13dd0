"""A curved 2D mesh coloured by Q3: a plate with a hole curved at order 4,
drawn with matplotlib into plate-q3.png (python plot_2d.py [out.png])."""
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import meshio
import numpy as np
from matplotlib.collections import PolyCollection

import hocurve

repo = Path(__file__).resolve().parents[2]
mesh = hocurve.from_meshio(meshio.read(repo / "tests" / "data" / "plate_hole_2d.msh"), shapes={5: "circle:1,0.5,0.25"})
result = mesh.run(order=4, ordering="vtk")

# Each curved triangle drawn as the polygon through its boundary nodes:
# VTK's Lagrange triangle lists the vertices, then each edge's nodes in turn.
p = result.order
edges = [[0] + list(range(3, 3 + (p - 1))), [1] + list(range(2 + p, 1 + 2 * p)), [2] + list(range(1 + 2 * p, 3 * p))]
outline = [i for e in edges for i in e]
polygons = [result.nodes[cell[outline]] for cell in result.cells]

fig, ax = plt.subplots(figsize=(8, 4))
coll = PolyCollection(polygons, array=result.cell_quality[:, 2], cmap="viridis", edgecolors="k", linewidths=0.3)
ax.add_collection(coll)
ax.autoscale()
ax.set_aspect("equal")
fig.colorbar(coll, ax=ax, label="Q3 (scaled Jacobian)")
ax.set_title(f"p = {p}: min Q3 {result.quality['min_q3']:.3f}, {len(result.cells)} cells")
out = sys.argv[1] if len(sys.argv) > 1 else "plate-q3.png"
fig.savefig(out, dpi=120)
print(f"wrote {out}")
