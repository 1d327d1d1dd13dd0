//! Topological repair of the linear mesh before curving: cells that cannot
//! stay valid once curved with their vertices fixed are flipped away or split.
//!
//! Three steps ([`crate::curve::CurveOptions`]: the first with
//! `remove_caps`, the others with `repair`):
//!
//! 1. [`caps`]: boundary caps (tets with two faces on one smooth surface,
//!    less than 45° apart) are removed, which flips their surface edge:
//!    purely topological, no geometry needed.
//! 2. [`repair_with`]: given how far the curved boundary bulges over each
//!    boundary facet ([`bulge`], measured by projecting a few points of each
//!    facet), the *bad* cells ([`detect`]: all vertices on one surface that
//!    bulges into the domain, or a boundary facet bulging past half the
//!    height of the opposite vertex, itself on the boundary) are removed by
//!    local flips ([`flips`]: 2-3, 3-2 and edge removal in 3D, edge flips in
//!    2D). For each bad cell, the valid
//!    flip that removes it with the best smallest quality of its new cells
//!    (a quality that counts the bulge, [`detect`]) is applied if that beats
//!    the smallest quality of the cells it replaces; passes repeat until no
//!    cell is bad or no flip improves (at most [`MAX_PASSES`]). A bad cell no
//!    flip improves is left as it is. Boundary facets, vertices and
//!    orientations are kept; every accepted flip strictly raises the sorted
//!    vector of qualities, so no configuration comes back. Before the flips,
//!    a bad surface cell that is a cap whose faces are more than 45° apart
//!    (so step 1 kept it; coarse meshes of a sphere or a torus make them at
//!    50–90°) is removed like a cap: the geometry has shown that the surface
//!    is smooth there and bulges into the cell, and a flip would keep the
//!    surface edge the cap's two faces share, along which curving squeezes
//!    whatever cells are there (unless caps are kept: then only flips). The
//!    new facets are measured again before the next sweep. Between the caps
//!    and the flips, [`surface`]: a boundary edge whose facet would fold on
//!    its surface once curved is flipped to the other diagonal of its two
//!    facets (the new facets are measured, and a flip that does not help is
//!    refused), at most [`MAX_ROUNDS`] rounds.
//! 3. [`split`]: an interior edge opposite a vertex where a triangle of the
//!    mesh has two boundary edges on a smooth boundary (the cells between
//!    that triangle and the boundary would be squeezed flat there) is split
//!    at its midpoint, each cell around it into two; a new interior vertex.
//!
//! The cells of the result are the cells of the input that no step touched,
//! in their order, then the new cells. Each maps to an input cell (see
//! [`Repaired::input_cell`]).

pub mod bulge;
pub mod caps;
pub mod detect;
pub mod flips;
mod geom;
pub mod split;
pub mod surface;
#[cfg(test)]
mod tests;

use rustc_hash::FxHashSet as HashSet;

use crate::mesh::LinearMesh;
pub use bulge::{bulge_samples, facet_bulges, BulgeSamples};
pub use caps::remove_boundary_caps;
pub use detect::{bad_cells, Assessment, Criteria, BULGE_FRACTION};
pub use flips::FlipKind;
use flips::Work;
use geom::barycentric;

/// Passes over the bad cells at most, in one round of flips.
pub const MAX_PASSES: usize = 20;

/// Sweeps of surface caps at most ([`repair_with`]).
pub const MAX_ROUNDS: usize = 8;

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
    /// Bad surface cells that were boundary caps whose faces meet at more
    /// than [`caps::CAP_MAX_NORMAL_ANGLE_DEG`] (so the caps step kept them):
    /// removed like caps, their surface edge flipped to their chord
    /// ([`repair_with`]).
    pub surface_caps: usize,
    /// Cells of the mesh given that are not in the result.
    pub cells_removed: usize,
    /// Cells of the result that are not in the mesh given.
    pub cells_added: usize,
    /// Bad cells in the result: no flip improved them (left to the curving).
    pub bad_cells_left: usize,
    /// Interior edges split at their midpoint, each cell around them into
    /// two, because a smooth boundary would squeeze a cell flat ([`split`]).
    pub edge_splits: usize,
    /// Boundary edges flipped to the other diagonal of their two facets,
    /// because curving would fold one of them on its surface ([`surface`]).
    pub surface_flips: usize,
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
    /// step touched; for a new cell, the cell of the mesh given that contains
    /// its centroid (flips keep the region the cells cover and cap removals
    /// only shrink it, so there is one; on a tie, the one in which the
    /// centroid's smallest barycentric coordinate is largest).
    pub input_cell: Vec<usize>,
    pub summary: RepairSummary,
}

