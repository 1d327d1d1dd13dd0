//! Small structured meshes made in the tests themselves, and the assembled
//! system of a straight high-order mesh.
#![allow(dead_code)]

use hocurve::assembly::{DofMap, LinearElasticKernel, System};
use hocurve::cases::Case;
use hocurve::geometry::Shape;
use hocurve::mapping::ElementCache;
use hocurve::material::LinearElastic;
use hocurve::mesh::{validate_and_orient, HighOrderMesh, LinearMesh, Topology};
use hocurve::quadrature::simplex_rule;
use hocurve::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use hocurve::solver::SymmetricCsc;

/// The order-p mesh of `case` (straight), its dofs (cell interiors condensed
/// or not), pattern, and the ILE system (ν = 0.45, rule of degree 2p) for a
/// smooth prescribed field; with `residual`, assembled as for IIL/Newton.
pub struct StraightSystem {
    pub mesh: HighOrderMesh,
    pub system: System,
}

impl StraightSystem {
    pub fn dofs(&self) -> &DofMap {
        self.system.dofs()
    }

    pub fn pattern(&self) -> &SymmetricCsc {
        self.system.pattern()
    }
}

pub fn straight_system(case: &Case, p: usize, condensed: bool, residual: bool) -> StraightSystem {
    let (lin, _) = validate_and_orient(&case.mesh).unwrap();
    let topo = Topology::new(&lin).unwrap();
    let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
    let mesh = HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal).unwrap();
    let dofs = if condensed { DofMap::condensed(&mesh) } else { DofMap::new(&mesh) };
    let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(topo.simplex, 2 * p));
    let kernel = LinearElasticKernel { cache, material: LinearElastic::try_from_young_poisson(1.0, 0.45).unwrap() };
    let prescribed: Vec<f64> = (0..mesh.coords.len()).map(|i| 0.01 * (i as f64 * 0.1).sin()).collect();
    let mut system = System::new(&mesh, dofs);
    system.assemble(&mesh, &mesh.coords, &kernel, &prescribed, residual).unwrap();
    StraightSystem { mesh, system }
}

/// Unit square split into 2n² triangles, interior vertices jittered
/// deterministically so the mesh is not trivially structured.
pub fn square_mesh(n: usize) -> LinearMesh {
    let mut coords = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (mut x, mut y) = (i as f64 / n as f64, j as f64 / n as f64);
            if i > 0 && i < n && j > 0 && j < n {
                x += 0.15 / n as f64 * ((i * 7 + j * 3) as f64).sin();
                y += 0.15 / n as f64 * ((i * 5 + j * 11) as f64).cos();
            }
            coords.extend_from_slice(&[x, y]);
        }
    }
    let v = |i: usize, j: usize| j * (n + 1) + i;
    let mut cells = Vec::new();
    for j in 0..n {
        for i in 0..n {
            cells.extend_from_slice(&[v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            cells.extend_from_slice(&[v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    LinearMesh { dim: 2, coords, cells, ..Default::default() }
}

/// Unit cube split into 6n³ tetrahedra (Kuhn subdivision), interior vertices jittered.
pub fn cube_mesh(n: usize) -> LinearMesh {
    kuhn_cube(n, 0.1)
}

/// Unit cube split into 6n³ tetrahedra (Kuhn subdivision), interior vertices
/// moved by up to `jitter`/n (0: the regular grid).
pub fn kuhn_cube(n: usize, jitter: f64) -> LinearMesh {
    let mut coords = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let mut x = [i as f64 / n as f64, j as f64 / n as f64, k as f64 / n as f64];
                if [i, j, k].iter().all(|&t| t > 0 && t < n) {
                    for (d, xd) in x.iter_mut().enumerate() {
                        *xd += jitter / n as f64 * ((i * 7 + j * 3 + k * 5 + d * 13) as f64).sin();
                    }
                }
                coords.extend_from_slice(&x);
            }
        }
    }
    let v = |i: usize, j: usize, k: usize| (k * (n + 1) + j) * (n + 1) + i;
    let mut cells = Vec::new();
    // The six tets of the Kuhn subdivision share the main diagonal 0 → 7.
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for p in perms {
                    let mut c = [i, j, k];
                    let mut tet = vec![v(c[0], c[1], c[2])];
                    for &axis in &p {
                        c[axis] += 1;
                        tet.push(v(c[0], c[1], c[2]));
                    }
                    cells.extend_from_slice(&tet);
                }
            }
        }
    }
    LinearMesh { dim: 3, coords, cells, ..Default::default() }
}

