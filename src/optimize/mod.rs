//! The optimisation stage: untangle and improve the cells that the elastic
//! curving left invalid or of low quality, by moving the high-order nodes
//! around them.
//!
//! For each group of bad cells (certified invalid, or sampled Q3 below a
//! threshold), a [`patch`] of surrounding cells is formed and the positions
//! of its free nodes minimise the sum over its cells of the regularised
//! distortion energy of [`energy`]: first with the regularisation δ > 0,
//! which is finite on inverted cells and pushes det J up (untangling), then
//! with δ = 0, a barrier that keeps every sample point valid while the
//! distortion falls. A patch's new positions are kept only if they improve
//! it: fewer certified-invalid cells, or as many and a higher minimum Q3.
//! The cells still bad are then given larger patches, up to a few rounds.
//! Patches never share a node, so they are optimised in parallel and the
//! result does not depend on the number of threads.
//!
//! Pure: no I/O; the mesh's boundary nodes and the cells outside the patches
//! are never moved.

pub mod energy;
pub mod lbfgs;
pub mod patch;

use std::time::Instant;

use rayon::prelude::*;

use crate::mapping::ElementCache;
use crate::mesh::HighOrderMesh;
use crate::quadrature::simplex_rule;
use crate::quality::{self, CertifiedJacobian, ElementQuality, JacobianBernstein, Verdict};
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use energy::{ElementSamples, SampleRule};
use patch::{build_patches, NodeCells, Patch};

/// Settings of the optimisation stage.
#[derive(Debug, Clone, PartialEq)]
pub struct OptimizeOptions {
    /// Run the stage when some cell needs it (default on).
    pub enabled: bool,
    /// Cells whose sampled Q3 is below this are optimised too (default
    /// [`DEFAULT_THRESHOLD`]); invalid cells always are.
    pub threshold: f64,
}

/// Default Q3 below which a valid cell is optimised.
pub const DEFAULT_THRESHOLD: f64 = 0.2;

impl Default for OptimizeOptions {
    fn default() -> Self {
        OptimizeOptions { enabled: true, threshold: DEFAULT_THRESHOLD }
    }
}

/// What the optimisation stage did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OptimizeReport {
    /// Whether it ran (some cell was invalid or below the threshold).
    pub ran: bool,
    /// Cells selected at the start: invalid or below the threshold.
    pub target_cells: usize,
    /// Cells of the patches whose new positions were kept.
    pub cells_touched: usize,
    /// Nodes those patches moved.
    pub nodes_moved: usize,
    /// Patches optimised, over all rounds.
    pub patches: usize,
    /// Rounds of growing patches.
    pub rounds: usize,
    /// Certified-invalid (or undecided) cells before and after.
    pub invalid_before: usize,
    pub invalid_after: usize,
    /// Minimum sampled Q3 before and after.
    pub min_q3_before: f64,
    pub min_q3_after: f64,
    pub seconds: f64,
}

/// Node-neighbour layers of the patches of each round.
const LAYERS: [usize; 5] = [1, 2, 3, 5, 8];

/// Rounds in which cells that are valid but below the threshold are still
/// selected (after that, only invalid ones).
const QUALITY_ROUNDS: usize = 2;

/// Untangling: the regularisation is δ² = ε(ε − J_min) while J_min < ε.
const UNTANGLE_EPS: f64 = 0.1;
/// Untangling stops once the smallest sampled J (relative to the straight
/// element) exceeds this.
const UNTANGLED: f64 = 0.02;
const UNTANGLE_PASSES: usize = 8;
/// An untangling pass that raises the worst J by less than this times δ
/// has stalled.
const STALLED: f64 = 1e-3;
const MAX_ITERATIONS: usize = 100;

/// Everything per order that the patches share.
struct Stage<'a> {
    dim: usize,
    /// Sample rules: quadrature of degree 2p with the nodal lattice of order
    /// p (first round), or of order 2p (later rounds).
    coarse: SampleRule,
    fine: SampleRule,
    sampling: &'a ElementCache,
    bernstein: JacobianBernstein,
}

/// Cell figures used to select and to accept.
#[derive(Debug, Clone, Copy)]
struct CellState {
    q: ElementQuality,
    cert: CertifiedJacobian,
}

impl CellState {
    fn invalid(&self) -> bool {
        self.cert.verdict != Verdict::Valid
    }
}

