#!/usr/bin/env python3
"""Open hocurve's .msh and .vtu output with gmsh and VTK and check the cells.

    cargo run --example write_sample -- OUT_DIR 3 6 10
    python3 scripts/check_written_files.py OUT_DIR

For every OUT_DIR/*.msh: gmsh must load it, and every node of every element
must sit at the affine image of gmsh's reference node (the sample cells are
straight), and gmsh's Jacobian determinants must be positive and constant per
element (up to round-off: 1e-6 relative, since order 10 amplifies it to ~1e-8). For every OUT_DIR/*.vtu: VTK must read it, the cells must be Lagrange
triangles/tetrahedra whose interpolated geometry is the affine map of their
vertices, and the point field "x" must equal the points. meshio is tried too if
installed. Exits non-zero on any failure.
"""
import glob
import os
import sys

import numpy as np


def check_msh(path):
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.open(path)
        node_tags, xyz, _ = gmsh.model.mesh.getNodes()
        xyz = xyz.reshape(-1, 3)
        pos = {int(t): i for i, t in enumerate(node_tags)}
        types, elem_tags, elem_nodes = gmsh.model.mesh.getElements()
        n_elems = 0
        for t, et, en in zip(types, elem_tags, elem_nodes):
            name, dim, order, nn, ref, _ = gmsh.model.mesh.getElementProperties(t)
            ref = np.asarray(ref).reshape(nn, dim)
            en = np.asarray(en).reshape(-1, nn)
            for cell in en:
                x = xyz[[pos[int(v)] for v in cell]]
                verts = x[: dim + 1]
                lam = np.column_stack([1 - ref.sum(axis=1), ref])
                err = np.abs(lam @ verts - x).max()
                assert err < 1e-12, f"{path}: {name} node positions off by {err}"
            n_elems += len(en)
            ip, _w = gmsh.model.mesh.getIntegrationPoints(t, f"Gauss{2 * order}")
            _jac, det, _pts = gmsh.model.mesh.getJacobians(t, ip)
            det = np.asarray(det).reshape(len(en), -1)
            assert (det > 0).all(), f"{path}: non-positive Jacobian"
            spread = (det.max(axis=1) - det.min(axis=1)).max() / det.max()
            assert spread < 1e-6, f"{path}: Jacobian not constant on straight cells ({spread})"
        print(f"gmsh  {os.path.basename(path)}: {len(node_tags)} nodes, {n_elems} elements, "
              f"types {list(types)}, Jacobians positive and constant")
    finally:
        gmsh.finalize()


def check_vtu(path):
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    grid = reader.GetOutput()
    n, ne = grid.GetNumberOfPoints(), grid.GetNumberOfCells()
    assert n > 0 and ne > 0, f"{path}: VTK read {n} points, {ne} cells"
    pts = vtk_to_numpy(grid.GetPoints().GetData())
    x = vtk_to_numpy(grid.GetPointData().GetArray("x"))
    d = x.shape[1] if x.ndim == 2 else 1
    assert np.allclose(x[:, :3], pts[:, : x.shape[1]]), f"{path}: point field 'x' != points"
    ids = vtk_to_numpy(grid.GetCellData().GetArray("cell_id"))
    assert (ids == np.arange(ne)).all(), f"{path}: cell_id"
    rng = np.random.default_rng(0)
    for c in range(ne):
        cell = grid.GetCell(c)
        ct = cell.GetCellType()
        assert ct in (69, 71), f"{path}: cell type {ct}"
        dim = 2 if ct == 69 else 3
        verts = np.array([cell.GetPoints().GetPoint(i) for i in range(dim + 1)])
        for _ in range(20):
            xi = rng.dirichlet(np.ones(dim + 1))
            pc = list(xi[1:]) + [0.0] * (3 - dim)
            out = [0.0, 0.0, 0.0]
            w = [0.0] * cell.GetNumberOfPoints()
            cell.EvaluateLocation(vtk.reference(0), pc, out, w)
            err = np.abs(np.array(out) - xi @ verts).max()
            assert err < 1e-10, f"{path}: cell {c} geometry off by {err}"
    print(f"vtk   {os.path.basename(path)}: {n} points, {ne} cells of type "
          f"{grid.GetCellType(0)}, geometry affine as expected")
    try:
        import meshio
    except ImportError:
        return
    m = meshio.read(path)
    print(f"meshio {os.path.basename(path)}: {len(m.points)} points, "
          f"{[(b.type, len(b.data)) for b in m.cells]}")


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "target/sample"
    msh = sorted(glob.glob(os.path.join(out_dir, "*.msh")))
    vtu = sorted(glob.glob(os.path.join(out_dir, "*.vtu")))
    if not msh or not vtu:
        sys.exit(f"no .msh/.vtu files in {out_dir}")
    for p in msh:
        check_msh(p)
    for p in vtu:
        check_vtu(p)
    print("all files OK")


if __name__ == "__main__":
    main()