/// Quality 6√2·V / l_max³ of tetrahedron `c` (1 for the regular one; signed).
pub fn tet_quality(mesh: &LinearMesh, c: usize) -> f64 {
    let p: Vec<[f64; 3]> = mesh.cells[4 * c..4 * c + 4].iter().map(|&v| mesh.vertex(v)).collect();
    let e = |a: usize| [p[a][0] - p[0][0], p[a][1] - p[0][1], p[a][2] - p[0][2]];
    let (a, b, d) = (e(1), e(2), e(3));
    let det =
        a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0]) + a[2] * (b[0] * d[1] - b[1] * d[0]);
    let mut l: f64 = 0.0;
    for i in 0..4 {
        for j in i + 1..4 {
            l = l.max((0..3).map(|k| (p[i][k] - p[j][k]).powi(2)).sum::<f64>().sqrt());
        }
    }
    2f64.sqrt() * det / l.powi(3)
}

/// The regular [`kuhn_cube`] with `count` interior vertices (all three grid
/// indices even, so their stars are disjoint) each moved along a fixed
/// direction until the worst cell around it has quality `quality`
/// ([`tet_quality`]): `count` nearly degenerate cells, same connectivity as
/// `kuhn_cube(n, 0.0)`.
pub fn cube_with_slivers(n: usize, count: usize, quality: f64) -> LinearMesh {
    let mut mesh = kuhn_cube(n, 0.0);
    let nv = mesh.n_vertices();
    let mut stars = vec![Vec::new(); nv];
    for c in 0..mesh.n_cells() {
        for &v in &mesh.cells[4 * c..4 * c + 4] {
            stars[v].push(c);
        }
    }
    let mut moved = 0;
    for v in 0..nv {
        let ijk = [v % (n + 1), (v / (n + 1)) % (n + 1), v / (n + 1) / (n + 1)];
        if moved == count || ijk.iter().any(|&t| t == 0 || t == n || t % 2 == 1) {
            continue;
        }
        let dir = [0.3 + 0.1 * (moved as f64).sin(), -0.7, 0.5];
        let x0 = mesh.vertex(v);
        let sign: Vec<f64> = stars[v].iter().map(|&c| tet_quality(&mesh, c).signum()).collect();
        let worst = |mesh: &mut LinearMesh, t: f64| {
            for d in 0..3 {
                mesh.coords[3 * v + d] = x0[d] + t * dir[d];
            }
            stars[v].iter().zip(&sign).map(|(&c, s)| s * tet_quality(mesh, c)).fold(f64::INFINITY, f64::min)
        };
        // The worst quality falls from its start to 0 (then negative) along the ray: bisect.
        let (mut lo, mut hi) = (0.0, 1.0 / n as f64);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if worst(&mut mesh, mid) > quality {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let q = worst(&mut mesh, lo);
        assert!((q - quality).abs() <= 1e-3 * quality, "vertex {v}: quality {q:e}");
        moved += 1;
    }
    assert_eq!(moved, count, "not enough interior vertices");
    mesh
}

/// The user data of [`onto_counted`]: a shape, and how many points the
/// projector was asked for.
pub struct CountedShape {
    pub shape: Shape,
    pub points: usize,
}

impl CountedShape {
    pub fn new(shape: Shape) -> CountedShape {
        CountedShape { shape, points: 0 }
    }
}

/// A C projector onto the [`CountedShape`] that `user` points to (3D
/// points), counting them.
pub unsafe extern "C" fn onto_counted(
    user: *mut std::ffi::c_void,
    _: std::ffi::c_int,
    _: std::ffi::c_int,
    n: usize,
    points: *const f64,
    out: *mut f64,
) -> std::ffi::c_int {
    let c = &mut *(user as *mut CountedShape);
    let (p, o) = (std::slice::from_raw_parts(points, 3 * n), std::slice::from_raw_parts_mut(out, 3 * n));
    for (x, y) in p.chunks(3).zip(o.chunks_mut(3)) {
        y.copy_from_slice(&c.shape.closest_point([x[0], x[1], x[2]]));
    }
    c.points += n;
    0
}

/// A C ABI handle on `m` (3D, boundary tagged) projecting onto `shape`
/// (which must outlive it), at order `p`.
pub unsafe fn c_handle(m: &LinearMesh, shape: &mut CountedShape, p: std::ffi::c_int) -> *mut hocurve::ffi::HocMesh {
    use hocurve::ffi::*;
    let cells: Vec<i64> = m.cells.iter().map(|&v| v as i64).collect();
    let facets: Vec<i64> = m.facets.iter().map(|&v| v as i64).collect();
    let mut h = std::ptr::null_mut();
    assert_eq!(hoc_mesh_create(3, m.n_vertices(), m.coords.as_ptr(), m.n_cells(), cells.as_ptr(), &mut h), HOC_OK);
    assert_eq!(hoc_mesh_set_boundary(h, m.n_facets(), facets.as_ptr(), m.facet_tags.as_ptr()), HOC_OK);
    let user = shape as *mut CountedShape as *mut std::ffi::c_void;
    assert_eq!(hoc_mesh_set_projector(h, Some(onto_counted), user), HOC_OK);
    assert_eq!(hoc_mesh_set_order(h, p, HOC_SPACING_OPTIMAL), HOC_OK);
    h
}