/// Optimise the bad cells of `mesh` in place (module docs). `straight` holds
/// the straight-sided positions of the same nodes, `sampling` is
/// [`quality::sampling_cache`] of `basis`; `cell_quality` and `certified`
/// are the figures of every cell on entry and are updated for the cells
/// that changed.
pub fn optimize(
    mesh: &mut HighOrderMesh,
    straight: &[f64],
    basis: &LagrangeBasis,
    sampling: &ElementCache,
    opts: &OptimizeOptions,
    cell_quality: &mut [ElementQuality],
    certified: &mut [CertifiedJacobian],
) -> OptimizeReport {
    let t0 = Instant::now();
    let mut report = OptimizeReport {
        invalid_before: certified.iter().filter(|c| c.verdict != Verdict::Valid).count(),
        min_q3_before: cell_quality.iter().map(|q| q.q3).fold(f64::INFINITY, f64::min),
        ..Default::default()
    };
    let bad = |c: usize, round: usize, q: &[ElementQuality], cert: &[CertifiedJacobian]| {
        cert[c].verdict != Verdict::Valid || (round < QUALITY_ROUNDS && q[c].q3 < opts.threshold)
    };
    let nc = mesh.n_cells();
    report.target_cells = (0..nc).filter(|&c| bad(c, 0, cell_quality, certified)).count();
    if opts.enabled && report.target_cells > 0 {
        report.ran = true;
        let stage = Stage::new(basis, sampling);
        let adj = NodeCells::new(mesh);
        let mut touched = vec![false; nc];
        let mut moved = vec![false; mesh.n_nodes()];
        for (round, &layers) in LAYERS.iter().enumerate() {
            let seeds: Vec<usize> = (0..nc).filter(|&c| bad(c, round, cell_quality, certified)).collect();
            if seeds.is_empty() {
                break;
            }
            report.rounds += 1;
            let patches = build_patches(mesh, &adj, &seeds, layers);
            report.patches += patches.len();
            let rule = if round == 0 { &stage.coarse } else { &stage.fine };
            let coords = &mesh.coords;
            let results: Vec<Option<Vec<f64>>> = patches
                .par_iter()
                .map(|p| {
                    stage.optimize_patch(
                        coords,
                        &mesh.cells,
                        mesh.nodes_per_cell(),
                        straight,
                        p,
                        rule,
                        cell_quality,
                        certified,
                    )
                })
                .collect();
            let dim = stage.dim;
            for (p, result) in patches.iter().zip(results) {
                let Some(x) = result else { continue };
                for (i, &n) in p.free.iter().enumerate() {
                    mesh.coords[n * dim..(n + 1) * dim].copy_from_slice(&x[i * dim..(i + 1) * dim]);
                    moved[n] = true;
                }
                for &c in &p.cells {
                    let s = stage.cell_state(&mesh.coords, mesh.cell(c), straight);
                    cell_quality[c] = s.q;
                    certified[c] = s.cert;
                    touched[c] = true;
                }
            }
        }
        report.cells_touched = touched.iter().filter(|&&t| t).count();
        report.nodes_moved = moved.iter().filter(|&&m| m).count();
    }
    report.invalid_after = certified.iter().filter(|c| c.verdict != Verdict::Valid).count();
    report.min_q3_after = cell_quality.iter().map(|q| q.q3).fold(f64::INFINITY, f64::min);
    report.seconds = t0.elapsed().as_secs_f64();
    report
}

