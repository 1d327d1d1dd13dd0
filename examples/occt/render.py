#!/usr/bin/env python3
"""Render a curved hocurve mesh (.vtu with VTK Lagrange cells) to a PNG, headless.

    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow \\
        .venv/bin/python examples/occt/render.py part-p4.vtu docs/occt-part-p4.png

The boundary surface is drawn from VTK's nonlinear subdivision of the
high-order faces (so the curvature shows), and every element edge on the
boundary as a curve evaluated through the cell's own Lagrange interpolation
(vtkCell.EvaluateLocation along the edge), not as a chord. Needs only the
`vtk` wheel (scripts/setup_python.sh); without a display it renders offscreen
through EGL (or OSMesa), so no X server is needed.

Options: --size W H, --subdivision N (levels of nonlinear subdivision, default
3), --samples N (points per curved edge, default 12), the camera
(--view DX DY DZ: direction to the camera, z up), --zoom.
"""
import argparse
import os
import sys

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
import vtk  # noqa: E402


def boundary_edges(grid, samples):
    """Polylines along the boundary edges of the cells, through their Lagrange interpolation."""
    ncell = grid.GetNumberOfCells()
    dim = 3 if grid.GetCellType(0) in (vtk.VTK_LAGRANGE_TETRAHEDRON, vtk.VTK_TETRA) else 2
    nv = dim + 1
    # Facets (3D: corner-vertex triples) bounding one cell.
    corners = []
    count = {}
    for c in range(ncell):
        ids = grid.GetCell(c).GetPointIds()
        v = [ids.GetId(i) for i in range(nv)]
        corners.append(v)
        for omit in range(nv):
            f = tuple(sorted(v[i] for i in range(nv) if i != omit))
            count[f] = count.get(f, 0) + 1
    # Boundary edges (a, b) -> (cell, local a, local b).
    edges = {}
    for c, v in enumerate(corners):
        for omit in range(nv):
            f = [i for i in range(nv) if i != omit]
            if count[tuple(sorted(v[i] for i in f))] != 1:
                continue
            for i in range(len(f)):
                for j in range(i + 1, len(f)):
                    key = tuple(sorted((v[f[i]], v[f[j]])))
                    edges.setdefault(key, (c, f[i], f[j]))
    # Reference coordinates of the corner vertices of VTK's simplices.
    ref = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    pts = vtk.vtkPoints()
    lines = vtk.vtkCellArray()
    weights = [0.0] * grid.GetMaxCellSize()
    x = [0.0, 0.0, 0.0]
    sub = vtk.reference(0)
    for c, i, j in edges.values():
        cell = grid.GetCell(c)
        lines.InsertNextCell(samples + 1)
        for k in range(samples + 1):
            t = k / samples
            pc = [(1 - t) * ref[i][d] + t * ref[j][d] for d in range(3)]
            cell.EvaluateLocation(sub, pc, x, weights)
            lines.InsertCellPoint(pts.InsertNextPoint(x))
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    poly.SetLines(lines)
    return poly, len(edges)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("vtu")
    ap.add_argument("png")
    ap.add_argument("--size", type=int, nargs=2, default=[1000, 560])
    ap.add_argument("--subdivision", type=int, default=3)
    ap.add_argument("--samples", type=int, default=12)
    ap.add_argument("--view", type=float, nargs=3, default=[0.8, -1.5, 1.3],
                    help="direction from the centre to the camera (z is up)")
    ap.add_argument("--zoom", type=float, default=1.25)
    a = ap.parse_args()

    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(a.vtu)
    reader.Update()
    grid = reader.GetOutput()
    if grid.GetNumberOfCells() == 0:
        sys.exit(f"render.py: no cells in {a.vtu}")

    surface = vtk.vtkDataSetSurfaceFilter()
    surface.SetInputData(grid)
    surface.SetNonlinearSubdivisionLevel(a.subdivision)
    normals = vtk.vtkPolyDataNormals()
    normals.SetInputConnection(surface.GetOutputPort())
    normals.SetFeatureAngle(35)
    normals.SplittingOn()
    smap = vtk.vtkPolyDataMapper()
    smap.SetInputConnection(normals.GetOutputPort())
    smap.ScalarVisibilityOff()
    smap.SetResolveCoincidentTopologyToPolygonOffset()
    smap.SetRelativeCoincidentTopologyPolygonOffsetParameters(1.5, 1.5)
    sact = vtk.vtkActor()
    sact.SetMapper(smap)
    prop = sact.GetProperty()
    prop.SetColor(0.72, 0.80, 0.90)
    prop.SetInterpolationToPhong()
    prop.SetSpecular(0.25)
    prop.SetSpecularPower(30)
    prop.SetAmbient(0.15)

    lines, n_edges = boundary_edges(grid, a.samples)
    lmap = vtk.vtkPolyDataMapper()
    lmap.SetInputData(lines)
    lact = vtk.vtkActor()
    lact.SetMapper(lmap)
    lact.GetProperty().SetColor(0.08, 0.10, 0.18)
    lact.GetProperty().SetLineWidth(1.2)
    lact.GetProperty().LightingOff()

    ren = vtk.vtkRenderer()
    ren.SetBackground(1, 1, 1)
    ren.AddActor(sact)
    ren.AddActor(lact)
    light = vtk.vtkLightKit()
    light.AddLightsToRenderer(ren)
    b = grid.GetBounds()
    centre = [(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2]
    cam = ren.GetActiveCamera()
    cam.SetFocalPoint(*centre)
    cam.SetPosition(*[centre[k] + a.view[k] for k in range(3)])
    cam.SetViewUp(0, 0, 1) if abs(b[5] - b[4]) > 0 else cam.SetViewUp(0, 1, 0)
    ren.ResetCamera()
    cam.Zoom(a.zoom)

    win = vtk.vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetMultiSamples(8)
    win.SetSize(*a.size)
    win.AddRenderer(ren)
    win.Render()

    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(win)
    grab.ReadFrontBufferOff()
    grab.Update()
    png = vtk.vtkPNGWriter()
    png.SetFileName(a.png)
    png.SetInputConnection(grab.GetOutputPort())
    png.SetCompressionLevel(9)
    png.Write()
    print(f"render.py: {grid.GetNumberOfCells()} cells, {n_edges} boundary edges -> {a.png}")


if __name__ == "__main__":
    main()
