//! Patches: the cells around the bad ones whose free nodes the optimisation
//! moves.
//!
//! A patch is the set of cells within `layers` node-neighbour layers of some
//! bad cells; patches that share a node are merged, so two patches never
//! touch. A node moves only if it is free (an interior node, not on the
//! boundary) and every cell around it is in the patch, so the cells outside
//! a patch never change, and patches can be optimised independently (in
//! parallel, with the same result for any number of threads).

use crate::mesh::{HighOrderMesh, NodeConstraint};

/// The cells around every node, in compressed rows.
#[derive(Debug, Clone)]
pub struct NodeCells {
    offsets: Vec<usize>,
    cells: Vec<usize>,
}

impl NodeCells {
    pub fn new(mesh: &HighOrderMesh) -> NodeCells {
        let n = mesh.n_nodes();
        let mut offsets = vec![0usize; n + 1];
        for &v in &mesh.cells {
            offsets[v + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut cells = vec![0; mesh.cells.len()];
        let npc = mesh.nodes_per_cell();
        for (c, cell) in mesh.cells.chunks_exact(npc).enumerate() {
            for &v in cell {
                cells[fill[v]] = c;
                fill[v] += 1;
            }
        }
        NodeCells { offsets, cells }
    }

    /// The cells that have node `n`, in increasing order.
    pub fn of(&self, n: usize) -> &[usize] {
        &self.cells[self.offsets[n]..self.offsets[n + 1]]
    }
}

/// One patch: its cells (sorted), the interior nodes it moves (sorted), and
/// the boundary nodes that may slide on their entity (sorted: high-order
/// nodes on a curve or surface, not vertices).
#[derive(Debug, Clone, PartialEq)]
pub struct Patch {
    pub cells: Vec<usize>,
    pub free: Vec<usize>,
    pub sliding: Vec<usize>,
}

/// The patches around the cells `seeds`: each seed grown by `layers` layers
/// of cells that share a node with it, then merged into connected groups
/// (cells sharing a node). Deterministic: patches come sorted by their
/// first cell.
pub fn build_patches(mesh: &HighOrderMesh, adj: &NodeCells, seeds: &[usize], layers: usize) -> Vec<Patch> {
    let nc = mesh.n_cells();
    // Multi-source breadth-first growth.
    let mut in_set = vec![false; nc];
    let mut frontier: Vec<usize> = Vec::new();
    for &c in seeds {
        if !in_set[c] {
            in_set[c] = true;
            frontier.push(c);
        }
    }
    for _ in 0..layers {
        let mut next = Vec::new();
        for &c in &frontier {
            for &n in mesh.cell(c) {
                for &d in adj.of(n) {
                    if !in_set[d] {
                        in_set[d] = true;
                        next.push(d);
                    }
                }
            }
        }
        frontier = next;
    }
    // Connected components of the grown set (through shared nodes).
    let mut component = vec![usize::MAX; nc];
    let mut patches = Vec::new();
    for start in 0..nc {
        if !in_set[start] || component[start] != usize::MAX {
            continue;
        }
        let id = patches.len();
        component[start] = id;
        let mut stack = vec![start];
        let mut cells = Vec::new();
        while let Some(c) = stack.pop() {
            cells.push(c);
            for &n in mesh.cell(c) {
                for &d in adj.of(n) {
                    if in_set[d] && component[d] == usize::MAX {
                        component[d] = id;
                        stack.push(d);
                    }
                }
            }
        }
        cells.sort_unstable();
        let mut free: Vec<usize> = cells
            .iter()
            .flat_map(|&c| mesh.cell(c).iter().copied())
            .filter(|&n| mesh.constraint[n] == NodeConstraint::Free && adj.of(n).iter().all(|&d| component[d] == id))
            .collect();
        free.sort_unstable();
        free.dedup();
        let mut sliding: Vec<usize> = cells
            .iter()
            .flat_map(|&c| mesh.cell(c).iter().copied())
            .filter(|&n| {
                n >= mesh.n_vertices
                    && matches!(mesh.constraint[n], NodeConstraint::OnEntity { .. })
                    && adj.of(n).iter().all(|&d| component[d] == id)
            })
            .collect();
        sliding.sort_unstable();
        sliding.dedup();
        patches.push(Patch { cells, free, sliding });
    }
    patches
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases;

    #[test]
    fn patches_are_disjoint_and_move_only_free_nodes_whose_cells_are_all_inside() {
        let (linear, _) = crate::mesh::validate_and_orient(&cases::sphere_in_box_3d(3, 2).mesh).unwrap();
        let topo = crate::mesh::Topology::new(&linear).unwrap();
        let nodes = crate::reference::NodeSet::new(topo.simplex, 3, crate::reference::NodeSpacing::Optimal);
        let mesh = HighOrderMesh::elevate(&linear, &topo, &nodes, crate::reference::NodeSpacing::Optimal).unwrap();
        let adj = NodeCells::new(&mesh);
        let seeds: Vec<usize> = (0..mesh.n_cells()).step_by(97).collect();
        let patches = build_patches(&mesh, &adj, &seeds, 1);
        let mut owner = vec![usize::MAX; mesh.n_cells()];
        for (p, patch) in patches.iter().enumerate() {
            for &c in &patch.cells {
                assert_eq!(owner[c], usize::MAX, "cell {c} in two patches");
                owner[c] = p;
            }
        }
        for s in &seeds {
            assert_ne!(owner[*s], usize::MAX);
        }
        for (p, patch) in patches.iter().enumerate() {
            for &n in &patch.free {
                assert_eq!(mesh.constraint[n], NodeConstraint::Free);
                assert!(adj.of(n).iter().all(|&c| owner[c] == p));
            }
            // No node of a patch belongs to a cell of another patch.
            for &c in &patch.cells {
                for &n in mesh.cell(c) {
                    assert!(adj.of(n).iter().all(|&d| owner[d] == p || owner[d] == usize::MAX));
                }
            }
        }
    }
}