impl<'a> Stage<'a> {
    fn new(basis: &LagrangeBasis, sampling: &'a ElementCache) -> Stage<'a> {
        let p = basis.order();
        Stage {
            dim: basis.simplex().dim(),
            coarse: sample_rule(basis, p),
            fine: sample_rule(basis, 2 * p),
            sampling,
            bernstein: JacobianBernstein::new(basis),
        }
    }

    fn cell_state(&self, coords: &[f64], cell: &[usize], straight: &[f64]) -> CellState {
        let dim = self.dim;
        let (xe, xs) = (gather(coords, cell, dim), gather(straight, cell, dim));
        CellState { q: quality::element_quality(self.sampling, &xe, &xs, None), cert: self.bernstein.certify(&xe) }
    }

    /// New positions of `patch.free` (dim each), or None if the optimisation
    /// did not improve the patch.
    #[allow(clippy::too_many_arguments)]
    fn optimize_patch(
        &self,
        coords: &[f64],
        cells: &[usize],
        npc: usize,
        straight: &[f64],
        patch: &Patch,
        rule: &SampleRule,
        cell_quality: &[ElementQuality],
        certified: &[CertifiedJacobian],
    ) -> Option<Vec<f64>> {
        if patch.free.is_empty() {
            return None;
        }
        let dim = self.dim;
        let cell = |c: usize| &cells[c * npc..(c + 1) * npc];
        // Per cell: its samples on the straight element, and for each of its
        // nodes the index among the free ones (or usize::MAX: fixed).
        let mut elements: Vec<ElementSamples> = Vec::with_capacity(patch.cells.len());
        let mut local: Vec<usize> = Vec::with_capacity(patch.cells.len() * npc);
        let mut h = f64::INFINITY;
        for &c in &patch.cells {
            let xs = gather(straight, cell(c), dim);
            elements.push(rule.element(&xs)?);
            h = h.min(element_size(dim, &xs));
            local.extend(cell(c).iter().map(|n| patch.free.binary_search(n).unwrap_or(usize::MAX)));
        }
        let mut x: Vec<f64> = patch.free.iter().flat_map(|&n| coords[n * dim..(n + 1) * dim].iter().copied()).collect();
        let gather_cell = |k: usize, x: &[f64], xe: &mut [f64]| {
            for (a, &n) in cell(patch.cells[k]).iter().enumerate() {
                let i = local[k * npc + a];
                let src = if i == usize::MAX { &coords[n * dim..(n + 1) * dim] } else { &x[i * dim..(i + 1) * dim] };
                xe[a * dim..(a + 1) * dim].copy_from_slice(src);
            }
        };
        let mut xe = vec![0.0; npc * dim];
        let mut ge = vec![0.0; npc * dim];
        let min_det = |x: &[f64], xe: &mut [f64]| {
            (0..patch.cells.len())
                .map(|k| {
                    gather_cell(k, x, xe);
                    rule.min_det(&elements[k], xe)
                })
                .fold(f64::INFINITY, f64::min)
        };
        let first_step = 0.05 * h;
        let run = |x: &mut Vec<f64>, delta: f64, xe: &mut Vec<f64>, ge: &mut Vec<f64>| {
            let mut f = |x: &[f64], g: &mut [f64]| -> Option<f64> {
                g.iter_mut().for_each(|v| *v = 0.0);
                let mut total = 0.0;
                for k in 0..patch.cells.len() {
                    gather_cell(k, x, xe);
                    ge.iter_mut().for_each(|v| *v = 0.0);
                    total += rule.energy_grad(&elements[k], xe, delta, ge)?;
                    for a in 0..npc {
                        let i = local[k * npc + a];
                        if i != usize::MAX {
                            for d in 0..dim {
                                g[i * dim + d] += ge[a * dim + d];
                            }
                        }
                    }
                }
                Some(total)
            };
            lbfgs::minimise(x, &mut f, first_step, MAX_ITERATIONS, 1e-6);
        };
        let mut jmin = min_det(&x, &mut xe);
        for _ in 0..UNTANGLE_PASSES {
            if jmin > UNTANGLED {
                break;
            }
            let delta = (UNTANGLE_EPS * (UNTANGLE_EPS - jmin)).sqrt();
            run(&mut x, delta, &mut xe, &mut ge);
            let last = jmin;
            jmin = min_det(&x, &mut xe);
            if jmin < 0.0 && jmin - last <= STALLED * delta {
                // The worst point does not move: it depends on fixed nodes
                // only, or the patch is too small; a larger one may help.
                break;
            }
        }
        if jmin > 0.0 {
            run(&mut x, 0.0, &mut xe, &mut ge);
        }
        // Keep the new positions only if they improve the patch.
        let score = |invalid: usize, q3: f64| (invalid, -q3);
        let before = score(
            patch.cells.iter().filter(|&&c| certified[c].verdict != Verdict::Valid).count(),
            patch.cells.iter().map(|&c| cell_quality[c].q3).fold(f64::INFINITY, f64::min),
        );
        let (mut invalid, mut q3) = (0, f64::INFINITY);
        for k in 0..patch.cells.len() {
            gather_cell(k, &x, &mut xe);
            let xs = gather(straight, cell(patch.cells[k]), dim);
            let s = CellState {
                q: quality::element_quality(self.sampling, &xe, &xs, None),
                cert: self.bernstein.certify(&xe),
            };
            invalid += s.invalid() as usize;
            q3 = q3.min(s.q.q3);
        }
        let after = score(invalid, q3);
        (after.0 < before.0 || (after.0 == before.0 && after.1 < before.1)).then_some(x)
    }
}

/// The sample rule of an order: the quadrature points of degree 2p (half
/// the weight) and the equispaced lattice of order `lattice` (the other
/// half, where det J is usually extreme: vertices, edges, faces).
fn sample_rule(basis: &LagrangeBasis, lattice: usize) -> SampleRule {
    let simplex = basis.simplex();
    let rule = simplex_rule(simplex, 2 * basis.order());
    let lattice = NodeSet::new(simplex, lattice, NodeSpacing::Equispaced);
    let wsum: f64 = rule.weights.iter().sum();
    let mut weights: Vec<f64> = rule.weights.iter().map(|w| 0.5 * w / wsum).collect();
    weights.extend(std::iter::repeat_n(0.5 / lattice.len() as f64, lattice.len()));
    let mut points = rule.points.clone();
    points.extend(lattice.coords.iter().copied());
    let tab = basis.tabulate(&points);
    SampleRule { dim: tab.dim, n_basis: tab.n_basis, weights, ref_grads: tab.grads }
}

fn gather(coords: &[f64], cell: &[usize], dim: usize) -> Vec<f64> {
    cell.iter().flat_map(|&n| coords[n * dim..(n + 1) * dim].iter().copied()).collect()
}

/// |straight element|^(1/d) from its vertices (the first d + 1 nodes).
fn element_size(dim: usize, xs: &[f64]) -> f64 {
    let v: Vec<[f64; 3]> = (0..=dim)
        .map(|a| {
            let mut p = [0.0; 3];
            p[..dim].copy_from_slice(&xs[a * dim..(a + 1) * dim]);
            p
        })
        .collect();
    crate::mapping::det(dim, &crate::mapping::affine_jacobian(dim, &v)).abs().powf(1.0 / dim as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::Simplex;

    /// The nodes of the reference element of `basis`, mapped to a skewed
    /// straight element and then bent by a smooth field scaled by `bend`.
    fn element(basis: &LagrangeBasis, bend: f64) -> (Vec<f64>, Vec<f64>) {
        let dim = basis.simplex().dim();
        let a = [[1.0, 0.3, -0.2], [0.1, 0.9, 0.25], [0.2, -0.1, 1.1]];
        let (mut xs, mut xe) = (Vec::new(), Vec::new());
        for p in &basis.nodes().coords {
            let y: Vec<f64> = (0..dim).map(|i| (0..dim).map(|j| a[i][j] * p[j]).sum()).collect();
            xs.extend(&y);
            for (i, yi) in y.iter().enumerate() {
                xe.push(yi + bend * (3.0 * y[(i + 1) % dim] * y[(i + 2) % dim] + y[i] * y[i]).sin());
            }
        }
        (xs, xe)
    }

    #[test]
    fn element_energy_gradient_matches_finite_differences() {
        for (simplex, p, delta) in [(Simplex::Tri, 3, 0.0), (Simplex::Tet, 2, 0.0), (Simplex::Tet, 3, 0.2)] {
            let basis = LagrangeBasis::new(&NodeSet::new(simplex, p, NodeSpacing::Optimal));
            let rule = sample_rule(&basis, p);
            let (xs, xe) = element(&basis, 0.05);
            let e = rule.element(&xs).unwrap();
            let mut g = vec![0.0; xe.len()];
            rule.energy_grad(&e, &xe, delta, &mut g).unwrap();
            let h = 1e-6;
            for k in 0..xe.len() {
                let (mut xp, mut xm) = (xe.clone(), xe.clone());
                xp[k] += h;
                xm[k] -= h;
                let fd = (rule.energy(&e, &xp, delta).unwrap() - rule.energy(&e, &xm, delta).unwrap()) / (2.0 * h);
                assert!((fd - g[k]).abs() < 1e-6 * (1.0 + fd.abs()), "{simplex:?} p={p} dof {k}: {fd} vs {}", g[k]);
            }
        }
    }

    #[test]
    fn a_straight_element_has_energy_one_and_zero_gradient() {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tet, 4, NodeSpacing::Optimal));
        let rule = sample_rule(&basis, 8);
        let (xs, _) = element(&basis, 0.0);
        let e = rule.element(&xs).unwrap();
        let mut g = vec![0.0; xs.len()];
        let v = rule.energy_grad(&e, &xs, 0.0, &mut g).unwrap();
        assert!((v - 1.0).abs() < 1e-12, "{v}");
        assert!(g.iter().all(|x| x.abs() < 1e-10), "{g:?}");
    }
}
