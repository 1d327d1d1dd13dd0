//! Splitting cells that moving nodes cannot make valid.
//!
//! The Jacobian of a curved cell at a vertex depends only on the nodes of the
//! cell's edges through that vertex, and on a face only on the nodes of the
//! cell's faces meeting it there. When all of those are boundary nodes (a
//! cell with two or three faces on the boundary, or all its vertices on
//! it), the curved boundary alone decides the sign of det J there, and no
//! interior node can change it. Such a cell is split at its centroid into
//! d + 1 cells, each made of one of its faces and the centroid. The curved
//! map of every new cell is the old cell's map restricted to it (a
//! polynomial of the same order), so the mesh and its boundary are
//! unchanged. The new cells' edges and faces through the centroid are
//! interior, so every point of the old cell now has free nodes around it.

use crate::mesh::{HighOrderMesh, NodeConstraint};
use crate::reference::{LagrangeBasis, NodeSet, Tabulation};

/// Reference points closer than this are the same node.
const SAME_POINT: f64 = 1e-9;

/// Split each cell of `cells` (distinct) at its centroid (module docs).
/// Each cell's first new cell takes its index; the others are appended in
/// order. `straight` holds the straight-sided positions of the nodes and
/// grows with them. Returns, for each cell of the new mesh, the cell it
/// came from.
pub fn split_at_centroids(
    mesh: &mut HighOrderMesh,
    straight: &mut Vec<f64>,
    basis: &LagrangeBasis,
    cells: &[usize],
) -> Vec<usize> {
    let plan = SplitPlan::new(mesh, basis);
    let mut parent: Vec<usize> = (0..mesh.n_cells()).collect();
    for &c in cells {
        plan.split(mesh, straight, c, &mut parent);
    }
    parent
}

/// A node of a sub-cell: an old node of the cell, or a new node (shared
/// by the sub-cells, numbered in order of first appearance).
enum Source {
    Old(usize),
    New(usize),
}

/// How every cell of an order splits, in reference coordinates.
struct SplitPlan {
    dim: usize,
    npc: usize,
    /// Per sub-cell, the source of each of its nodes.
    sources: Vec<Vec<Source>>,
    /// The reference points of the new nodes.
    new_points: Vec<[f64; 3]>,
    /// The old nodes strictly inside the cell.
    interior: Vec<usize>,
    /// The basis at `new_points`.
    table: Tabulation,
}

impl SplitPlan {
    /// The plan for the cells of `mesh`, whose nodes are those of `basis`.
    fn new(mesh: &HighOrderMesh, basis: &LagrangeBasis) -> SplitPlan {
        let dim = mesh.dim();
        let nodes = basis.nodes();
        let npc = nodes.len();
        let nv = dim + 1;
        let sub_points = sub_cell_points(mesh, nodes);
        let (sources, new_points) = node_sources(&sub_points, nodes, dim);
        // Old nodes strictly inside the cell disappear with it: their numbers are reused.
        let interior: Vec<usize> = (0..npc).filter(|&b| nodes.multi[b][..nv].iter().all(|&m| m > 0)).collect();
        let table = basis.tabulate(&new_points);
        SplitPlan { dim, npc, sources, new_points, interior, table }
    }

    /// Split cell `c`: its first sub-cell takes its place, the others are appended (parents in `parent`).
    fn split(&self, mesh: &mut HighOrderMesh, straight: &mut Vec<f64>, c: usize, parent: &mut Vec<usize>) {
        let npc = self.npc;
        let old: Vec<usize> = mesh.cell(c).to_vec();
        // The old cell's maps at the new points, before any old node is reused.
        let (curved, flat) = (self.eval(&old, &mesh.coords), self.eval(&old, straight));
        let numbers = self.number_new_nodes(mesh, straight, &old, &curved, &flat);
        for (k, src) in self.sources.iter().enumerate() {
            let conn: Vec<usize> = src
                .iter()
                .map(|s| match *s {
                    Source::Old(b) => old[b],
                    Source::New(j) => numbers[j],
                })
                .collect();
            if k == 0 {
                mesh.cells[c * npc..(c + 1) * npc].copy_from_slice(&conn);
            } else {
                mesh.cells.extend(conn);
                parent.push(c);
            }
        }
    }

    /// The map of the cell with nodes `old` and positions `xs` at the new points.
    fn eval(&self, old: &[usize], xs: &[f64]) -> Vec<f64> {
        let dim = self.dim;
        self.table
            .values
            .chunks_exact(self.npc)
            .flat_map(|values| {
                (0..dim).map(move |d| values.iter().zip(old).map(|(v, &b)| v * xs[b * dim + d]).sum::<f64>())
            })
            .collect()
    }

