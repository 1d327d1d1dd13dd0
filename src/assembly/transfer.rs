//! Transfer between nested Lagrange spaces of orders q < p on the same cells,
//! for the p-multigrid preconditioner of the solver.
//!
//! The order-q space is nested in the order-p one, so interpolation is exact:
//! a fine node at reference point ξ_a of its cell takes the value
//! Σ_b φ^q_b(ξ_a) u_b over the cell's order-q nodes, per component (for q = 1,
//! φ^1_b = λ_b, the barycentric coordinates). A node on an edge or face gets
//! weight zero from the coarse nodes off that entity, so its value does not
//! depend on the cell it is seen from.
//!
//! The order-q mesh is numbered by entity: a coarse node is identified by its
//! cell vertices (global numbers) and its barycentric counts on them, so
//! neighbouring cells agree. It is free if the entity it lies on carries free
//! order-p nodes (interior entities), else fixed.

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::lines::line_groups;
use super::{DofMap, LinearElasticKernel, System};
use crate::material::LinearElastic;
use crate::mesh::{HighOrderMesh, NodeConstraint};
use crate::reference::{LagrangeBasis, NodeSet};
use crate::sparse::{NodeGroups, SparseRows, SymmetricCsc};

/// The orders of the p-multigrid hierarchy below `p`: the even orders below
/// p, every other one, then 1 (6 → 4 → 2 → 1, 5 → 4 → 2 → 1, 3 → 2 → 1).
///
/// Measured on the sphere cavity (PCG iterations, one increment): p = 3:
/// 25 with [1], 15 with [2, 1]; p = 5: 41 with [2, 1], 33 with [3, 1], 25 with
/// [4, 2, 1] (also the fastest); p = 6: 50 with [3, 1], 39 with [4, 2, 1],
/// 31 with [5, 3, 1] but 17% slower (the order-5 level is expensive).
pub fn coarse_orders(p: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut q = p;
    while q > 1 {
        q = if q <= 2 {
            1
        } else if q % 2 == 1 {
            q - 1
        } else {
            q - 2
        };
        out.push(q);
    }
    out
}

/// The order-`q` mesh (1 ≤ q < p) on the cells of `mesh`: numbering by
/// entity (vertices first, as their own numbers), straight positions from the
/// order-p geometry, constraint Free on interior entities and Fixed elsewhere.
pub fn coarse_mesh(mesh: &HighOrderMesh, q: usize) -> HighOrderMesh {
    let dim = mesh.dim();
    let fine = NodeSet::new(mesh.simplex, mesh.order, mesh.spacing);
    let nodes = NodeSet::new(mesh.simplex, q, mesh.spacing);
    let tab = LagrangeBasis::new(&fine).tabulate(&nodes.coords);
    let (npf, npq) = (fine.len(), nodes.len());
    // For each coarse local node, a fine local node on the same entity.
    let support = |m: &[usize; 4]| (0..=dim).map(|i| m[i] > 0).collect::<Vec<_>>();
    let same_entity: Vec<usize> = nodes
        .multi
        .iter()
        .map(|m| fine.multi.iter().position(|f| support(f) == support(m)).expect("q < p: every entity has nodes"))
        .collect();
    let mut ids: HashMap<[(usize, usize); 4], usize> = HashMap::default();
    let mut cells = Vec::with_capacity(mesh.n_cells() * npq);
    let mut coords = mesh.coords[..mesh.n_vertices * dim].to_vec();
    let mut constraint: Vec<NodeConstraint> = mesh.constraint[..mesh.n_vertices].to_vec();
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        for (b, m) in nodes.multi.iter().enumerate() {
            if b <= dim {
                cells.push(cell[b]);
                continue;
            }
            let mut key = [(usize::MAX, 0); 4];
            for i in 0..=dim {
                key[i] = if m[i] > 0 { (cell[i], m[i]) } else { (usize::MAX, 0) };
            }
            key.sort_unstable();
            let next = constraint.len();
            let id = *ids.entry(key).or_insert(next);
            if id == next {
                let free = mesh.constraint[cell[same_entity[b]]] == NodeConstraint::Free;
                constraint.push(if free { NodeConstraint::Free } else { NodeConstraint::Fixed });
                for d in 0..dim {
                    coords.push((0..npf).map(|a| tab.values[b * npf + a] * mesh.coords[cell[a] * dim + d]).sum());
                }
            }
            cells.push(id);
        }
    }
    HighOrderMesh {
        simplex: mesh.simplex,
        order: q,
        spacing: mesh.spacing,
        coords,
        cells,
        n_vertices: mesh.n_vertices,
        constraint,
    }
}

