"""Geometry, meshes and reference-element helpers shared by the tests."""
import numpy as np

# Test geometries: a box [-L,L]^3 with a spherical cavity, a square [-1,1]^2
# with a circular hole. L = 0.8 with h = 0.3 gives ~1100 tets, none with all
# four vertices on the sphere (see test_gmsh_reads_our_msh.py for that case).
CENTER = (0.0, 0.0, 0.0)
RADIUS = 0.5


def box_with_sphere(gmsh, h, order=1, optimize=0, half=0.8):
    """Meshes the box [-half, half]^3 with a spherical cavity; returns the sphere surface tag."""
    gmsh.model.add("box_sphere")
    box = gmsh.model.occ.addBox(-half, -half, -half, 2 * half, 2 * half, 2 * half)
    ball = gmsh.model.occ.addSphere(*CENTER, RADIUS)
    gmsh.model.occ.cut([(3, box)], [(3, ball)])
    gmsh.model.occ.synchronize()
    tags = [t for d, t in gmsh.model.getEntities(2) if gmsh.model.getType(d, t) == "Sphere"]
    assert len(tags) == 1, tags
    _mesh(gmsh, 3, h, order, optimize)
    return tags[0]


def square_with_hole(gmsh, h, order=1, optimize=0):
    """Meshes the square with a circular hole; returns the tags of the circle's curves."""
    gmsh.model.add("square_hole")
    sq = gmsh.model.occ.addRectangle(-1, -1, 0, 2, 2)
    disk = gmsh.model.occ.addDisk(*CENTER, RADIUS, RADIUS)
    gmsh.model.occ.cut([(2, sq)], [(2, disk)])
    gmsh.model.occ.synchronize()
    tags = [t for d, t in gmsh.model.getEntities(1) if gmsh.model.getType(d, t) in ("Circle", "Ellipse")]
    assert tags, gmsh.model.getEntities(1)
    _mesh(gmsh, 2, h, order, optimize)
    return tags


def _mesh(gmsh, dim, h, order, optimize):
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0)
    gmsh.option.setNumber("Mesh.ElementOrder", order)
    gmsh.option.setNumber("Mesh.HighOrderOptimize", optimize)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.model.mesh.generate(dim)


def write_msh41(gmsh, path):
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(str(path))


def element_type(gmsh, dim, order):
    return gmsh.model.mesh.getElementType("Triangle" if dim == 2 else "Tetrahedron", order)


def cells(gmsh, dim):
    """(element type, element tags, node tags reshaped per element) of the one cell type."""
    types = list(gmsh.model.mesh.getElementTypes(dim))
    assert len(types) == 1, types
    t = types[0]
    etags, ntags = gmsh.model.mesh.getElementsByType(t)
    nn = gmsh.model.mesh.getElementProperties(t)[3]
    return t, np.asarray(etags), np.asarray(ntags).reshape(-1, nn)


def node_coords(gmsh):
    """{node tag: xyz} of every node of the current model."""
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    return np.asarray(tags), np.asarray(xyz).reshape(-1, 3)


def jacobian_dets(gmsh, etype, local_points):
    """det J at the given reference points (flat list), shape (elements, points)."""
    _j, det, _x = gmsh.model.mesh.getJacobians(etype, list(np.ravel(local_points)))
    npts = len(np.ravel(local_points)) // 3
    return np.asarray(det).reshape(-1, npts)


def sample_points(gmsh, etype, p):
    """Many reference points per element: gmsh's Gauss rule of degree 2p plus
    the element's own (equispaced) nodes, vertices included, plus the
    equispaced lattice of order 3p."""
    uvw, _w = gmsh.model.mesh.getIntegrationPoints(etype, f"Gauss{2 * p}")
    _name, dim, _o, _nn, nodes, _np = gmsh.model.mesh.getElementProperties(etype)
    nodes = np.asarray(nodes).reshape(-1, dim)
    lat = lattice(dim, 3 * p)
    pts = [np.asarray(uvw).reshape(-1, 3)]
    for a in (nodes, lat):
        pad = np.zeros((len(a), 3))
        pad[:, :dim] = a
        pts.append(pad)
    return np.vstack(pts)


def lattice(dim, n):
    """Equispaced points of order n on the reference simplex (vertex 0 at the origin)."""
    out = []
    if dim == 2:
        for j in range(n + 1):
            for i in range(n + 1 - j):
                out.append((i / n, j / n))
    else:
        for k in range(n + 1):
            for j in range(n + 1 - k):
                for i in range(n + 1 - j - k):
                    out.append((i / n, j / n, k / n))
    return np.asarray(out, dtype=float)