    /// Number the new nodes of a cell (reusing its interior nodes') and place them at `curved` and `flat`.
    fn number_new_nodes(
        &self,
        mesh: &mut HighOrderMesh,
        straight: &mut Vec<f64>,
        old: &[usize],
        curved: &[f64],
        flat: &[f64],
    ) -> Vec<usize> {
        let dim = self.dim;
        let mut reuse = self.interior.iter().map(|&b| old[b]);
        (0..self.new_points.len())
            .map(|j| {
                let n = reuse.next().unwrap_or_else(|| {
                    mesh.constraint.push(NodeConstraint::Free);
                    mesh.coords.extend(std::iter::repeat_n(0.0, dim));
                    straight.extend(std::iter::repeat_n(0.0, dim));
                    mesh.constraint.len() - 1
                });
                mesh.coords[n * dim..(n + 1) * dim].copy_from_slice(&curved[j * dim..(j + 1) * dim]);
                straight[n * dim..(n + 1) * dim].copy_from_slice(&flat[j * dim..(j + 1) * dim]);
                n
            })
            .collect()
    }
}

/// The nodes of the sub-cells as reference points of the old cell.
fn sub_cell_points(mesh: &HighOrderMesh, nodes: &NodeSet) -> Vec<Vec<[f64; 3]>> {
    // Sub-cell k has the old vertices but k, and the centroid in slot k
    // (same orientation).
    let dim = mesh.dim();
    let npc = nodes.len();
    let nv = dim + 1;
    let vertices = mesh.simplex.vertex_coords();
    let mut centroid = [0.0; 3];
    for v in &vertices[..nv] {
        for d in 0..dim {
            centroid[d] += v[d] / nv as f64;
        }
    }
    (0..nv)
        .map(|k| {
            (0..npc)
                .map(|a| {
                    let lam = nodes.barycentric(a);
                    let mut x = [0.0; 3];
                    for (i, l) in lam[..nv].iter().enumerate() {
                        let w = if i == k { &centroid } else { &vertices[i] };
                        for d in 0..dim {
                            x[d] += l * w[d];
                        }
                    }
                    x
                })
                .collect()
        })
        .collect()
}