/// Flip the bad cells of `mesh` away: one round of [`repair_with`], with
/// the bulges known. `mesh` is validated and positively oriented (see
/// [`crate::mesh::validate_and_orient`]); `bulge` has one value per facet
/// ([`facet_bulges`]). Facets are unchanged; the cells no flip touched come
/// first, in their order, then the new cells.
pub fn repair(mesh: &LinearMesh, bulge: &[f64]) -> Repaired {
    let origin = (0..mesh.n_cells()).map(|c| vec![c]).collect();
    flip_round(mesh, bulge, &Criteria::new(mesh, bulge), origin, mesh).0
}

/// The repair (module docs). With `remove_caps`, the bad surface cells that
/// are boundary caps, whatever the angle of their faces, are removed first
/// ([`caps::sweep`], one sweep of vertex-disjoint caps at a time, at most
/// [`MAX_ROUNDS`]); `measure` gives the bulges of each new mesh (one value
/// per facet, see [`crate::geometry::facet_bulges`]). Then one round of flips
/// ([`repair`]) removes the other bad cells. The cells no step touched come
/// first, in their order, then the new cells.
pub fn repair_with<E>(
    mesh: &LinearMesh,
    remove_caps: bool,
    mut measure: impl FnMut(&LinearMesh, &BulgeSamples) -> Result<Vec<[f64; 3]>, E>,
) -> Result<Repaired, E> {
    let n = mesh.n_cells();
    let mut cur = mesh.clone();
    // Per cell of `cur`: the cells of `mesh` it overlaps, and which one it is if unchanged.
    let mut origin: Vec<Vec<usize>> = (0..n).map(|c| vec![c]).collect();
    let mut same: Vec<Option<usize>> = (0..n).map(Some).collect();
    let mut summary = RepairSummary::default();
    let mut m = Measured::of(&cur, &mut measure)?;
    // The criteria of `cur`, made again whenever it changes but by the
    // flips and splits, which keep its facets and boundary.
    let mut crit = Criteria::on_boundary(&cur, &m.bulge, &m.boundary);
    for round in 0..MAX_ROUNDS {
        let bad = crit.bad_cells(&cur);
        if round == 0 {
            summary.bad_cells = bad.len();
            summary.surface_cells = bad.iter().filter(|(_, a)| a.surface).count();
            summary.bulge_cells = bad.iter().filter(|(_, a)| a.bulge).count();
        }
        let surface: HashSet<usize> = bad.iter().filter(|(_, a)| a.surface).map(|&(c, _)| c).collect();
        if !remove_caps || surface.is_empty() {
            break;
        }
        let Some((next, kept)) = caps::sweep(&cur, |c, _| surface.contains(&c)) else { break };
        summary.surface_caps += cur.n_cells() - next.n_cells();
        origin = kept.iter().map(|&c| std::mem::take(&mut origin[c])).collect();
        same = kept.iter().map(|&c| same[c]).collect();
        cur = next;
        m = Measured::of(&cur, &mut measure)?;
        crit = Criteria::on_boundary(&cur, &m.bulge, &m.boundary);
    }
    // Surface edges whose facet folds once curved; a flip that does not
    // lower the squeeze is refused and its round done again without it.
    let mut refused = HashSet::default();
    for _ in 0..MAX_ROUNDS {
        let squeeze = surface::squeezes(&cur, &m.samples, &m.projected);
        let Some(round) = surface::flip_round(&cur, &m.bulge, &squeeze, &origin, &refused) else { break };
        let next = Measured::of(&round.mesh, &mut measure)?;
        let after = surface::squeezes(&round.mesh, &next.samples, &next.projected);
        let worse: Vec<[usize; 2]> =
            round.flips.iter().filter(|f| f.squeeze_after(&after) >= f.squeeze).map(|f| f.ab).collect();
        if !worse.is_empty() {
            refused.extend(worse);
            continue;
        }
        summary.surface_flips += round.flips.len();
        same = round.old.iter().map(|o| o.and_then(|c| same[c])).collect();
        origin = round.origin;
        cur = round.mesh;
        m = next;
        crit = Criteria::on_boundary(&cur, &m.bulge, &m.boundary);
    }
    let bulge = m.bulge;
    let (r, o) = flip_round(&cur, &bulge, &crit, origin, mesh);
    let s = r.summary;
    summary.flips_23 = s.flips_23;
    summary.flips_32 = s.flips_32;
    summary.edge_removals = s.edge_removals;
    summary.flips_22 = s.flips_22;
    summary.bad_cells_left = s.bad_cells_left;
    let n_kept = r.mesh.n_cells() - s.cells_added;
    let same: Vec<Option<usize>> =
        (0..r.mesh.n_cells()).map(|i| if i < n_kept { same[r.input_cell[i]] } else { None }).collect();
    // Flips keep the facets, so the bulges still hold, and the boundary
    // (they swap interior faces and edges only): the criteria too.
    let split = split::split_squeezed_with(&r.mesh, crit);
    summary.edge_splits = split.edges;
    let same: Vec<Option<usize>> =
        split.parent.iter().zip(&split.whole).map(|(&c, &w)| if w { same[c] } else { None }).collect();
    let o: Vec<&[usize]> = split.parent.iter().map(|&c| o[c].as_slice()).collect();
    let cur = split.mesh;
    let untouched = same.iter().flatten().count();
    summary.cells_removed = n - untouched;
    summary.cells_added = cur.n_cells() - untouched;
    let d = mesh.dim;
    let input_cell = (0..cur.n_cells())
        .map(|c| same[c].unwrap_or_else(|| locate(mesh, &cur, &cur.cells[c * (d + 1)..(c + 1) * (d + 1)], o[c])))
        .collect();
    Ok(Repaired { mesh: cur, input_cell, summary })
}

