"""The .vtu hocurve writes reads back in meshio and VTK with Lagrange cells in
VTK's node order: converted to gmsh's order (permutation taken from VTK's and
gmsh's own reference nodes) every cell matches the .msh of the same run."""
import json

import numpy as np
import pytest

import meshes as M

CASES = [(2, 2), (2, 4), (2, 5), (3, 2), (3, 3)]
MESHIO_TYPE = {2: "VTK_LAGRANGE_TRIANGLE", 3: "VTK_LAGRANGE_TETRAHEDRON"}
VTK_TYPE = {2: 69, 3: 71}


@pytest.mark.parametrize("dim,p", CASES, ids=[f"{d}d-p{p}" for d, p in CASES])
def test_vtu_read_back(gmsh, hocurve, tmp_path, dim, p):
    import meshio
    import vtk

    src = tmp_path / "linear.msh"
    if dim == 2:
        geometry = [f"{t}=circle:0,0,{M.RADIUS}" for t in M.square_with_hole(gmsh, 0.3)]
    else:
        geometry = [f"{M.box_with_sphere(gmsh, 0.3)}=sphere:0,0,0,{M.RADIUS}"]
    M.write_msh41(gmsh, src)
    r = hocurve.curve(src, p, geometry, tmp_path / "out.vtu", tmp_path / "r.json")
    hocurve.curve(src, p, geometry, tmp_path / "out.msh", tmp_path / "r_msh.json")

    m = meshio.read(tmp_path / "out.vtu")
    assert [c.type for c in m.cells] == [MESHIO_TYPE[dim]]
    conn = m.cells[0].data
    assert len(m.points) == r["nodes"] and len(conn) == r["cells"]
    npc = (p + 1) * (p + 2) // 2 if dim == 2 else (p + 1) * (p + 2) * (p + 3) // 6
    assert conn.shape[1] == npc
    assert set(m.cell_data) >= {"Q3", "Q1"}
    q3 = np.asarray(m.cell_data["Q3"][0])
    assert q3.min() == pytest.approx(r["min_q3"], abs=1e-12)

    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(tmp_path / "out.vtu"))
    reader.Update()
    ug = reader.GetOutput()
    assert ug.GetNumberOfPoints() == r["nodes"] and ug.GetNumberOfCells() == r["cells"]
    assert {ug.GetCellType(i) for i in range(ug.GetNumberOfCells())} == {VTK_TYPE[dim]}

    # Same geometry as the .msh of the same run, cell by cell in gmsh order.
    gmsh.clear()
    gmsh.open(str(tmp_path / "out.msh"))
    perm = M.vtk_to_gmsh_permutation(gmsh, dim, p)
    tags, x = M.node_coords(gmsh)
    pos = np.zeros(int(tags.max()) + 1, dtype=int)
    pos[tags.astype(int)] = np.arange(len(tags))
    _t, _e, gconn = M.cells(gmsh, dim)
    from_msh = x[pos[gconn.astype(int)]]
    from_vtu = np.asarray(m.points)[conn[:, perm]]
    assert from_vtu.shape == from_msh.shape
    np.testing.assert_allclose(from_vtu, from_msh, rtol=0, atol=1e-12)

    # VTK evaluates the cells it read as Lagrange cells: at interior reference
    # points they map where gmsh maps the .msh cells (VTK's and gmsh's
    # reference simplices coincide, vertex 0 at the origin).
    etype = M.element_type(gmsh, dim, p)
    ref = M.hocurve_rule_points(dim, 3)
    _j, _d, xg = gmsh.model.mesh.getJacobians(etype, list(ref.ravel()))
    xg = np.asarray(xg).reshape(len(gconn), len(ref), 3)
    worst = 0.0
    sub, w = vtk.reference(0), [0.0] * npc
    for c in range(ug.GetNumberOfCells()):
        cell = ug.GetCell(c)
        for k, pc in enumerate(ref):
            xv = [0.0, 0.0, 0.0]
            cell.EvaluateLocation(sub, list(pc), xv, w)
            worst = max(worst, float(np.abs(np.asarray(xv) - xg[c, k]).max()))
    print(f"\n{dim}D p={p}: max |x_VTK - x_gmsh| at {len(ref)} points per cell: {worst:.2e}")
    assert worst < 1e-12
