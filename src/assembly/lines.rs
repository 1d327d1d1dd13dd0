//! Lines of cells through stretched layers, for the smoother of the
//! p-multigrid preconditioner.
//!
//! In a boundary layer the cells are flat: two of their facets are long
//! (parallel to the wall) and the others short, and the stiffness couples a
//! cell far more strongly to its neighbours across the long facets than
//! along the layer. Chaining each stretched cell to the neighbours across
//! its two largest facets gives lines of cells that run through the layers,
//! from the wall outwards (the element lines of Fidkowski, Oliver, Lu and
//! Darmofal's p-multigrid, 2005). The smoother then solves the nodes of a
//! line together ([`NodeGroups`]). Cells that are not
//! stretched belong to no line, so a mesh without stretched cells is
//! smoothed exactly as before.

use rustc_hash::FxHashMap as HashMap;

use super::DofMap;
use crate::mesh::HighOrderMesh;
use crate::sparse::NodeGroups;

/// A cell is stretched when its second largest facet is at least this many
/// times its smallest (edge lengths in 2D, face areas in 3D). A regular
/// triangle has 1, a right isosceles one 1.4, and a prism of a boundary layer
/// split into tetrahedra its aspect ratio or more.
pub const STRETCHED: f64 = 4.0;

/// The measure (length, area) of each facet of cell `c`, facet f opposite vertex f.
fn facet_measures(mesh: &HighOrderMesh, c: usize) -> [f64; 4] {
    let dim = mesh.dim();
    let v: Vec<[f64; 3]> = mesh.cell(c)[..=dim].iter().map(|&i| mesh.node(i)).collect();
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let mut out = [0.0; 4];
    for (f, m) in out.iter_mut().enumerate().take(dim + 1) {
        let others: Vec<[f64; 3]> = (0..=dim).filter(|&k| k != f).map(|k| v[k]).collect();
        *m = if dim == 2 {
            norm(sub(others[1], others[0]))
        } else {
            let (a, b) = (sub(others[1], others[0]), sub(others[2], others[0]));
            0.5 * norm([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
        };
    }
    out
}

/// A line started on a stretched cell goes on through cells whose second
/// largest facet is at least this many times their smallest.
pub const STRETCHED_ON: f64 = 2.0;

/// The two largest facets of cell `c` (largest first) and how stretched it
/// is (second largest over smallest), if that is at least [`STRETCHED_ON`].
fn strong_facets(mesh: &HighOrderMesh, c: usize) -> Option<([usize; 2], f64)> {
    let nf = mesh.dim() + 1;
    let m = facet_measures(mesh, c);
    let mut order: Vec<usize> = (0..nf).collect();
    order.sort_by(|&a, &b| m[b].total_cmp(&m[a]).then(a.cmp(&b)));
    let ratio = m[order[1]] / m[order[nf - 1]];
    (ratio >= STRETCHED_ON).then_some(([order[0], order[1]], ratio))
}

/// Lines of stretched cells, each in order along the line; every cell in
/// at most one line, lines of one cell dropped. Deterministic: cells are
/// taken as starts in index order.
pub fn cell_lines(mesh: &HighOrderMesh) -> Vec<Vec<usize>> {
    let dim = mesh.dim();
    let cells: Vec<Option<([usize; 2], f64)>> = (0..mesh.n_cells()).map(|c| strong_facets(mesh, c)).collect();
    if !cells.iter().flatten().any(|&(_, r)| r >= STRETCHED) {
        return Vec::new();
    }
    // Facet (sorted vertices) → (cell, local facet), for the neighbour across it.
    let key = |c: usize, f: usize| {
        let mut k = [usize::MAX; 3];
        for (slot, &v) in k.iter_mut().zip(mesh.cell(c)[..=dim].iter().enumerate().filter(|&(i, _)| i != f).map(|(_, v)| v)) {
            *slot = v;
        }
        k[..dim].sort_unstable();
        k
    };
    let mut facets: HashMap<[usize; 3], Vec<(usize, usize)>> = HashMap::default();
    for (c, s) in cells.iter().enumerate() {
        for &f in s.iter().flat_map(|(f, _)| f) {
            facets.entry(key(c, f)).or_default().push((c, f));
        }
    }
    let across = |c: usize, f: usize| -> Option<(usize, usize)> {
        facets.get(&key(c, f))?.iter().copied().find(|&(n, _)| n != c)
    };
    let mut taken = vec![false; mesh.n_cells()];
    let mut lines = Vec::new();
    for start in 0..mesh.n_cells() {
        let Some(([f0, f1], ratio)) = cells[start] else { continue };
        if taken[start] || ratio < STRETCHED {
            continue;
        }
        taken[start] = true;
        let mut walk = |mut c: usize, mut f: usize| {
            let mut out = Vec::new();
            // The neighbour across a strong facet of c that counts it among its own strong facets.
            while let Some((n, g)) = across(c, f).filter(|&(n, _)| !taken[n]) {
                taken[n] = true;
                out.push(n);
                let (s, _) = cells[n].expect("only strong facets are indexed");
                (c, f) = (n, if s[0] == g { s[1] } else { s[0] });
            }
            out
        };
        let mut line: Vec<usize> = walk(start, f1);
        line.reverse();
        line.push(start);
        line.extend(walk(start, f0));
        if line.len() > 1 {
            lines.push(line);
        }
    }
    lines
}

/// The nodes of each line of `lines` (cells of `mesh`, which has the same
/// cells as the mesh the lines were found on) as groups of the system's
/// nodal blocks of `dofs`: a node whose dofs are not all free (fixed, or
/// condensed) is left out, and a node in two lines stays in the first.
pub fn line_groups(mesh: &HighOrderMesh, dofs: &DofMap, lines: &[Vec<usize>]) -> NodeGroups {
    let dim = mesh.dim();
    let block = |v: usize| -> Option<u32> {
        let r0 = dofs.system_row(v * dim)?;
        (r0 % dim == 0 && (1..dim).all(|d| dofs.system_row(v * dim + d) == Some(r0 + d))).then_some((r0 / dim) as u32)
    };
    let lists: Vec<Vec<u32>> =
        lines.iter().map(|line| line.iter().flat_map(|&c| mesh.cell(c).iter().filter_map(|&v| block(v))).collect()).collect();
    NodeGroups::from_lists(&lists, dofs.n_system / dim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases;
    use crate::mesh::{validate_and_orient, LinearMesh, Topology};
    use crate::reference::{NodeSet, NodeSpacing};

    fn elevate(lin: &LinearMesh, p: usize) -> HighOrderMesh {
        let (lin, _) = validate_and_orient(lin).unwrap();
        let topo = Topology::new(&lin).unwrap();
        let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
        HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal).unwrap()
    }

    #[test]
    fn lines_run_through_the_layers_from_the_wall_outwards() {
        // 16 columns of 6 layers, each quad two triangles, all stretched.
        let mesh = elevate(&cases::circle_layers_2d(16, 6, 100.0, 1.3).mesh, 2);
        let lines = cell_lines(&mesh);
        assert_eq!(lines.len(), 16, "{lines:?}");
        let mut seen = vec![false; mesh.n_cells()];
        for line in &lines {
            assert_eq!(line.len(), 12, "{line:?}");
            for w in line.windows(2) {
                // Consecutive cells share a facet (two vertices) ...
                let shared = mesh.cell(w[0])[..3].iter().filter(|v| mesh.cell(w[1])[..3].contains(v)).count();
                assert_eq!(shared, 2, "{line:?}");
            }
            for &c in line {
                assert!(!std::mem::replace(&mut seen[c], true), "cell {c} in two lines");
            }
            // ... and the line goes from the wall (radius 1) outwards.
            let radius = |c: usize| {
                let x = (0..3).map(|i| mesh.node(mesh.cell(c)[i])).fold([0.0; 2], |a, p| [a[0] + p[0], a[1] + p[1]]);
                (x[0] * x[0] + x[1] * x[1]).sqrt() / 3.0
            };
            let r: Vec<f64> = line.iter().map(|&c| radius(c)).collect();
            assert!(r.windows(2).all(|w| w[0] < w[1]) || r.windows(2).all(|w| w[0] > w[1]), "{r:?}");
        }
        assert!(seen.iter().all(|&s| s), "every stretched cell is in a line");
    }

    #[test]
    fn a_mesh_without_stretched_cells_has_no_lines() {
        for mesh in [cases::sphere_in_box_3d(2, 3).mesh, cases::circle_layers_2d(32, 4, 1.0, 1.0).mesh] {
            assert!(cell_lines(&elevate(&mesh, 2)).is_empty());
        }
    }

    #[test]
    fn line_groups_take_each_free_node_once() {
        let mesh = elevate(&cases::circle_layers_2d(16, 6, 100.0, 1.3).mesh, 3);
        let lines = cell_lines(&mesh);
        for dofs in [DofMap::new(&mesh), DofMap::condensed(&mesh)] {
            let groups = line_groups(&mesh, &dofs, &lines);
            assert_eq!(groups.len(), lines.len());
            let mut nodes = groups.nodes.clone();
            nodes.sort_unstable();
            nodes.dedup();
            assert_eq!(nodes.len(), groups.nodes.len(), "a node in two groups");
            // Every free node of a cell in a line is in a group: here all cells are.
            assert_eq!(groups.nodes.len(), dofs.n_system / 2);
        }
    }
}