/// The prolongation from the free dofs of `coarse` (an order-q mesh from
/// [`coarse_mesh`], same cells) to the system dofs of `fine` (order > q), in
/// the numberings of their [`DofMap`]s. Prescribed dofs on either side are
/// left out: P maps the order-q fields that vanish on the boundary. Under
/// static condensation of `fine` its interior dofs are left out too: the
/// coarse operator is then the Galerkin product with the Schur complement,
/// i.e. the coarse fields extended into the cells at least energy.
pub fn prolongation(
    fine: &HighOrderMesh,
    fine_dofs: &DofMap,
    coarse: &HighOrderMesh,
    coarse_dofs: &DofMap,
) -> SparseRows {
    let dim = fine.dim();
    let fine_nodes = NodeSet::new(fine.simplex, fine.order, fine.spacing);
    let coarse_nodes = NodeSet::new(coarse.simplex, coarse.order, coarse.spacing);
    let tab = LagrangeBasis::new(&coarse_nodes).tabulate(&fine_nodes.coords);
    let nq = coarse_nodes.len();
    // Each fine node's first cell, and its place there.
    let mut owner = vec![(usize::MAX, 0); fine.n_nodes()];
    for c in 0..fine.n_cells() {
        for (a, &n) in fine.cell(c).iter().enumerate() {
            if owner[n].0 == usize::MAX {
                owner[n] = (c, a);
            }
        }
    }
    // The fine system's nodes in the order of their rows (a node's `dim`
    // rows are consecutive), their rows made in parallel.
    let mut by_row = vec![0; fine_dofs.n_system / dim];
    for n in 0..fine.n_nodes() {
        if let Some(r0) = fine_dofs.system_row(n * dim) {
            by_row[r0 / dim] = n;
        }
    }
    let rows: Vec<Vec<(u32, f64)>> = by_row
        .par_iter()
        .flat_map_iter(|&n| {
            let (c, a) = owner[n];
            let (ccell, weights) = (coarse.cell(c), &tab.values[a * nq..(a + 1) * nq]);
            (0..dim).map(move |d| {
                let mut row: Vec<(u32, f64)> = ccell
                    .iter()
                    .zip(weights)
                    .filter(|(_, w)| w.abs() > 1e-12)
                    .filter_map(|(&m, &w)| coarse_dofs.system_row(m * dim + d).map(|j| (j as u32, w)))
                    .collect();
                row.sort_unstable_by_key(|e| e.0);
                row
            })
        })
        .collect();
    SparseRows::from_rows(coarse_dofs.n_system, &rows)
}

/// A p-multigrid hierarchy ([`multigrid_levels`]).
pub struct MultigridLevels {
    /// Per coarse level, from the finest: the prolongation to the level
    /// above and the lower-triangle pattern of the level's operator.
    pub levels: Vec<(SparseRows, SymmetricCsc)>,
    /// The nodes of the cell lines on the fine level and on each coarse one.
    pub groups: Vec<NodeGroups>,
    /// The first coarse level's operator assembled on its own mesh (the
    /// values of its pattern), when asked for.
    pub first_values: Option<Vec<f64>>,
}

