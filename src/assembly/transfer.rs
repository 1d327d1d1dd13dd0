//! Transfer between the order-p space and the order-1 space on the linear
//! vertices, for the p-multigrid preconditioner of the solver.
//!
//! The order-1 space is nested in the order-p one, so interpolation is exact:
//! a fine node at barycentric coordinates λ(ξ_a) of its cell takes the value
//! Σ_i λ_i(ξ_a) u_{v_i} over the cell's vertices, per component. A node on an
//! edge or face has λ = 0 at the vertices off that entity, so its value does
//! not depend on the cell it is seen from.

use super::DofMap;
use crate::mesh::HighOrderMesh;
use crate::reference::NodeSet;
use crate::solver::{SparseRows, SymmetricCsc};

/// The order-1 mesh on the vertices of `mesh` (same simplices, vertex coordinates
/// and constraints).
pub fn vertex_mesh(mesh: &HighOrderMesh) -> HighOrderMesh {
    let dim = mesh.dim();
    let nv = dim + 1;
    let cells = (0..mesh.n_cells()).flat_map(|c| mesh.cell(c)[..nv].iter().copied()).collect();
    HighOrderMesh {
        simplex: mesh.simplex,
        order: 1,
        spacing: mesh.spacing,
        coords: mesh.coords[..mesh.n_vertices * dim].to_vec(),
        cells,
        n_vertices: mesh.n_vertices,
        constraint: mesh.constraint[..mesh.n_vertices].to_vec(),
    }
}

/// The prolongation P from the free vertex dofs to the free dofs of `dofs`
/// (rows in the numbering of `dofs`, columns in that of the vertex mesh's
/// [`DofMap`]), and the lower-triangle pattern of Pᵀ K P (vertex pairs that
/// share a cell). Prescribed dofs on either side are left out: P maps the
/// order-1 fields that vanish on the boundary.
pub fn vertex_prolongation(mesh: &HighOrderMesh, dofs: &DofMap) -> (SparseRows, SymmetricCsc) {
    let dim = mesh.dim();
    let coarse_mesh = vertex_mesh(mesh);
    let coarse = DofMap::new(&coarse_mesh);
    let coarse_pattern = coarse.pattern(&coarse_mesh);
    let nodes = NodeSet::new(mesh.simplex, mesh.order, mesh.spacing);
    let lambdas: Vec<[f64; 4]> = (0..nodes.len()).map(|a| nodes.barycentric(a)).collect();
    let mut rows: Vec<Vec<(u32, f64)>> = vec![Vec::new(); dofs.n_free];
    let mut done = vec![false; mesh.n_nodes()];
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        for (a, &n) in cell.iter().enumerate() {
            if done[n] || dofs.free[n * dim] == usize::MAX {
                continue;
            }
            done[n] = true;
            for d in 0..dim {
                let row = &mut rows[dofs.free[n * dim + d]];
                for (i, &v) in cell[..=dim].iter().enumerate() {
                    let (l, j) = (lambdas[a][i], coarse.free[v * dim + d]);
                    if l.abs() > 1e-14 && j != usize::MAX {
                        row.push((j as u32, l));
                    }
                }
                row.sort_unstable_by_key(|e| e.0);
            }
        }
    }
    (SparseRows::from_rows(coarse.n_free, &rows), coarse_pattern)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases;
    use crate::mesh::{validate_and_orient, Topology};
    use crate::reference::NodeSpacing;

    fn mesh3d(p: usize) -> HighOrderMesh {
        let case = cases::sphere_in_box_3d(2, 3);
        let (lin, _) = validate_and_orient(&case.mesh).unwrap();
        let topo = Topology::new(&lin).unwrap();
        let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
        HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal).unwrap()
    }

    #[test]
    fn prolongation_reproduces_affine_fields_at_free_nodes() {
        for p in [2, 4] {
            let mesh = mesh3d(p);
            let dofs = DofMap::new(&mesh);
            let (pm, _) = vertex_prolongation(&mesh, &dofs);
            let coarse_mesh = vertex_mesh(&mesh);
            let coarse = DofMap::new(&coarse_mesh);
            // An affine field that vanishes nowhere; the free vertices carry its values.
            let f = |x: [f64; 3], d: usize| 0.3 + (d as f64 + 1.0) * x[0] - 0.7 * x[1] + 0.2 * d as f64 * x[2];
            let mut uc = vec![0.0; coarse.n_free];
            for v in 0..mesh.n_vertices {
                for d in 0..3 {
                    if coarse.free[v * 3 + d] != usize::MAX {
                        uc[coarse.free[v * 3 + d]] = f(mesh.node(v), d);
                    }
                }
            }
            let mut uf = vec![0.0; dofs.n_free];
            pm.matvec_into(&uc, &mut uf);
            // Exact at every free node whose cell's vertices are all free, i.e. where
            // no prescribed vertex is left out of the interpolation.
            let mut checked = 0;
            for c in 0..mesh.n_cells() {
                let cell = mesh.cell(c);
                if cell[..4].iter().any(|&v| coarse.free[v * 3] == usize::MAX) {
                    continue;
                }
                for &n in cell {
                    for d in 0..3 {
                        let e = uf[dofs.free[n * 3 + d]] - f(mesh.node(n), d);
                        assert!(e.abs() < 1e-12, "p={p} node {n}: error {e:e}");
                        checked += 1;
                    }
                }
            }
            assert!(checked > 100, "{checked}");
        }
    }
}
