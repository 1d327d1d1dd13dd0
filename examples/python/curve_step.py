"""Curve a STEP part at order 3 with gmsh and hocurve: python curve_step.py part.step"""
import sys

import gmsh
import hocurve.gmsh

gmsh.initialize()
gmsh.model.occ.importShapes(sys.argv[1])
gmsh.model.occ.synchronize()
gmsh.model.mesh.generate(3)
result = hocurve.gmsh.curve_model(order=3)
print(f"{len(result.cells)} cells, min Q3 {result.quality['min_q3']:.3f}, valid: {result.valid}")
gmsh.write(sys.argv[1].rsplit(".", 1)[0] + "-p3.msh")
gmsh.finalize()