def plugin_min_scaled_jacobian(gmsh, dim):
    """gmsh's AnalyseMeshQuality plugin: per-element min J / max J (Bézier bounds)."""
    gmsh.plugin.setNumber("AnalyseMeshQuality", "JacobianDeterminant", 1)
    gmsh.plugin.setNumber("AnalyseMeshQuality", "IGEMeasure", 0)
    gmsh.plugin.setNumber("AnalyseMeshQuality", "ICNMeasure", 0)
    gmsh.plugin.setNumber("AnalyseMeshQuality", "CreateView", 1)
    gmsh.plugin.setNumber("AnalyseMeshQuality", "Recompute", 1)
    gmsh.plugin.setNumber("AnalyseMeshQuality", "DimensionOfElements", dim)
    before = set(gmsh.view.getTags())
    gmsh.plugin.run("AnalyseMeshQuality")
    new = [v for v in gmsh.view.getTags() if v not in before]
    assert len(new) == 1, new
    _dt, tags, data, _t, _nc = gmsh.view.getModelData(new[0], 0)
    gmsh.view.remove(new[0])
    return np.asarray(tags), np.asarray(data).ravel()


# ---------------------------------------------------------------------------
# hocurve's quadrature rule (src/quadrature/simplex_rules.rs), rebuilt here so
# that gmsh's Jacobians can be sampled at exactly hocurve's points.


def gauss_jacobi_nodes(n, alpha, beta):
    """Nodes of the n-point Gauss–Jacobi rule on [-1, 1] (Golub–Welsch)."""
    k = np.arange(n, dtype=float)
    ab = alpha + beta
    a = np.empty(n)
    for i in range(n):
        s = 2 * i + ab
        a[i] = (beta - alpha) / (ab + 2) if i == 0 else (beta**2 - alpha**2) / (s * (s + 2))
    b = np.empty(max(n - 1, 0))
    for i in range(1, n):
        s = 2 * i + ab
        b[i - 1] = np.sqrt(4 * i * (i + alpha) * (i + beta) * (i + ab) / (s * s * (s + 1) * (s - 1)))
    del k
    return np.sort(np.linalg.eigvalsh(np.diag(a) + np.diag(b, 1) + np.diag(b, -1)))


def hocurve_rule_points(dim, degree):
    """Points of hocurve's collapsed Gauss–Jacobi simplex rule exact to `degree`."""
    n = (degree + 2) // 2
    xa = gauss_jacobi_nodes(n, 0.0, 0.0)
    xb = gauss_jacobi_nodes(n, 1.0, 0.0)
    pts = []
    if dim == 2:
        for b in xb:
            for a in xa:
                pts.append((0.25 * (1 + a) * (1 - b), 0.5 * (1 + b), 0.0))
    else:
        xc = gauss_jacobi_nodes(n, 2.0, 0.0)
        for c in xc:
            for b in xb:
                for a in xa:
                    pts.append((0.125 * (1 + a) * (1 - b) * (1 - c), 0.25 * (1 + b) * (1 - c), 0.5 * (1 + c)))
    return np.asarray(pts)


def lattice_points(dim, order):
    """The equispaced lattice of `order` on the reference simplex (all multi-indices)."""
    pts = []
    for k in range(order + 1 if dim == 3 else 1):
        for j in range(order + 1 - k):
            for i in range(order + 1 - k - j):
                pts.append((i / order, j / order, k / order if dim == 3 else 0.0))
    return np.asarray(pts)


def hocurve_sample_points(dim, p):
    """hocurve's quality sample set: the degree-2p rule plus the order-2p lattice."""
    return np.vstack([hocurve_rule_points(dim, 2 * p), lattice_points(dim, 2 * p)])


def scaled_jacobian(det):
    """Per element: min J / max J, or min J / max |J| when J ≤ 0 somewhere (hocurve's Q3)."""
    mn = det.min(axis=1)
    mx = np.where(mn > 0, det.max(axis=1), np.abs(det).max(axis=1))
    return mn / mx


# ---------------------------------------------------------------------------
# VTK Lagrange ordering, from VTK itself.


def vtk_to_gmsh_permutation(gmsh, dim, order):
    """perm such that gmsh_nodes[i] = vtk_nodes[perm[i]] for one cell."""
    import vtk

    etype = element_type(gmsh, dim, order)
    _name, _d, _o, nn, g, _np = gmsh.model.mesh.getElementProperties(etype)
    g = np.asarray(g).reshape(-1, dim)
    cell = vtk.vtkLagrangeTriangle() if dim == 2 else vtk.vtkLagrangeTetra()
    cell.GetPointIds().SetNumberOfIds(nn)
    cell.GetPoints().SetNumberOfPoints(nn)
    for i in range(nn):
        cell.GetPointIds().SetId(i, i)
        cell.GetPoints().SetPoint(i, 0.0, 0.0, 0.0)
    cell.Initialize()
    v = np.asarray([cell.GetParametricCoords()[i] for i in range(3 * nn)]).reshape(-1, 3)[:, :dim]
    perm = []
    for x in g:
        d = np.abs(v - x).max(axis=1)
        j = int(np.argmin(d))
        assert d[j] < 1e-9, (x, d[j])
        perm.append(j)
    assert sorted(perm) == list(range(nn))
    return np.asarray(perm)


def cells_of_entity(gmsh, dim, tag):
    """(element type, element tags, node tags per element) of the linear elements on one entity."""
    types, etags, ntags = gmsh.model.mesh.getElements(dim, tag)
    assert len(types) == 1, types
    nn = gmsh.model.mesh.getElementProperties(types[0])[3]
    return types[0], np.asarray(etags[0]), np.asarray(ntags[0]).reshape(-1, nn)
