//! Small structured meshes made in the tests themselves, and the assembled
//! system of a straight high-order mesh.
#![allow(dead_code)]

use hocurve::assembly::{assemble, Assembled, AssemblyPlan, DofMap, LinearElasticKernel};
use hocurve::cases::Case;
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
    pub dofs: DofMap,
    pub pattern: SymmetricCsc,
    pub system: Assembled,
}

pub fn straight_system(case: &Case, p: usize, condensed: bool, residual: bool) -> StraightSystem {
    let (lin, _) = validate_and_orient(&case.mesh).unwrap();
    let topo = Topology::new(&lin).unwrap();
    let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
    let mesh = HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal).unwrap();
    let dofs = if condensed { DofMap::condensed(&mesh) } else { DofMap::new(&mesh) };
    let pattern = dofs.pattern(&mesh);
    let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(topo.simplex, 2 * p));
    let kernel = LinearElasticKernel { cache, material: LinearElastic::try_from_young_poisson(1.0, 0.45).unwrap() };
    let prescribed: Vec<f64> = (0..mesh.coords.len()).map(|i| 0.01 * (i as f64 * 0.1).sin()).collect();
    let plan = AssemblyPlan::new(&mesh, &dofs, &pattern);
    let system = assemble(&mesh, &mesh.coords, &dofs, &pattern, &plan, &kernel, &prescribed, residual).unwrap();
    StraightSystem { mesh, dofs, pattern, system }
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
    let mut coords = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let mut x = [i as f64 / n as f64, j as f64 / n as f64, k as f64 / n as f64];
                if [i, j, k].iter().all(|&t| t > 0 && t < n) {
                    for (d, xd) in x.iter_mut().enumerate() {
                        *xd += 0.1 / n as f64 * ((i * 7 + j * 3 + k * 5 + d * 13) as f64).sin();
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