/// One round of flips on `mesh`, whose cell c overlaps the cells `origin[c]`
/// of `base`: the repaired mesh, and the origins of its cells. Its
/// `input_cell` gives an untouched cell's index in `mesh` and a new cell's in
/// `base` (the same mesh for [`repair`]). `crit` is made for `mesh` and `bulge`.
fn flip_round(
    mesh: &LinearMesh,
    bulge: &[f64],
    crit: &Criteria,
    origin: Vec<Vec<usize>>,
    base: &LinearMesh,
) -> (Repaired, Vec<Vec<usize>>) {
    let n = mesh.n_cells();
    let mut summary = RepairSummary::default();
    if !(mesh.dim == 2 || mesh.dim == 3) || bulge.len() != mesh.n_facets() {
        let input_cell = (0..n).collect();
        return (Repaired { mesh: mesh.clone(), input_cell, summary }, origin);
    }
    let bad = crit.bad_cells(mesh);
    if bad.is_empty() {
        let input_cell = (0..n).collect();
        return (Repaired { mesh: mesh.clone(), input_cell, summary }, origin);
    }
    for (_, a) in &bad {
        summary.bad_cells += 1;
        summary.surface_cells += a.surface as usize;
        summary.bulge_cells += a.bulge as usize;
    }
    let mut w = Work::new(mesh, crit, origin);
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
                FlipKind::SurfaceEdge => unreachable!("bad cells are not flipped by surface edge"),
            }
            w.apply(&f);
            changed = true;
        }
        if !changed {
            break;
        }
    }
    summary.bad_cells_left = (0..w.cells.len()).filter(|&c| w.alive[c] && w.assessment[c].is_bad()).count();
    let d = mesh.dim;
    let (cells, old, origin) = w.into_cells();
    let input_cell = old
        .iter()
        .enumerate()
        .map(|(i, o)| o.unwrap_or_else(|| locate(base, base, &cells[i * (d + 1)..(i + 1) * (d + 1)], &origin[i])))
        .collect();
    summary.cells_added = old.iter().filter(|o| o.is_none()).count();
    summary.cells_removed = n - (old.len() - summary.cells_added);
    let out = LinearMesh { cells, ..mesh.clone() };
    (Repaired { mesh: out, input_cell, summary }, origin)
}

/// The bulge samples of a mesh, their projections and the bulge of each
/// facet, and its boundary facets (for its [`Criteria`]).
struct Measured {
    boundary: Vec<geom::FacetKey>,
    samples: BulgeSamples,
    projected: Vec<[f64; 3]>,
    bulge: Vec<f64>,
}

impl Measured {
    fn of<E>(
        mesh: &LinearMesh,
        measure: &mut impl FnMut(&LinearMesh, &BulgeSamples) -> Result<Vec<[f64; 3]>, E>,
    ) -> Result<Measured, E> {
        let boundary = geom::boundary_facets(mesh);
        let samples = bulge::bulge_samples_on(mesh, &boundary);
        let projected = measure(mesh, &samples)?;
        let bulge = facet_bulges(mesh, &samples, &projected);
        Ok(Measured { boundary, samples, projected, bulge })
    }
}

/// The cell among `candidates` (cells of `mesh`) that contains the centroid
/// of `cell`, whose vertices are those of `at` (`mesh`'s, and any added
/// after them).
fn locate(mesh: &LinearMesh, at: &LinearMesh, cell: &[usize], candidates: &[usize]) -> usize {
    let d = mesh.dim;
    let mut g = [0.0; 3];
    for &v in cell {
        let x = at.vertex(v);
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
