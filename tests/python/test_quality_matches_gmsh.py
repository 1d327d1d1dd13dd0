"""`hocurve quality` on meshes gmsh curved itself agrees with gmsh's Jacobians.

Three figures per case, all printed:
  * hocurve's min Q3 (min J / max J at its sample points: the degree-2p
    quadrature rule plus the equispaced lattice of order 2p);
  * gmsh's det J sampled at exactly those points (rebuilt in
    meshes.hocurve_sample_points): must agree to round-off, element by element
    through min, mean and the worst cell. A node-ordering error in the reader
    would change the Jacobians, so this is the sharp check;
  * gmsh's AnalyseMeshQuality plugin (Bézier bounds over the whole element):
    a lower bound of the true min J / max J, so hocurve must not read below it,
    and must be within 0.02 of it on valid meshes.
"""
import json

import numpy as np
import pytest

import meshes as M

# (dim, p, box half-width): the box [-1,1]^3 meshed at h = 0.5 has one tet
# with all four vertices on the sphere, which gmsh's own curving inverts.
CASES = [(2, 2, 0), (2, 3, 0), (2, 4, 0), (3, 2, 0.8), (3, 3, 0.8), (3, 4, 0.8), (3, 3, 1.0)]


def gmsh_mesh(gmsh, dim, p, half, path):
    if dim == 2:
        M.square_with_hole(gmsh, 0.3, order=p)
    else:
        M.box_with_sphere(gmsh, 0.3 if half < 1 else 0.5, order=p, half=half)
    M.write_msh41(gmsh, path)


@pytest.mark.parametrize("dim,p,half", CASES, ids=[f"{d}d-p{p}" + ("-inverted" if b == 1 else "") for d, p, b in CASES])
def test_quality_matches_gmsh(gmsh, hocurve, tmp_path, dim, p, half):
    path, rep = tmp_path / "mesh.msh", tmp_path / "q.json"
    gmsh_mesh(gmsh, dim, p, half, path)
    etype, etags, _conn = M.cells(gmsh, dim)
    assert etype == M.element_type(gmsh, dim, p)

    same = M.scaled_jacobian(M.jacobian_dets(gmsh, etype, M.hocurve_sample_points(dim, p)))
    _ptags, plugin = M.plugin_min_scaled_jacobian(gmsh, dim)

    hocurve.ok("quality", path, "--report", rep)
    q = json.loads(rep.read_text())
    print(f"\n{dim}D p={p}: cells {q['cells']}: hocurve min Q3 {q['min_q3']:.6f} | gmsh at the same points "
          f"{same.min():.6f} | gmsh AnalyseMeshQuality {plugin.min():.6f} "
          f"(diff {q['min_q3'] - plugin.min():+.4f}); invalid: hocurve {q['invalid_elements']}, "
          f"gmsh {int((same <= 0).sum())} at the same points, {int((plugin <= 0).sum())} by the plugin")

    assert q["order"] == p and q["cells"] == len(etags)
    assert q["nodes"] == len(gmsh.model.mesh.getNodes()[0])
    assert q["min_q3"] == pytest.approx(same.min(), abs=1e-9)
    assert q["mean_q3"] == pytest.approx(same.mean(), abs=1e-9)
    assert same[q["worst_cell"]] == pytest.approx(same.min(), abs=1e-9)  # ties: symmetric cells
    assert q["invalid_elements"] == int((same <= 0).sum())
    if plugin.min() > 0:
        assert q["min_q3"] >= plugin.min() - 1e-9
        assert q["min_q3"] - plugin.min() <= 0.02
    if half == 1.0:
        assert q["invalid_elements"] >= 1 and q["min_q3"] <= 0