/// The p-multigrid hierarchy of `mesh` below its order ([`coarse_orders`]):
/// per coarse level, from the finest, the prolongation from that level to the
/// one above and the lower-triangle pattern of its operator; and the nodes
/// of the cell `lines` ([`super::cell_lines`]; none: `&[]`) on the fine
/// level and on each coarse level, for the smoother's line blocks.
///
/// With `material`, also the first coarse level's linear elastic stiffness
/// assembled on the coarse mesh (the fine mesh's geometry interpolated at
/// its nodes), which the solver takes instead of the Galerkin product PᵀAP
/// of the fine matrix. On the sphere and torus cavities at
/// p = 4 the PCG iterations of every increment are the same with either,
/// and assembling at p = 2 took 10 and 29 ms against 59 and 111 ms for
/// the product. None if a coarse cell has det J ≤ 0 somewhere (a curved
/// fine mesh whose coarse interpolant is inverted): the Galerkin product
/// then serves.
pub fn multigrid_levels(
    mesh: &HighOrderMesh,
    dofs: &DofMap,
    lines: &[Vec<usize>],
    material: Option<LinearElastic>,
) -> MultigridLevels {
    let mut out = Vec::new();
    let mut groups = vec![line_groups(mesh, dofs, lines)];
    let mut first_values = None;
    let mut above: Option<(HighOrderMesh, DofMap)> = None;
    for q in coarse_orders(mesh.order) {
        let cm = coarse_mesh(mesh, q);
        // A cell-interior (bubble) function of order q vanishes on the cell's
        // faces: on condensed levels above it prolongs to zero, so the coarse
        // level is condensed too.
        let cd = if dofs.is_condensed() { DofMap::condensed(&cm) } else { DofMap::new(&cm) };
        if cd.n_system == 0 {
            break; // no interior entity of this order: the level above is the coarsest
        }
        let p = match &above {
            None => prolongation(mesh, dofs, &cm, &cd),
            Some((am, ad)) => prolongation(am, ad, &cm, &cd),
        };
        groups.push(if q > 1 { line_groups(&cm, &cd, lines) } else { NodeGroups::default() });
        let (cd, pattern) = match material.filter(|_| above.is_none()) {
            Some(material) => {
                let (cd, pattern, values) = assembled(&cm, cd, material);
                first_values = values;
                (cd, pattern)
            }
            None => {
                let pattern = cd.pattern(&cm);
                (cd, pattern)
            }
        };
        out.push((p, pattern));
        above = Some((cm, cd));
    }
    MultigridLevels { levels: out, groups, first_values }
}