/// The source of each sub-cell node, and the reference points of the new nodes.
fn node_sources(sub_points: &[Vec<[f64; 3]>], nodes: &NodeSet, dim: usize) -> (Vec<Vec<Source>>, Vec<[f64; 3]>) {
    let mut new_points: Vec<[f64; 3]> = Vec::new();
    let sources: Vec<Vec<Source>> = sub_points
        .iter()
        .map(|pts| {
            pts.iter()
                .map(|x| {
                    let near = |y: &[f64; 3]| (0..dim).all(|d| (x[d] - y[d]).abs() < SAME_POINT);
                    if let Some(b) = nodes.coords.iter().position(near) {
                        return Source::Old(b);
                    }
                    let j = new_points.iter().position(near).unwrap_or_else(|| {
                        new_points.push(*x);
                        new_points.len() - 1
                    });
                    Source::New(j)
                })
                .collect()
        })
        .collect();
    (sources, new_points)
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use super::*;
    use crate::quadrature::simplex_rule;
    use crate::reference::{NodeSet, NodeSpacing, Simplex};

    /// A curved mesh of order `p`: a built-in case elevated, every node
    /// moved by a smooth field (so the cells are curved polynomials).
    fn curved(simplex: Simplex, p: usize) -> (HighOrderMesh, Vec<f64>, LagrangeBasis) {
        let case = match simplex {
            Simplex::Tri => crate::cases::annulus_2d(0.5, 1.0, 10, 2),
            Simplex::Tet => crate::cases::sphere_in_box_3d(2, 1),
        };
        let (linear, _) = crate::mesh::validate_and_orient(&case.mesh).unwrap();
        let topo = crate::mesh::Topology::new(&linear).unwrap();
        let nodes = NodeSet::new(simplex, p, NodeSpacing::Optimal);
        let mut mesh = HighOrderMesh::elevate(&linear, &topo, &nodes, NodeSpacing::Optimal).unwrap();
        let straight = mesh.coords.clone();
        let dim = mesh.dim();
        for x in mesh.coords.chunks_exact_mut(dim) {
            let (a, b) = (x[0], x[1]);
            x[0] += 0.03 * (3.0 * b).sin();
            x[1] += 0.03 * (2.0 * a).cos();
        }
        (mesh, straight, LagrangeBasis::new(&nodes))
    }

    /// ∫ det J over each cell (a rule exact for det J of order-p cells).
    fn volumes(mesh: &HighOrderMesh, basis: &LagrangeBasis) -> Vec<f64> {
        let dim = mesh.dim();
        let rule = simplex_rule(mesh.simplex, dim * (basis.order() - 1));
        let tab = basis.tabulate(&rule.points);
        (0..mesh.n_cells())
            .map(|c| {
                let cell = mesh.cell(c);
                (0..rule.weights.len())
                    .map(|q| {
                        let mut j = [[0.0; 3]; 3];
                        for (a, &n) in cell.iter().enumerate() {
                            for r in 0..dim {
                                for s in 0..dim {
                                    j[r][s] += mesh.coords[n * dim + r] * tab.grads[(q * cell.len() + a) * dim + s];
                                }
                            }
                        }
                        rule.weights[q] * crate::linalg::det(dim, &j)
                    })
                    .sum()
            })
            .collect()
    }

    /// The nodes of each face of each cell, as a sorted list: a conforming
    /// mesh has each face once (boundary) or twice (interior).
    fn faces(mesh: &HighOrderMesh, nodes: &NodeSet) -> HashMap<Vec<usize>, usize> {
        let nv = mesh.dim() + 1;
        let mut count = HashMap::new();
        for c in 0..mesh.n_cells() {
            for k in 0..nv {
                let mut f: Vec<usize> =
                    (0..nodes.len()).filter(|&a| nodes.multi[a][k] == 0).map(|a| mesh.cell(c)[a]).collect();
                f.sort_unstable();
                *count.entry(f).or_insert(0) += 1;
            }
        }
        count
    }

    #[test]
    fn a_split_keeps_the_curved_map_the_volume_and_conformity() {
        for (simplex, p) in [(Simplex::Tri, 2), (Simplex::Tri, 5), (Simplex::Tet, 2), (Simplex::Tet, 4)] {
            let (mut mesh, mut straight, basis) = curved(simplex, p);
            let before = mesh.clone();
            let vol_before = volumes(&mesh, &basis);
            let straight_vol_before = volumes(&HighOrderMesh { coords: straight.clone(), ..mesh.clone() }, &basis);
            let faces_before = faces(&mesh, basis.nodes());
            let chosen: Vec<usize> = (0..mesh.n_cells()).step_by(3).collect();
            let parent = split_at_centroids(&mut mesh, &mut straight, &basis, &chosen);
            let nv = mesh.dim() + 1;
            assert_eq!(mesh.n_cells(), before.n_cells() + chosen.len() * (nv - 1), "{simplex:?} p={p}");
            assert_eq!(parent.len(), mesh.n_cells());
            // Each old cell's volume is the sum of its pieces', curved and straight.
            let vol = volumes(&mesh, &basis);
            let straight_vol = volumes(&HighOrderMesh { coords: straight.clone(), ..mesh.clone() }, &basis);
            let mut sum = vec![0.0; before.n_cells()];
            let mut sum_straight = vec![0.0; before.n_cells()];
            for (c, &q) in parent.iter().enumerate() {
                sum[q] += vol[c];
                sum_straight[q] += straight_vol[c];
                assert!(vol[c] > 0.0 && straight_vol[c] > 0.0, "{simplex:?} p={p}: cell {c}");
            }
            for c in 0..before.n_cells() {
                assert!(
                    (sum[c] - vol_before[c]).abs() < 1e-12 * vol_before[c].abs().max(1e-3),
                    "{simplex:?} p={p} cell {c}"
                );
                assert!((sum_straight[c] - straight_vol_before[c]).abs() < 1e-12, "{simplex:?} p={p} cell {c}");
            }
            // Old nodes that are still used keep their position and constraint.
            let used: std::collections::HashSet<usize> = mesh.cells.iter().copied().collect();
            let dim = mesh.dim();
            for n in 0..before.n_nodes() {
                if used.contains(&n) && before.constraint[n] != NodeConstraint::Free {
                    assert_eq!(mesh.coords[n * dim..(n + 1) * dim], before.coords[n * dim..(n + 1) * dim]);
                    assert_eq!(mesh.constraint[n], before.constraint[n]);
                }
            }
            assert!(mesh.constraint[before.n_nodes()..].iter().all(|c| *c == NodeConstraint::Free));
            // Conforming: every face once or twice, and the boundary faces are the old ones.
            let after = faces(&mesh, basis.nodes());
            assert!(after.values().all(|&k| k <= 2), "{simplex:?} p={p}");
            let boundary = |f: &HashMap<Vec<usize>, usize>| {
                let mut b: Vec<Vec<usize>> = f.iter().filter(|(_, &k)| k == 1).map(|(f, _)| f.clone()).collect();
                b.sort();
                b
            };
            assert_eq!(boundary(&after), boundary(&faces_before), "{simplex:?} p={p}");
            // No node is orphaned: the numbers of the interior nodes were reused.
            assert_eq!(used.len(), mesh.n_nodes(), "{simplex:?} p={p}");
        }
    }
}
