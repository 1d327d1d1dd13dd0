//! Topological repair of the linear mesh before curving: cells that cannot
//! stay valid once curved with their vertices fixed are flipped away.
//!
//! Two steps, each optional ([`crate::curve::CurveOptions`]):
//!
//! 1. [`caps`]: boundary caps (tets with two faces on one smooth surface)
//!    are removed, which flips their surface edge: purely topological.
//! 2. [`repair`]: given how far the curved boundary bulges over each boundary
//!    facet ([`bulge`], measured by projecting a few points of each facet),
//!    the *bad* cells ([`detect`]: all vertices on one surface that bulges
//!    into the domain, or a boundary facet bulging past half the height of
//!    the opposite vertex) are removed by local flips ([`flips`]: 2-3, 3-2
//!    and edge removal in 3D, edge flips in 2D). For each bad cell, the valid
//!    flip that removes it with the best smallest quality of its new cells
//!    (a quality that counts the bulge, [`detect`]) is applied if that beats
//!    the smallest quality of the cells it replaces; passes repeat until no
//!    cell is bad or no flip improves (at most [`MAX_PASSES`]). A bad cell no
//!    flip improves is left as it is. Boundary facets, vertices and
//!    orientations are kept; every accepted flip strictly raises the sorted
//!    vector of qualities, so no configuration comes back.
//!
//! The cells of the result are the cells of the input that no flip touched,
//! in their order, then the new cells. Each maps to an input cell (see
//! [`Repaired::input_cell`]).

pub mod bulge;
pub mod caps;
pub mod detect;
pub mod flips;
mod geom;
#[cfg(test)]
mod tests;

use crate::mesh::LinearMesh;
pub use bulge::{bulge_samples, facet_bulges, BulgeSamples};
pub use caps::remove_boundary_caps;
pub use detect::{bad_cells, Assessment, Criteria, BULGE_FRACTION};
pub use flips::FlipKind;
use flips::Work;
use geom::barycentric;

/// Passes over the bad cells at most.
pub const MAX_PASSES: usize = 20;

/// What [`repair`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RepairSummary {
    /// Bad cells of the mesh given ([`detect`]).
    pub bad_cells: usize,
    /// Of them, cells with all vertices on one surface bulging into the domain.
    pub surface_cells: usize,
    /// Of them, cells with a boundary facet bulging past [`BULGE_FRACTION`] of their height.
    pub bulge_cells: usize,
    /// 2-3 flips (3D).
    pub flips_23: usize,
    /// 3-2 flips (3D).
    pub flips_32: usize,
    /// Removals of an edge with four or more tets around it (3D).
    pub edge_removals: usize,
    /// Edge flips (2D).
    pub flips_22: usize,
    /// Cells of the mesh given that are not in the result.
    pub cells_removed: usize,
    /// Cells of the result that are not in the mesh given.
    pub cells_added: usize,
    /// Bad cells in the result: no flip improved them (left to the curving).
    pub bad_cells_left: usize,
}

impl RepairSummary {
    /// All flips.
    pub fn flips(&self) -> usize {
        self.flips_23 + self.flips_32 + self.edge_removals + self.flips_22
    }
}

/// The repaired mesh.
#[derive(Debug, Clone)]
pub struct Repaired {
    pub mesh: LinearMesh,
    /// For each cell of `mesh`, a cell of the mesh given: itself for a cell no
    /// flip touched; for a new cell, the cell of the mesh given that contains
    /// its centroid (flips keep the region the cells cover, so there is one;
    /// on a tie, the one in which the centroid's smallest barycentric
    /// coordinate is largest).
    pub input_cell: Vec<usize>,
    pub summary: RepairSummary,
}

/// Flip the bad cells of `mesh` away (module docs). `mesh` is validated and
/// positively oriented (see [`crate::mesh::validate_and_orient`]); `bulge`
/// has one value per facet ([`facet_bulges`]).
pub fn repair(mesh: &LinearMesh, bulge: &[f64]) -> Repaired {
    let n = mesh.n_cells();
    let identity = || Repaired { mesh: mesh.clone(), input_cell: (0..n).collect(), summary: RepairSummary::default() };
    if !(mesh.dim == 2 || mesh.dim == 3) || bulge.len() != mesh.n_facets() {
        return identity();
    }
    let crit = Criteria::new(mesh, bulge);
    let mut w = Work::new(mesh, &crit);
    let mut summary = RepairSummary::default();
    for a in w.assessment.iter().filter(|a| a.is_bad()) {
        summary.bad_cells += 1;
        summary.surface_cells += a.surface as usize;
        summary.bulge_cells += a.bulge as usize;
    }
    if summary.bad_cells == 0 {
        return Repaired { summary, ..identity() };
    }
    for _ in 0..MAX_PASSES {
        let bad: Vec<usize> = (0..w.cells.len()).filter(|&c| w.alive[c] && w.assessment[c].is_bad()).collect();
        let mut changed = false;
        for c in bad {
            if !w.alive[c] || !w.assessment[c].is_bad() {
                continue;
            }
            let best = w
                .candidates(c)
                .into_iter()
                .filter(|f| {
                    let old = f.remove.iter().map(|&r| w.assessment[r].quality).fold(f64::INFINITY, f64::min);
                    f.min_quality > old + 1e-12
                })
                .max_by(|x, y| x.min_quality.total_cmp(&y.min_quality));
            let Some(f) = best else { continue };
            match f.kind {
                FlipKind::TwoThree => summary.flips_23 += 1,
                FlipKind::ThreeTwo => summary.flips_32 += 1,
                FlipKind::EdgeRemoval => summary.edge_removals += 1,
                FlipKind::TwoTwo => summary.flips_22 += 1,
            }
            w.apply(&f);
            changed = true;
        }
        if !changed {
            break;
        }
    }
    let d = mesh.dim;
    let mut out = mesh.clone();
    out.cells.clear();
    let mut input_cell = Vec::new();
    let live = |range: std::ops::Range<usize>| range.filter(|&c| w.alive[c]).collect::<Vec<_>>();
    for c in live(0..n) {
        out.cells.extend_from_slice(&w.cells[c][..=d]);
        input_cell.push(c);
    }
    for c in live(n..w.cells.len()) {
        out.cells.extend_from_slice(&w.cells[c][..=d]);
        input_cell.push(locate(mesh, &w.cells[c][..=d], &w.origin[c]));
        summary.cells_added += 1;
        summary.bad_cells_left += w.assessment[c].is_bad() as usize;
    }
    summary.cells_removed = (0..n).filter(|&c| !w.alive[c]).count();
    summary.bad_cells_left += (0..n).filter(|&c| w.alive[c] && w.assessment[c].is_bad()).count();
    Repaired { mesh: out, input_cell, summary }
}

/// The cell among `candidates` (cells of `mesh`) that contains the centroid of `cell`.
fn locate(mesh: &LinearMesh, cell: &[usize], candidates: &[usize]) -> usize {
    let d = mesh.dim;
    let mut g = [0.0; 3];
    for &v in cell {
        let x = mesh.vertex(v);
        for k in 0..3 {
            g[k] += x[k] / (d + 1) as f64;
        }
    }
    let score = |c: usize| {
        let x: Vec<[f64; 3]> = mesh.cells[c * (d + 1)..(c + 1) * (d + 1)].iter().map(|&v| mesh.vertex(v)).collect();
        barycentric(d, &x, g)[..=d].iter().copied().fold(f64::INFINITY, f64::min)
    };
    *candidates.iter().max_by(|&&a, &&b| score(a).total_cmp(&score(b))).expect("a new cell replaces some cells")
}