/// The linear elastic stiffness of `material` on `mesh` with its dofs
/// `dofs`: the dofs back, the pattern, and its values (None if a cell has
/// det J ≤ 0 somewhere).
fn assembled(mesh: &HighOrderMesh, dofs: DofMap, material: LinearElastic) -> (DofMap, SymmetricCsc, Option<Vec<f64>>) {
    let kernel = LinearElasticKernel::for_nodes(&NodeSet::new(mesh.simplex, mesh.order, mesh.spacing), material);
    let mut system = System::new(mesh, dofs);
    let prescribed = vec![0.0; mesh.coords.len()];
    let ok = system.assemble(mesh, &mesh.coords, &kernel, &prescribed, false).is_ok();
    let (dofs, pattern, values) = system.into_matrix();
    (dofs, pattern, ok.then_some(values))
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
    fn vertex_prolongation_reproduces_affine_fields_at_free_nodes() {
        for p in [2, 4] {
            let mesh = mesh3d(p);
            let dofs = DofMap::new(&mesh);
            let coarse_mesh = coarse_mesh(&mesh, 1);
            let coarse = DofMap::new(&coarse_mesh);
            let pm = prolongation(&mesh, &dofs, &coarse_mesh, &coarse);
            // An affine field that vanishes nowhere; the free vertices carry its values.
            let f = |x: [f64; 3], d: usize| 0.3 + (d as f64 + 1.0) * x[0] - 0.7 * x[1] + 0.2 * d as f64 * x[2];
            let mut uc = vec![0.0; coarse.n_free];
            for v in 0..mesh.n_vertices {
                for d in 0..3 {
                    if let Some(i) = coarse.free_index(v * 3 + d) {
                        uc[i] = f(mesh.node(v), d);
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
                if cell[..4].iter().any(|&v| coarse.free_index(v * 3).is_none()) {
                    continue;
                }
                for &n in cell {
                    for d in 0..3 {
                        let e = uf[dofs.free_index(n * 3 + d).unwrap()] - f(mesh.node(n), d);
                        assert!(e.abs() < 1e-12, "p={p} node {n}: error {e:e}");
                        checked += 1;
                    }
                }
            }
            assert!(checked > 100, "{checked}");
        }
    }

    /// On straight cells the order-2 space is nested in the order-4 one and
    /// both rules integrate their stiffness exactly, so the level assembled
    /// on the coarse mesh is the Galerkin product PᵀKP of the fine matrix.
    #[test]
    fn the_assembled_first_level_is_the_galerkin_product_on_straight_cells() {
        use crate::solver::pcg::SymmetricOperator;
        let mesh = mesh3d(4);
        let material = LinearElastic::try_from_young_poisson(1e5, 0.45).unwrap();
        let kernel = LinearElasticKernel::for_nodes(&NodeSet::new(mesh.simplex, 4, mesh.spacing), material);
        let mut fine = System::new(&mesh, DofMap::new(&mesh));
        fine.assemble(&mesh, &mesh.coords, &kernel, &vec![0.0; mesh.coords.len()], false).unwrap();
        let hierarchy = multigrid_levels(&mesh, fine.dofs(), &[], Some(material));
        let assembled = hierarchy.first_values.expect("straight cells assemble");
        let (p, coarse) = &hierarchy.levels[0];
        let op = SymmetricOperator::try_new(fine.pattern(), 3).unwrap();
        let galerkin = crate::solver::pmg::galerkin_product(op.with(fine.pattern(), fine.values()), p, &p.transpose(), coarse);
        let scale = galerkin.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (k, (x, y)) in assembled.iter().zip(&galerkin).enumerate() {
            assert!((x - y).abs() <= 1e-10 * scale, "entry {k}: {x} against {y}");
        }
        assert_eq!(assembled.len(), galerkin.len());
    }

    #[test]
    fn order_2_mesh_of_an_order_4_mesh_is_the_elevated_order_2_mesh() {
        let m4 = mesh3d(4);
        let m2 = mesh3d(2);
        let c2 = coarse_mesh(&m4, 2);
        assert_eq!(c2.n_nodes(), m2.n_nodes());
        let free = |m: &HighOrderMesh| m.constraint.iter().filter(|c| **c == NodeConstraint::Free).count();
        assert_eq!(free(&c2), free(&m2));
        for (x, y) in c2.coords.iter().zip(&m2.coords).take(m2.n_vertices * 3) {
            assert_eq!(x, y);
        }
    }

    #[test]
    fn quadratic_fields_are_reproduced_through_the_hierarchy() {
        // P_{4←2}: a quadratic field on the order-2 free nodes equals the field at
        // the order-4 nodes of cells whose order-2 nodes are all free.
        let mesh = mesh3d(4);
        let dofs = DofMap::new(&mesh);
        let levels = multigrid_levels(&mesh, &dofs, &[], None).levels;
        assert_eq!(levels.len(), 2);
        assert_eq!(coarse_orders(6), [4, 2, 1]);
        assert_eq!(coarse_orders(5), [4, 2, 1]);
        assert_eq!(coarse_orders(3), [2, 1]);
        assert_eq!(coarse_orders(2), [1]);
        let c2 = coarse_mesh(&mesh, 2);
        let d2 = DofMap::new(&c2);
        assert_eq!(levels[0].0.n_cols, d2.n_free);
        let f = |x: [f64; 3], d: usize| 1.0 + x[0] * x[1] - (d as f64) * x[2] * x[2] + 0.5 * x[0];
        let mut u2 = vec![0.0; d2.n_free];
        for n in 0..c2.n_nodes() {
            for d in 0..3 {
                if let Some(i) = d2.free_index(n * 3 + d) {
                    u2[i] = f(c2.node(n), d);
                }
            }
        }
        let mut u4 = vec![0.0; dofs.n_free];
        levels[0].0.matvec_into(&u2, &mut u4);
        let mut checked = 0;
        for c in 0..mesh.n_cells() {
            if c2.cell(c).iter().any(|&m| d2.free_index(m * 3).is_none()) {
                continue;
            }
            for &n in mesh.cell(c) {
                let e = u4[dofs.free_index(n * 3).unwrap()] - f(mesh.node(n), 0);
                assert!(e.abs() < 1e-10, "node {n}: {e:e}");
                checked += 1;
            }
        }
        assert!(checked > 0);
    }
}
