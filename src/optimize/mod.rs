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
//! When the interior nodes alone leave a patch invalid or below the
//! threshold, its high-order boundary nodes slide on their entity through
//! the projector. After two rounds, the cells still invalid are split at
//! their centroid ([`split`]) and later rounds, with larger patches, work on
//! the invalid cells until two rounds in a row fix nothing. Last, once every
//! cell is valid, a polish: small patches around the (at most 8) cells
//! nearest the smallest Q3, each kept only if it raises its patch's smallest
//! Q3, while that raises the mesh's by 1 % or more; the energy, an average,
//! counts the cells near the smallest Q3 [`POLISH_FOCUS`] times so that it
//! aims at the floor. Its boundary nodes slide at any
//! quality, but a slide is kept only if the boundary between the nodes stays
//! close to the geometry ([`fidelity`]): sliding moves nodes off their
//! interpolation points, and unguarded, the boundary's distance to the CAD
//! between nodes stopped converging with p (a sphere-torus part at p = 5:
//! 1.4e-4 against 1.5e-6 at p = 4).
//! Patches never share a node, so they are optimised in parallel and the
//! result does not depend on the number of threads.
//!
//! Pure: no I/O; vertices, nodes on untagged boundary and the cells outside
//! the patches are never moved, and boundary nodes only along their entity.

pub mod energy;
mod fidelity;
pub mod lbfgs;
pub mod patch;
pub mod split;

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;

use crate::geometry::Projector;
use crate::mapping::ElementCache;
use crate::mesh::{HighOrderMesh, NodeConstraint};
use crate::quadrature::simplex_rule;
use crate::quality::{self, CertifiedJacobian, ElementQuality, JacobianBernstein, Verdict};
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use energy::{ElementSamples, SampleRule};
use patch::{build_patches, NodeCells, Patch};

/// Settings of the optimisation stage.
#[derive(Debug, Clone, PartialEq)]
pub struct OptimizeOptions {
    /// Run the stage (default on): the rounds when some cell is invalid or
    /// below the threshold, then the polish.
    pub enabled: bool,
    /// Cells whose sampled Q3 is below this are optimised too (default
    /// [`DEFAULT_THRESHOLD`]); invalid cells always are.
    pub threshold: f64,
    /// Let the high-order boundary nodes of a patch slide on their entity
    /// when moving the interior nodes leaves a cell invalid (default on).
    pub slide: bool,
    /// Split the cells still invalid after the first rounds at their
    /// centroid ([`split`]), so that interior nodes reach every point of
    /// them, and optimise again (default on).
    pub split: bool,
    /// After the first rounds, work on the cells still invalid: split them
    /// (with `split`) and optimise growing patches around them, the later
    /// rounds (default on). Off, the stage ends after the first rounds
    /// when some cell is still invalid: the curving turns it off in a
    /// first run that removed caps, whose failure the run with the caps
    /// kept may then rescue at less cost ([`crate::curve::CurveOptions::retry_keep_caps`]).
    pub later_rounds: bool,
    /// For a slow projector (gmsh's `getClosestPoint` through Python, at
    /// 0.1 to 0.4 ms a point): sliding nodes move in their tangent planes
    /// and are projected after each pass, and at every step only where that
    /// does not make the patch valid and lift it above the threshold
    /// (wrenchnut through gmsh at p = 3: 25,000 projected points instead of
    /// 297,000; as valid, the floor sometimes lower, and a little more work
    /// where the first way seldom suffices, as on analytic shapes). Default
    /// off: every step projected.
    pub tangent_first: bool,
}

/// Default Q3 below which a valid cell is optimised.
pub const DEFAULT_THRESHOLD: f64 = 0.2;

impl Default for OptimizeOptions {
    fn default() -> Self {
        OptimizeOptions {
            enabled: true,
            threshold: DEFAULT_THRESHOLD,
            slide: true,
            split: true,
            later_rounds: true,
            tangent_first: false,
        }
    }
}

/// What the optimisation stage did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OptimizeReport {
    /// Whether some round ran (cells invalid or below the threshold, or the polish).
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
    /// Cells split at their centroid ([`split`]); each became d + 1 cells.
    pub cells_split: usize,
    /// Certified-invalid (or undecided) cells before and after.
    pub invalid_before: usize,
    pub invalid_after: usize,
    /// Minimum sampled Q3 before and after.
    pub min_q3_before: f64,
    pub min_q3_after: f64,
    pub seconds: f64,
}

/// Node-neighbour layers of the patches of the first rounds, in which cells
/// valid but below the threshold are selected too.
const FIRST_LAYERS: [usize; 2] = [1, 2];

/// Node-neighbour layers of the later rounds, after the split, on the
/// invalid cells only.
const LATER_LAYERS: [usize; 5] = [1, 2, 3, 5, 8];

/// The later rounds stop after this many rounds in a row that leave as many
/// invalid cells (larger patches cost more and seldom help then).
const FUTILE_ROUNDS: usize = 2;

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
/// L-BFGS iterations the interior nodes of a patch that may slide get
/// before it is decided whether they go on alone or slide
/// ([`PatchContext::optimize_patch`]).
const INTERIOR_TRIAL: usize = 20;

/// Everything per order that the patches share.
struct PatchContext<'a> {
    dim: usize,
    /// Sample rules: quadrature of degree 2p with the nodal lattice of order
    /// p (first round), or of order 2p (later rounds).
    coarse: SampleRule,
    fine: SampleRule,
    sampling: &'a ElementCache,
    bernstein: JacobianBernstein,
    /// The boundary pieces sampled by the polish's guard.
    pieces: fidelity::Pieces,
}

/// What one round does: patches of `layers` layers around its seeds,
/// sampled by `rule`; boundary nodes slide where interior moves leave a
/// patch invalid or with Q3 below `slide_below`. With a `baseline`, a
/// slide is kept only if the boundary between the nodes stays as close to
/// the geometry as [`fidelity`] allows.
#[derive(Clone, Copy)]
struct Pass<'r> {
    layers: usize,
    rule: &'r SampleRule,
    slide_below: f64,
    /// [`OptimizeOptions::tangent_first`].
    tangent_first: bool,
    baseline: Option<&'r Baseline>,
    /// The energy of the cells whose Q3 is below `focus.0` counts
    /// `focus.1` times (outside the polish: every cell alike).
    focus: (f64, f64),
    /// [`INTERIOR_TRIAL`] (other values in tests).
    interior_trial: usize,
}

/// The boundary before the polish: its distance from the geometry between
/// the nodes.
type Baseline = fidelity::Baseline;

/// Cell figures used to select and to accept.
#[derive(Debug, Clone, Copy)]
struct CellState {
    q: ElementQuality,
    cert: CertifiedJacobian,
}

impl CellState {
    /// Whether the cell is not certified valid.
    fn invalid(&self) -> bool {
        self.cert.verdict != Verdict::Valid
    }
}

/// Optimise the bad cells of `mesh` in place (module docs). `straight` holds
/// the straight-sided positions of the same nodes, `sampling` is
/// [`quality::sampling_cache`] of `basis`; `cell_quality` and `certified`
/// are the figures of every cell on entry and are updated for the cells
/// that changed. With a `projector`, the high-order boundary nodes of a
/// patch that interior moves cannot make valid slide on their entity.
///
/// Cells split at their centroid ([`OptimizeOptions::split`]) add cells
/// and nodes: `mesh`, `straight`, `cell_quality` and `certified` grow, and
/// the second value returned gives, for each cell of the result, the cell
/// of `mesh` on entry it is part of (itself for a cell not split).
#[allow(clippy::too_many_arguments)]
pub fn optimize(
    mesh: &mut HighOrderMesh,
    straight: &mut Vec<f64>,
    basis: &LagrangeBasis,
    sampling: &ElementCache,
    opts: &OptimizeOptions,
    projector: Option<&dyn Projector>,
    cell_quality: &mut Vec<ElementQuality>,
    certified: &mut Vec<CertifiedJacobian>,
) -> (OptimizeReport, Vec<usize>) {
    let t0 = Instant::now();
    let mut state = MeshState { mesh, straight, cell_quality, certified };
    let mut report = OptimizeReport {
        invalid_before: invalid_count(state.certified),
        min_q3_before: min_q3(state.cell_quality),
        ..Default::default()
    };
    let mut parent: Vec<usize> = (0..state.mesh.n_cells()).collect();
    report.target_cells = state.selected(true, opts.threshold).len();
    // Nothing to do where no cell is invalid, below the threshold or curved
    // enough for the polish to matter: the context (a basis table at twice
    // the order) is not even built, and a straight mesh comes back untouched.
    let needed = report.invalid_before > 0 || report.target_cells > 0 || report.min_q3_before < POLISH_CEILING;
    if opts.enabled && needed {
        let ctx = PatchContext::new(basis, sampling);
        // Projector calls are serialised: a host's callback is called from
        // one thread at a time.
        let projector = projector.filter(|_| opts.slide).map(Mutex::new);
        let mut stage = Stage::new(&ctx, projector.as_ref(), opts, &state, &mut report);
        if let Some(split) = stage.run(&mut state, basis, opts.split, opts.later_rounds) {
            parent = split;
        }
    }
    report.invalid_after = invalid_count(state.certified);
    report.min_q3_after = min_q3(state.cell_quality);
    report.seconds = t0.elapsed().as_secs_f64();
    (report, parent)
}

/// The mesh and the figures of its cells, which the stage changes together.
struct MeshState<'m> {
    mesh: &'m mut HighOrderMesh,
    /// The straight-sided positions of the mesh's nodes.
    straight: &'m mut Vec<f64>,
    cell_quality: &'m mut Vec<ElementQuality>,
    certified: &'m mut Vec<CertifiedJacobian>,
}

impl MeshState<'_> {
    /// The cells certified invalid, and with `quality` those whose Q3 is below `threshold`.
    fn selected(&self, quality: bool, threshold: f64) -> Vec<usize> {
        let (q, cert) = (&self.cell_quality, &self.certified);
        (0..cert.len()).filter(|&c| cert[c].verdict != Verdict::Valid || (quality && q[c].q3 < threshold)).collect()
    }

    /// The figures of cell `c` as its nodes are now.
    fn measure(&self, ctx: &PatchContext, c: usize) -> CellState {
        ctx.cell_state(&self.mesh.coords, self.mesh.cell(c), self.straight)
    }

    /// The mesh as the patches of a round read it.
    fn view(&self) -> MeshView<'_> {
        MeshView {
            coords: &self.mesh.coords,
            cells: &self.mesh.cells,
            npc: self.mesh.nodes_per_cell(),
            constraint: &self.mesh.constraint,
            straight: self.straight,
            cell_quality: self.cell_quality,
            certified: self.certified,
        }
    }
}

/// The rounds of one call of [`optimize`]: what they share, and what they changed.
struct Stage<'s, 'p> {
    ctx: &'s PatchContext<'s>,
    projector: Option<&'s Mutex<&'p dyn Projector>>,
    threshold: f64,
    /// [`OptimizeOptions::tangent_first`].
    tangent_first: bool,
    /// Whether the polish retries a stalled round on the fine rule
    /// ([`POLISH_GAIN`]; always, but in a test that compares).
    fine_retry: bool,
    /// The cells of the patches kept so far.
    touched: Vec<bool>,
    /// The nodes those patches moved.
    moved: Vec<bool>,
    report: &'s mut OptimizeReport,
}

impl<'s, 'p> Stage<'s, 'p> {
    /// A stage on `state` that has changed nothing yet.
    fn new(
        ctx: &'s PatchContext<'s>,
        projector: Option<&'s Mutex<&'p dyn Projector>>,
        opts: &OptimizeOptions,
        state: &MeshState,
        report: &'s mut OptimizeReport,
    ) -> Self {
        let touched = vec![false; state.mesh.n_cells()];
        let moved = vec![false; state.mesh.n_nodes()];
        let (threshold, tangent_first) = (opts.threshold, opts.tangent_first);
        Stage { ctx, projector, threshold, tangent_first, fine_retry: true, touched, moved, report }
    }

    /// Every phase in turn (the split and the later rounds with `later`),
    /// then the report's totals; the cells' parents if some were split.
    fn run(&mut self, state: &mut MeshState, basis: &LagrangeBasis, split: bool, later: bool) -> Option<Vec<usize>> {
        self.first_rounds(state);
        let parent = if split && later { self.split_invalid(state, basis) } else { None };
        if later {
            self.later_rounds(state);
        }
        if let Some(parent) = &parent {
            self.pieces_round(state, parent);
        }
        self.polish(state);
        self.report.ran = self.report.rounds > 0;
        self.report.cells_touched = self.touched.iter().filter(|&&t| t).count();
        self.report.nodes_moved = self.moved.iter().filter(|&&m| m).count();
        parent
    }

    /// First rounds: invalid and low-quality cells, the cheap sample rule
    /// first. The second, on larger patches and the fine rule, runs only
    /// while some cell is invalid: when the first left every cell valid,
    /// the polish lifts the floor at less cost. On U_Joint_2 at p = 4 the
    /// second round spent 7.5 s on 1,666 cells for the same floor (0.130),
    /// and the polish then stopped at 0.152; without it, 0.194. On the
    /// crankshaft at p = 4, 40 % of the projections and a third of the
    /// stage's time less, the same floor; on the robustness corpus at
    /// p = 2..4 one run of 171 changed, 0.128 to 0.153.
    fn first_rounds(&mut self, state: &mut MeshState) {
        let ctx = self.ctx;
        for (k, &layers) in FIRST_LAYERS.iter().enumerate() {
            let seeds = state.selected(true, self.threshold);
            if seeds.is_empty() || (k > 0 && invalid_count(state.certified) == 0) {
                break;
            }
            let rule = if k == 0 { &ctx.coarse } else { &ctx.fine };
            self.run_round(state, &seeds, self.pass(layers, rule));
        }
    }

    /// Split the cells still invalid and measure the pieces; each cell's parent, or None if none was invalid.
    fn split_invalid(&mut self, state: &mut MeshState, basis: &LagrangeBasis) -> Option<Vec<usize>> {
        let invalid = state.selected(false, self.threshold);
        if invalid.is_empty() {
            return None;
        }
        let parent = split::split_at_centroids(state.mesh, state.straight, basis, &invalid);
        self.report.cells_split = invalid.len();
        for c in invalid.iter().copied().chain(state.cell_quality.len()..state.mesh.n_cells()) {
            let s = state.measure(self.ctx, c);
            if c < state.cell_quality.len() {
                (state.cell_quality[c], state.certified[c]) = (s.q, s.cert);
            } else {
                state.cell_quality.push(s.q);
                state.certified.push(s.cert);
            }
        }
        Some(parent)
    }

    /// Later rounds: growing patches around the invalid cells until [`FUTILE_ROUNDS`] in a row fix nothing.
    fn later_rounds(&mut self, state: &mut MeshState) {
        let ctx = self.ctx;
        let mut futile = 0;
        for &layers in &LATER_LAYERS {
            let seeds = state.selected(false, self.threshold);
            if seeds.is_empty() || futile == FUTILE_ROUNDS {
                break;
            }
            self.run_round(state, &seeds, self.pass(layers, &ctx.fine));
            futile = if invalid_count(state.certified) < seeds.len() { 0 } else { futile + 1 };
        }
    }

    /// The pieces of split cells had no quality round: one, on those below the threshold.
    fn pieces_round(&mut self, state: &mut MeshState, parent: &[usize]) {
        let ctx = self.ctx;
        // A split cell's first piece keeps its index; the others point to it.
        let mut piece = vec![false; state.mesh.n_cells()];
        for (c, &q) in parent.iter().enumerate().filter(|(c, q)| c != *q) {
            (piece[c], piece[q]) = (true, true);
        }
        let seeds: Vec<usize> =
            (0..state.mesh.n_cells()).filter(|&c| piece[c] && state.cell_quality[c].q3 < self.threshold).collect();
        if !seeds.is_empty() {
            self.run_round(state, &seeds, self.pass(FIRST_LAYERS[0], &ctx.fine));
        }
    }

    /// Polish: small patches around the cells near the smallest Q3, while that rises.
    fn polish(&mut self, state: &mut MeshState) {
        // Each patch is kept only if its own smallest Q3 rose, and the cells
        // near the floor weigh more in its energy: both aim at the floor,
        // which the energy, an average, does not by itself.
        // Boundary nodes slide at any quality here, as far as the boundary
        // between them stays close to the geometry (see [`fidelity`]).
        let ctx = self.ctx;
        let baseline = self.projector.map(|_| Baseline::new(&state.mesh.coords));
        // After a round that did not lift the floor, one more around the
        // worst cell alone, sampled by the fine rule ([`POLISH_GAIN`]).
        let mut retry = false;
        for _ in 0..POLISH_ROUNDS {
            if invalid_count(state.certified) > 0 {
                break;
            }
            let floor = min_q3(state.cell_quality);
            if floor >= POLISH_CEILING {
                break;
            }
            let (seeds, rule) = if retry {
                (polish_seeds(state.cell_quality, floor, 1), &ctx.fine)
            } else {
                // The coarse rule: the polish's patches are valid, and a pass
                // is kept only if the measured Q3 rose (as good, a third of the time).
                (polish_seeds(state.cell_quality, floor, POLISH_SEEDS), &ctx.coarse)
            };
            let focus = (POLISH_FACTOR * floor, POLISH_FOCUS);
            let pass = match &baseline {
                Some(b) => Pass { slide_below: f64::INFINITY, baseline: Some(b), focus, ..self.pass(FIRST_LAYERS[0], rule) },
                None => Pass { focus, ..self.pass(FIRST_LAYERS[0], rule) },
            };
            self.run_round(state, &seeds, pass);
            let now = min_q3(state.cell_quality);
            let stalled = now < floor * (1.0 + POLISH_GAIN);
            if stalled && (retry || !self.fine_retry) {
                break;
            }
            retry = stalled;
        }
    }

    /// A pass of `layers` layers sampled by `rule`, sliding below the threshold.
    fn pass<'r>(&self, layers: usize, rule: &'r SampleRule) -> Pass<'r> {
        Pass {
            layers,
            rule,
            slide_below: self.threshold,
            tangent_first: self.tangent_first,
            baseline: None,
            focus: (0.0, 1.0),
            interior_trial: INTERIOR_TRIAL,
        }
    }

    /// One round: the patches around `seeds` optimised in parallel, the improved ones kept.
    fn run_round(&mut self, state: &mut MeshState, seeds: &[usize], pass: Pass) {
        let adj = NodeCells::new(state.mesh);
        let patches = build_patches(state.mesh, &adj, seeds, pass.layers);
        self.report.rounds += 1;
        self.report.patches += patches.len();
        self.touched.resize(state.mesh.n_cells(), false);
        self.moved.resize(state.mesh.n_nodes(), false);
        let results = self.optimize_patches(state, &patches, pass);
        self.keep(state, &patches, results);
    }

    /// The new positions of each patch's moving nodes, or None where they did not improve it.
    fn optimize_patches(&self, state: &MeshState, patches: &[Patch], pass: Pass) -> Vec<Option<Vec<f64>>> {
        let (ctx, projector) = (self.ctx, self.projector);
        let view = state.view();
        // Largest first: one large patch often takes most of a round, and
        // started last it would run alone at the end. (Each patch's result
        // does not depend on the order.)
        let mut order: Vec<usize> = (0..patches.len()).collect();
        order.sort_by_key(|&k| std::cmp::Reverse(patches[k].cells.len()));
        let mut results: Vec<(usize, Option<Vec<f64>>)> = order
            .into_par_iter()
            .with_max_len(1)
            .map(|k| (k, ctx.optimize_patch(&view, &patches[k], pass, projector)))
            .collect();
        results.sort_unstable_by_key(|r| r.0);
        results.into_iter().map(|r| r.1).collect()
    }

    /// Write the improved patches' positions into the mesh and measure their cells again.
    fn keep(&mut self, state: &mut MeshState, patches: &[Patch], results: Vec<Option<Vec<f64>>>) {
        let dim = self.ctx.dim;
        let mut changed = Vec::new();
        for (p, result) in patches.iter().zip(results) {
            let Some(x) = result else { continue };
            for (i, &n) in p.free.iter().chain(&p.sliding).enumerate() {
                if state.mesh.coords[n * dim..(n + 1) * dim] != x[i * dim..(i + 1) * dim] {
                    self.moved[n] = true;
                }
                state.mesh.coords[n * dim..(n + 1) * dim].copy_from_slice(&x[i * dim..(i + 1) * dim]);
            }
            changed.extend_from_slice(&p.cells);
        }
        // Each cell measured on its own, so in parallel: the polish's
        // rounds measured 2,000 cells one after the other on the screw at
        // p = 2, 10 ms of its 0.1 s.
        let (ctx, now) = (self.ctx, &*state);
        let measured: Vec<CellState> = changed.par_iter().map(|&c| now.measure(ctx, c)).collect();
        for (&c, s) in changed.iter().zip(measured) {
            state.cell_quality[c] = s.q;
            state.certified[c] = s.cert;
            self.touched[c] = true;
        }
    }
}

/// The seeds of a polish round: of the cells with Q3 below [`POLISH_FACTOR`] × `floor`, the `count` worst, sorted.
fn polish_seeds(cell_quality: &[ElementQuality], floor: f64, count: usize) -> Vec<usize> {
    let mut seeds: Vec<usize> =
        (0..cell_quality.len()).filter(|&c| cell_quality[c].q3 < POLISH_FACTOR * floor).collect();
    seeds.sort_by(|&a, &b| cell_quality[a].q3.total_cmp(&cell_quality[b].q3).then(a.cmp(&b)));
    seeds.truncate(count);
    seeds.sort_unstable();
    seeds
}

/// The cells certified invalid (or undecided).
fn invalid_count(cert: &[CertifiedJacobian]) -> usize {
    cert.iter().filter(|c| c.verdict != Verdict::Valid).count()
}

/// The mesh as the patches of a round read it (none writes it while they run).
struct MeshView<'v> {
    coords: &'v [f64],
    /// Every cell's nodes, `npc` per cell.
    cells: &'v [usize],
    npc: usize,
    constraint: &'v [NodeConstraint],
    straight: &'v [f64],
    cell_quality: &'v [ElementQuality],
    certified: &'v [CertifiedJacobian],
}

impl MeshView<'_> {
    /// The nodes of cell `c`.
    fn cell(&self, c: usize) -> &[usize] {
        &self.cells[c * self.npc..(c + 1) * self.npc]
    }

    /// The entity (dimension, tag) that node `n` lies on, if it may slide.
    fn entity(&self, n: usize) -> Option<(usize, i32)> {
        match self.constraint[n] {
            NodeConstraint::OnEntity { dim, tag } => Some((dim, tag)),
            _ => None,
        }
    }

    /// (invalid cells, min Q3) of `cells` on entry to the round.
    fn score(&self, cells: &[usize]) -> (usize, f64) {
        (
            cells.iter().filter(|&&c| self.certified[c].verdict != Verdict::Valid).count(),
            cells.iter().map(|&c| self.cell_quality[c].q3).fold(f64::INFINITY, f64::min),
        )
    }
}

impl<'a> PatchContext<'a> {
    /// The context of the order of `basis`.
    fn new(basis: &LagrangeBasis, sampling: &'a ElementCache) -> PatchContext<'a> {
        let p = basis.order();
        PatchContext {
            dim: basis.simplex().dim(),
            coarse: sample_rule(basis, p),
            fine: sample_rule(basis, 2 * p),
            sampling,
            bernstein: JacobianBernstein::new(basis),
            pieces: fidelity::Pieces::new(basis),
        }
    }

    /// The figures of the cell with nodes `cell` at `coords`.
    fn cell_state(&self, coords: &[f64], cell: &[usize], straight: &[f64]) -> CellState {
        let dim = self.dim;
        let (xe, xs) = (gather(coords, cell, dim), gather(straight, cell, dim));
        self.state(&xe, &xs)
    }

    /// The figures of the element with node coordinates `xe` (straight: `xs`).
    fn state(&self, xe: &[f64], xs: &[f64]) -> CellState {
        CellState { q: quality::element_quality(self.sampling, xe, xs, None), cert: self.bernstein.certify(xe) }
    }

    /// New positions of the patch's moving nodes (`patch.free`, then
    /// `patch.sliding`, `dim` coordinates each), or None if the optimisation
    /// did not improve the patch.
    ///
    /// First the interior nodes alone; then, if cells are still invalid or
    /// below `slide_below` and a projector is given, the interior and
    /// boundary nodes together, the boundary ones moving in their entity's
    /// tangent space (a frame found through the projector) and projected
    /// at every step; with `tangent_first`, projected after each pass
    /// first, and at every step only if that does not make the patch valid
    /// and above `slide_below` (then from the best positions found so far).
    /// In the polish (a `baseline`), interior and boundary nodes move
    /// together at once, and the interior nodes alone only if that slide is
    /// not kept: one minimisation instead of two where it is.
    fn optimize_patch(
        &self,
        view: &MeshView,
        patch: &Patch,
        Pass { rule, slide_below, tangent_first, baseline, focus, interior_trial, .. }: Pass,
        projector: Option<&Mutex<&dyn Projector>>,
    ) -> Option<Vec<f64>> {
        if patch.free.is_empty() && patch.sliding.is_empty() {
            return None;
        }
        let dim = self.dim;
        let work = PatchWork::new(self, view, patch, rule, focus)?;
        let node = |n: usize| point(&view.coords[n * dim..(n + 1) * dim]);
        let start: Vec<[f64; 3]> = patch.free.iter().chain(&patch.sliding).map(|&n| node(n)).collect();
        let before = view.score(&patch.cells);
        let result = |best: ((usize, f64), Vec<[f64; 3]>)| {
            better(best.0, before).then(|| best.1.iter().flat_map(|x| x[..dim].to_vec()).collect())
        };
        let sliding = projector.filter(|_| !patch.sliding.is_empty());
        if let (Some(projector), Some(baseline)) = (sliding, baseline) {
            let (mut pos, mut best) = (start.clone(), (before, start.clone()));
            work.slide(projector, &mut pos, &mut best, true);
            if better(best.0, before) && work.faithful(projector, baseline, &best.1) {
                return result(best);
            }
        }
        // Interior nodes alone (the sliding ones held where they are).
        let mut pos = start;
        let interior: Vec<Unknown> = (0..pos.len())
            .map(|j| if j < patch.free.len() { Unknown::free(pos[j], dim) } else { Unknown::fixed(pos[j]) })
            .collect();
        // Where sliding may follow, the interior nodes first get a trial
        // budget: a patch they alone lift above the threshold within it
        // goes on to convergence with its boundary nodes kept; the others
        // go to the slide, which moves the interior nodes too. On U_Joint_2
        // at p = 2, 15 of the 16 first-round patches slid after interior
        // passes of up to 174 iterations (the floor of the largest, 143
        // cells, went from 3e-4 to 1e-3), a third of the stage's time.
        let trial = if sliding.is_some() && baseline.is_none() { interior_trial } else { usize::MAX };
        let taken = work.problem(None).minimise(&mut pos, interior.clone(), 0.05 * work.h, trial);
        let mut best = (work.score(&pos), pos.clone());
        if taken == trial && best.0 .0 == 0 && best.0 .1 >= slide_below {
            work.problem(None).minimise(&mut pos, interior, 0.05 * work.h, usize::MAX);
            best = (work.score(&pos), pos.clone());
        }
        if let (Some(projector), true, None) = (sliding, best.0 .0 > 0 || best.0 .1 < slide_below, baseline) {
            // With `tangent_first`, in the tangent planes first, projected
            // after each pass; if that does not make the patch valid and
            // lift it above the threshold, with every step projected, from
            // the best the tangent passes found (from where the interior
            // nodes left it, the projected passes redid the tangent ones'
            // work: on SampleCrankshaft4A, whose worst cells stay below the
            // threshold, 1.55 times the cells evaluated at p = 2).
            if tangent_first {
                work.slide(projector, &mut pos, &mut best, true);
                if best.0 .0 == 0 && best.0 .1 >= slide_below {
                    return result(best);
                }
                pos.clone_from(&best.1);
            }
            work.slide(projector, &mut pos, &mut best, false);
        }
        result(best)
    }
}

/// One patch being optimised: its cells sampled on their straight elements,
/// where its moving nodes sit in them, and its length scales.
struct PatchWork<'w> {
    ctx: &'w PatchContext<'w>,
    view: &'w MeshView<'w>,
    patch: &'w Patch,
    rule: &'w SampleRule,
    elements: Vec<ElementSamples>,
    /// Per cell-local node of the patch cells: index among the moving nodes, or usize::MAX.
    local: Vec<usize>,
    /// Of each moving node, the smallest mean edge of its cells.
    scale: Vec<f64>,
    /// The median cell's mean edge.
    h: f64,
    /// Per patch cell, the weight of its energy.
    weights: Vec<f64>,
}

impl<'w> PatchWork<'w> {
    /// The patch sampled by `rule`; None if a straight element cannot be.
    fn new(
        ctx: &'w PatchContext<'w>,
        view: &'w MeshView<'w>,
        patch: &'w Patch,
        rule: &'w SampleRule,
        (focus_below, focus): (f64, f64),
    ) -> Option<Self> {
        let (dim, npc) = (ctx.dim, view.npc);
        let mut elements: Vec<ElementSamples> = Vec::with_capacity(patch.cells.len());
        let mut sizes = Vec::with_capacity(patch.cells.len());
        for &c in &patch.cells {
            let xs = gather(view.straight, view.cell(c), dim);
            elements.push(rule.element(&xs)?);
            sizes.push(mean_edge(dim, &xs));
        }
        let local: Vec<usize> = patch
            .cells
            .iter()
            .flat_map(|&c| view.cell(c).iter().map(|n| position_in(&patch.free, &patch.sliding, *n)))
            .collect();
        // Length scales: of each moving node, the smallest mean edge of its
        // cells (edges, not volume: a sliver's edges are as long as its
        // neighbours'); of the patch, the median cell's.
        let mut scale = vec![f64::INFINITY; patch.free.len() + patch.sliding.len()];
        for (k, &size) in sizes.iter().enumerate() {
            for &j in &local[k * npc..(k + 1) * npc] {
                if j != usize::MAX {
                    scale[j] = scale[j].min(size);
                }
            }
        }
        sizes.sort_by(f64::total_cmp);
        let h = sizes[sizes.len() / 2];
        let weights = patch.cells.iter().map(|&c| if view.cell_quality[c].q3 < focus_below { focus } else { 1.0 }).collect();
        Some(PatchWork { ctx, view, patch, rule, elements, local, scale, h, weights })
    }

    /// The patch's energy, its sliding nodes projected through `projector` if given.
    fn problem<'a, 'p>(&'a self, projector: Option<&'a Mutex<&'p dyn Projector>>) -> PatchProblem<'a, 'p> {
        PatchProblem {
            dim: self.ctx.dim,
            npc: self.view.npc,
            rule: self.rule,
            elements: &self.elements,
            local: &self.local,
            coords: self.view.coords,
            cells: self.patch.cells.as_slice(),
            all_cells: self.view.cells,
            weights: &self.weights,
            projector,
        }
    }

    /// (invalid cells, min Q3) of the patch with its moving nodes at `pos`.
    fn score(&self, pos: &[[f64; 3]]) -> (usize, f64) {
        let (dim, npc, view) = (self.ctx.dim, self.view.npc, self.view);
        let (mut invalid, mut q3) = (0, f64::INFINITY);
        let mut xe = vec![0.0; npc * dim];
        for (k, &c) in self.patch.cells.iter().enumerate() {
            gather_moved(view.cell(c), &self.local[k * npc..(k + 1) * npc], view.coords, pos, dim, &mut xe);
            let xs = gather(view.straight, view.cell(c), dim);
            let s = self.ctx.state(&xe, &xs);
            invalid += s.invalid() as usize;
            q3 = q3.min(s.q.q3);
        }
        (invalid, q3)
    }

    /// The sliding phase: passes on all moving nodes from the best positions
    /// yet (`best`: score, positions). The sliding nodes are projected onto
    /// their entity at every step, or with `tangent` only after each pass,
    /// having moved in their tangent planes (far fewer projector calls; for
    /// the polish, whose cells are valid, where a pass that leaves a cell
    /// invalid is simply not kept).
    fn slide(
        &self,
        projector: &Mutex<&dyn Projector>,
        pos: &mut Vec<[f64; 3]>,
        best: &mut ((usize, f64), Vec<[f64; 3]>),
        tangent: bool,
    ) {
        for _ in 0..SLIDING_PASSES {
            let unknowns = self.sliding_unknowns(projector, pos);
            let onto = self.problem(Some(projector));
            if tangent {
                let vars = Variables::new(unknowns.clone());
                self.problem(None).minimise(pos, unknowns, 0.05 * self.h, usize::MAX);
                if !onto.project(&vars, pos) {
                    break;
                }
            } else {
                onto.minimise(pos, unknowns, 0.05 * self.h, usize::MAX);
            }
            let score = self.score(pos);
            if better(score, best.0) {
                *best = (score, pos.clone());
            }
            if best.0 .0 == 0 {
                break;
            }
            pos.clone_from(&best.1);
        }
    }

    /// Whether the sliding nodes at `pos` keep the patch's boundary as close
    /// to the geometry between the nodes as `baseline` allows ([`fidelity`]).
    fn faithful(&self, projector: &Mutex<&dyn Projector>, baseline: &Baseline, pos: &[[f64; 3]]) -> bool {
        let (dim, npc, view, patch) = (self.ctx.dim, self.view.npc, self.view, self.patch);
        let nf = patch.free.len();
        let moved: BTreeSet<usize> = patch
            .sliding
            .iter()
            .zip(&pos[nf..])
            .filter(|(&n, x)| view.coords[n * dim..(n + 1) * dim] != x[..dim])
            .map(|(&n, _)| n)
            .collect();
        if moved.is_empty() {
            return true;
        }
        let cells: Vec<&[usize]> = patch.cells.iter().map(|&c| view.cell(c)).collect();
        let mut after = Vec::with_capacity(cells.len());
        for (k, cell) in cells.iter().enumerate() {
            let mut xe = vec![0.0; npc * dim];
            gather_moved(cell, &self.local[k * npc..(k + 1) * npc], view.coords, pos, dim, &mut xe);
            after.push(xe);
        }
        self.ctx.pieces.faithful(projector, &cells, view.cells, view.constraint, &moved, &after, baseline, self.h)
    }

    /// The unknowns of a sliding pass from `pos`: free nodes, and sliding ones in their entity's tangent space.
    fn sliding_unknowns(&self, projector: &Mutex<&dyn Projector>, pos: &[[f64; 3]]) -> Vec<Unknown> {
        let (dim, patch, view) = (self.ctx.dim, self.patch, self.view);
        let mut unknowns: Vec<Unknown> = (0..patch.free.len()).map(|j| Unknown::free(pos[j], dim)).collect();
        for (j, &n) in patch.sliding.iter().enumerate() {
            let at = pos[patch.free.len() + j];
            let s = self.scale[patch.free.len() + j];
            let frame = view.entity(n).and_then(|(edim, tag)| tangent_frame(projector, edim, tag, at, 1e-3 * s, dim));
            unknowns.push(match frame {
                Some(t) => Unknown { base: at, tangents: t, limit: SLIDE_LIMIT * s, on: view.entity(n) },
                None => Unknown::fixed(at),
            });
        }
        unknowns
    }
}

/// The smallest sampled Q3 of the cells (infinity for none).
fn min_q3(q: &[ElementQuality]) -> f64 {
    q.iter().map(|q| q.q3).fold(f64::INFINITY, f64::min)
}

/// (invalid cells, min Q3): fewer invalid cells, or as many and a higher Q3.
fn better(a: (usize, f64), b: (usize, f64)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 > b.1)
}

/// Polish rounds at most, on the cells whose Q3 is below [`POLISH_FACTOR`]
/// times the smallest.
const POLISH_ROUNDS: usize = 8;
const POLISH_FACTOR: f64 = 1.2;
/// Of them, the worst this many at most per round. Seeds near one another
/// merge into one patch: with 16, the polish evaluated 1.1 to 2.1 times as
/// many cells on screw, wrenchnut, component8 and U_Joint_2 at p = 2 and 3,
/// for a smallest Q3 between 0.018 higher (wrenchnut, p = 2) and 0.001
/// lower; with 4, rounds that lift one of several equally bad cells stop
/// the polish early (0.06 lower on screw at p = 2, 0.07 on wrenchnut at 3).
const POLISH_SEEDS: usize = 8;
/// No polish when the smallest Q3 is at least this: the cells are straight
/// or nearly so (Q3 = 1 for an affine cell), and the polish would move nodes
/// by round-off for nothing (six straight tets at p = 10: 723 nodes moved
/// and 2 s spent, for a Q3 that rose in its thirteenth digit).
const POLISH_CEILING: f64 = 0.99;
/// Polishing stops after a round that raised the smallest Q3 by less than
/// this fraction, and a retry around the worst cell alone on the fine
/// sample rule (lattice of order 2p) did not either. The coarse rule may
/// miss where that cell's Q3 is lowest: on component8 at p = 4 the coarse
/// rounds stopped at 0.220 and the retry went on to 0.269; on the other
/// 14 runs of the five STEP parts at p = 2 to 4 it raised the floor by
/// at most 0.0015, or not at all, for one patch of about 25 cells.
const POLISH_GAIN: f64 = 0.01;
/// In the polish, the energy of a cell whose Q3 is below [`POLISH_FACTOR`]
/// times the smallest counts this many times: the energy, an average, then
/// aims at the worst cells. On five STEP parts at p = 2 and 3 it raised
/// the smallest Q3 of nine runs of ten (by up to 0.15) against weight 1,
/// and lowered the tenth by 0.001; weight 10 lowered one by 0.12.
const POLISH_FOCUS: f64 = 5.0;

/// Passes of the sliding phase (optimise, project back, measure).
const SLIDING_PASSES: usize = 3;

/// A sliding node moves at most this times its length scale (the smallest
/// mean edge of its cells) from where a pass starts.
const SLIDE_LIMIT: f64 = 0.3;

/// One moving node: position base + Σ_m t_m tangents[m], with |Σ t_m
/// tangents[m]| ≤ limit; a node sliding on entity `on` is then projected
/// onto it (the tangents span its tangent space at `base`).
#[derive(Debug, Clone)]
struct Unknown {
    base: [f64; 3],
    tangents: Vec<[f64; 3]>,
    limit: f64,
    on: Option<(usize, i32)>,
}

impl Unknown {
    /// A node free to move in every direction.
    fn free(base: [f64; 3], dim: usize) -> Unknown {
        let tangents = (0..dim)
            .map(|d| {
                let mut e = [0.0; 3];
                e[d] = 1.0;
                e
            })
            .collect();
        Unknown { base, tangents, limit: f64::INFINITY, on: None }
    }
    /// A node held where it is.
    fn fixed(base: [f64; 3]) -> Unknown {
        Unknown { base, tangents: Vec::new(), limit: f64::INFINITY, on: None }
    }
}

/// The energy of one patch as a function of its unknowns.
#[derive(Clone, Copy)]
struct PatchProblem<'a, 'p> {
    dim: usize,
    npc: usize,
    rule: &'a SampleRule,
    elements: &'a [ElementSamples],
    /// Per cell-local node of the patch cells: index among the moving nodes, or usize::MAX.
    local: &'a [usize],
    coords: &'a [f64],
    cells: &'a [usize],
    all_cells: &'a [usize],
    /// Per patch cell, the weight of its energy.
    weights: &'a [f64],
    /// Projects the sliding nodes onto their entity (module docs of
    /// [`Unknown`]): every energy is evaluated on the entities, so a step
    /// the line search accepts is valid where the nodes really are.
    projector: Option<&'a Mutex<&'p dyn Projector>>,
}

impl PatchProblem<'_, '_> {
    /// Minimise over `unknowns` (one per moving node) from `pos`, untangling
    /// first if a sample point is inverted; writes the new positions. Takes
    /// at most `budget` L-BFGS iterations in all, and returns how many it took.
    fn minimise(&self, pos: &mut [[f64; 3]], unknowns: Vec<Unknown>, first_step: f64, budget: usize) -> usize {
        let vars = Variables::new(unknowns);
        if vars.n_vars == 0 {
            return 0;
        }
        let mut work = Scratch { trial: pos.to_vec(), ..Scratch::default() };
        let mut xe = vec![0.0; self.npc * self.dim];
        let mut t = vec![0.0; vars.n_vars];
        let mut left = budget;
        let mut jmin = self.min_det(pos, &mut xe);
        for _ in 0..UNTANGLE_PASSES {
            if jmin > UNTANGLED || left == 0 {
                break;
            }
            let delta = (UNTANGLE_EPS * (UNTANGLE_EPS - jmin)).sqrt();
            left -= self.descend(&vars, &mut t, delta, first_step, left, &mut work);
            let last = jmin;
            let mut now = pos.to_vec();
            self.place(&vars, &t, &mut now);
            jmin = self.min_det(&now, &mut xe);
            if jmin < 0.0 && jmin - last <= STALLED * delta {
                // The worst point does not move: it depends on fixed nodes
                // only, or the patch is too small; a larger one may help.
                break;
            }
        }
        if jmin > 0.0 && left > 0 {
            left -= self.descend(&vars, &mut t, 0.0, first_step, left, &mut work);
        }
        self.place(&vars, &t, pos);
        budget - left
    }

    /// L-BFGS on the energy regularised by `delta`, from the variables `t`,
    /// for at most `budget` iterations (and [`MAX_ITERATIONS`]); the iterations taken.
    fn descend(&self, vars: &Variables, t: &mut [f64], delta: f64, first_step: f64, budget: usize, work: &mut Scratch) -> usize {
        let mut f = |t: &[f64], g: &mut [f64]| self.energy_grad(vars, t, g, delta, work);
        lbfgs::minimise(t, &mut f, first_step, MAX_ITERATIONS.min(budget), 1e-6).iterations
    }

    /// The energy at the variables `t` (its gradient into `g`), or None where it is infinite.
    ///
    /// The cells' energies and gradients are computed in parallel (in
    /// chunks of [`CELLS_PER_TASK`], so a small patch stays on its thread),
    /// then summed in the cells' order: the same sums, bit for bit, for any
    /// number of threads. One large patch often takes most of a round.
    fn energy_grad(&self, vars: &Variables, t: &[f64], g: &mut [f64], delta: f64, work: &mut Scratch) -> Option<f64> {
        let (dim, nd) = (self.dim, self.npc * self.dim);
        if !self.place(vars, t, &mut work.trial) {
            return None;
        }
        let n = self.cells.len();
        work.energy.resize(n, 0.0);
        work.grads.resize(n * nd, 0.0);
        let trial = &work.trial;
        work.energy
            .par_iter_mut()
            .zip(work.grads.par_chunks_mut(nd))
            .enumerate()
            .with_min_len(CELLS_PER_TASK)
            .try_for_each_init(
                || vec![0.0; nd],
                |xe, (k, (energy, ge))| {
                    let (cell, loc) = self.cell(k);
                    gather_moved(cell, loc, self.coords, trial, dim, xe);
                    ge.fill(0.0);
                    *energy = self.rule.energy_grad(&self.elements[k], xe, delta, ge)?;
                    Some(())
                },
            )?;
        g.iter_mut().for_each(|v| *v = 0.0);
        let mut total = 0.0;
        for (k, (energy, ge)) in work.energy.iter().zip(work.grads.chunks_exact(nd)).enumerate() {
            let w = self.weights[k];
            total += w * energy;
            for (a, &j) in self.cell(k).1.iter().enumerate() {
                if j == usize::MAX {
                    continue;
                }
                for (m, tm) in vars.unknowns[j].tangents.iter().enumerate() {
                    g[vars.offsets[j] + m] += w * (0..dim).map(|d| tm[d] * ge[a * dim + d]).sum::<f64>();
                }
            }
        }
        Some(total)
    }

    /// The smallest sampled det J of the patch with its moving nodes at `p`.
    fn min_det(&self, p: &[[f64; 3]], xe: &mut [f64]) -> f64 {
        (0..self.cells.len())
            .map(|k| {
                let (cell, loc) = self.cell(k);
                gather_moved(cell, loc, self.coords, p, self.dim, xe);
                self.rule.min_det(&self.elements[k], xe)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The nodes of the patch's `k`-th cell, and their indices among the moving nodes.
    fn cell(&self, k: usize) -> (&[usize], &[usize]) {
        let (npc, c) = (self.npc, self.cells[k]);
        (&self.all_cells[c * npc..(c + 1) * npc], &self.local[k * npc..(k + 1) * npc])
    }

    /// Write the moving nodes' positions at the variables `t` into `out`; false if that is not allowed.
    fn place(&self, vars: &Variables, t: &[f64], out: &mut [[f64; 3]]) -> bool {
        for (j, u) in vars.unknowns.iter().enumerate() {
            let mut x = u.base;
            let mut moved2 = 0.0;
            for (m, tm) in u.tangents.iter().enumerate() {
                let v = t[vars.offsets[j] + m];
                for d in 0..3 {
                    x[d] += v * tm[d];
                }
                moved2 += v * v;
            }
            if moved2.sqrt() > u.limit {
                return false;
            }
            out[j] = x;
        }
        self.project(vars, out)
    }

    /// Project the sliding nodes in `out` onto their entity; false if the projector fails.
    fn project(&self, vars: &Variables, out: &mut [[f64; 3]]) -> bool {
        let dim = self.dim;
        let Some(projector) = self.projector.filter(|_| !vars.on_entity.is_empty()) else { return true };
        let Ok(projector) = projector.lock() else { return false };
        for (&(edim, tag), js) in &vars.on_entity {
            let points: Vec<[f64; 3]> = js.iter().map(|&j| out[j]).collect();
            let mut projected = vec![[f64::NAN; 3]; js.len()];
            if projector.project(edim, tag, &points, &mut projected).is_err() {
                return false;
            }
            for (&j, y) in js.iter().zip(&projected) {
                if !y[..dim].iter().all(|v| v.is_finite()) {
                    return false;
                }
                out[j] = *y;
                if dim == 2 {
                    out[j][2] = 0.0;
                }
            }
        }
        true
    }
}

/// The unknowns of one minimisation and where their variables are.
struct Variables {
    unknowns: Vec<Unknown>,
    /// Index of each unknown's first variable.
    offsets: Vec<usize>,
    n_vars: usize,
    /// The sliding unknowns by entity, in a deterministic order.
    on_entity: BTreeMap<(usize, i32), Vec<usize>>,
}

impl Variables {
    /// The variables of `unknowns`, one per tangent, in order.
    fn new(unknowns: Vec<Unknown>) -> Variables {
        let offsets: Vec<usize> = unknowns
            .iter()
            .scan(0, |acc, u| {
                let o = *acc;
                *acc += u.tangents.len();
                Some(o)
            })
            .collect();
        let n_vars = unknowns.iter().map(|u| u.tangents.len()).sum::<usize>();
        let mut on_entity: BTreeMap<(usize, i32), Vec<usize>> = BTreeMap::new();
        for (j, u) in unknowns.iter().enumerate() {
            if let (Some(e), false) = (u.on, u.tangents.is_empty()) {
                on_entity.entry(e).or_default().push(j);
            }
        }
        Variables { unknowns, offsets, n_vars, on_entity }
    }
}

/// Buffers of the energy evaluations: the moving nodes' trial positions,
/// and each cell's energy and gradient (by its nodes).
#[derive(Default)]
struct Scratch {
    trial: Vec<[f64; 3]>,
    energy: Vec<f64>,
    grads: Vec<f64>,
}

/// Cells of a patch that one task of the energy's evaluation takes at least.
const CELLS_PER_TASK: usize = 32;

/// Index of node `n` among the moving nodes (`free`, then `sliding`), or usize::MAX.
fn position_in(free: &[usize], sliding: &[usize], n: usize) -> usize {
    match free.binary_search(&n) {
        Ok(i) => i,
        Err(_) => sliding.binary_search(&n).map_or(usize::MAX, |i| free.len() + i),
    }
}

/// The node coordinates of one cell: moving nodes from `pos`, the others from `coords`.
fn gather_moved(cell: &[usize], local: &[usize], coords: &[f64], pos: &[[f64; 3]], dim: usize, xe: &mut [f64]) {
    for (a, (&n, &j)) in cell.iter().zip(local).enumerate() {
        let src = if j == usize::MAX { &coords[n * dim..(n + 1) * dim] } else { &pos[j][..dim] };
        xe[a * dim..(a + 1) * dim].copy_from_slice(src);
    }
}

/// `x` (2 or 3 coordinates) as a 3D point.
fn point(x: &[f64]) -> [f64; 3] {
    let mut p = [0.0; 3];
    p[..x.len()].copy_from_slice(x);
    p
}

/// An orthonormal basis of the tangent space of entity (`edim`, `tag`) at
/// `at` (a point on it): the projections of `at + eps e_k` less `at`,
/// orthonormalised, keeping `edim` of them. None if the projector fails or
/// the frame is degenerate.
fn tangent_frame(
    projector: &Mutex<&dyn Projector>,
    edim: usize,
    tag: i32,
    at: [f64; 3],
    eps: f64,
    dim: usize,
) -> Option<Vec<[f64; 3]>> {
    let probes: Vec<[f64; 3]> = (0..dim)
        .map(|k| {
            let mut x = at;
            x[k] += eps;
            x
        })
        .collect();
    let mut out = vec![[f64::NAN; 3]; probes.len()];
    projector.lock().ok()?.project(edim, tag, &probes, &mut out).ok()?;
    let mut vs: Vec<[f64; 3]> = out.iter().map(|y| [y[0] - at[0], y[1] - at[1], y[2] - at[2]]).collect();
    // Gram–Schmidt, largest first.
    let mut frame: Vec<[f64; 3]> = Vec::new();
    for _ in 0..edim {
        for v in vs.iter_mut() {
            for f in &frame {
                let d = v[0] * f[0] + v[1] * f[1] + v[2] * f[2];
                for i in 0..3 {
                    v[i] -= d * f[i];
                }
            }
        }
        let (k, len) = vs
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .enumerate()
            .fold((0, 0.0), |acc, (k, l)| if l > acc.1 { (k, l) } else { acc });
        if len.is_nan() || len <= 0.1 * eps {
            return None;
        }
        let v = vs[k];
        frame.push([v[0] / len, v[1] / len, v[2] / len]);
    }
    Some(frame)
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
    SampleRule::new(tab.dim, tab.n_basis, weights, &tab.grads)
}

/// The node coordinates of one cell.
fn gather(coords: &[f64], cell: &[usize], dim: usize) -> Vec<f64> {
    cell.iter().flat_map(|&n| coords[n * dim..(n + 1) * dim].iter().copied()).collect()
}

/// The mean edge length of a straight element, from its vertices (the
/// first d + 1 nodes).
fn mean_edge(dim: usize, xs: &[f64]) -> f64 {
    let (mut sum, mut n) = (0.0, 0);
    for a in 0..=dim {
        for b in a + 1..=dim {
            sum += (0..dim).map(|d| (xs[a * dim + d] - xs[b * dim + d]).powi(2)).sum::<f64>().sqrt();
            n += 1;
        }
    }
    sum / n as f64
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

    /// An annulus at p = 3 whose interior high-order nodes are jittered
    /// (every cell stays valid), its straight positions, and its basis.
    fn jittered_annulus() -> (HighOrderMesh, Vec<f64>, LagrangeBasis) {
        let case = crate::cases::annulus_2d(0.5, 1.0, 48, 3);
        let (linear, _) = crate::mesh::validate_and_orient(&case.mesh).unwrap();
        let topo = crate::mesh::Topology::new(&linear).unwrap();
        let nodes = NodeSet::new(topo.simplex, 3, NodeSpacing::Optimal);
        let mut mesh = HighOrderMesh::elevate(&linear, &topo, &nodes, NodeSpacing::Optimal).unwrap();
        let straight = mesh.coords.clone();
        let mut seed = 7u64;
        for n in mesh.n_vertices..mesh.n_nodes() {
            if mesh.constraint[n] == NodeConstraint::Free {
                for d in 0..2 {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    mesh.coords[2 * n + d] += 0.003 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
                }
            }
        }
        (mesh, straight, LagrangeBasis::new(&nodes))
    }

    /// The quality and certified verdict of every cell of `mesh`.
    fn cell_states(
        ctx: &PatchContext,
        mesh: &HighOrderMesh,
        straight: &[f64],
    ) -> (Vec<ElementQuality>, Vec<CertifiedJacobian>) {
        (0..mesh.n_cells()).map(|c| ctx.cell_state(&mesh.coords, mesh.cell(c), straight)).map(|s| (s.q, s.cert)).unzip()
    }

    /// The view of `mesh` that a round's patches read.
    fn view_of<'v>(
        mesh: &'v HighOrderMesh,
        straight: &'v [f64],
        cell_quality: &'v [ElementQuality],
        certified: &'v [CertifiedJacobian],
    ) -> MeshView<'v> {
        MeshView {
            coords: &mesh.coords,
            cells: &mesh.cells,
            npc: mesh.nodes_per_cell(),
            constraint: &mesh.constraint,
            straight,
            cell_quality,
            certified,
        }
    }

    #[test]
    fn a_patch_energy_weighs_its_focused_cells_its_gradient_matches_finite_differences_and_threads_do_not_change_it() {
        let (mesh, straight, basis) = jittered_annulus();
        let dim = 2;
        let sampling = quality::sampling_cache(&basis);
        let ctx = PatchContext::new(&basis, &sampling);
        let (q, cert) = cell_states(&ctx, &mesh, &straight);
        let view = view_of(&mesh, &straight, &q, &cert);
        let worst = (0..mesh.n_cells()).min_by(|&a, &b| q[a].q3.total_cmp(&q[b].q3)).unwrap();
        let patch = build_patches(&mesh, &NodeCells::new(&mesh), &[worst], 1).remove(0);
        let mut q3: Vec<f64> = patch.cells.iter().map(|&c| q[c].q3).collect();
        q3.sort_by(f64::total_cmp);
        let (below, focus) = (q3[q3.len() / 2], 5.0);
        let work = PatchWork::new(&ctx, &view, &patch, &ctx.coarse, (below, focus)).unwrap();
        assert!(work.weights.contains(&focus) && work.weights.contains(&1.0), "{:?}", work.weights);
        let node = |n: usize| point(&mesh.coords[n * dim..(n + 1) * dim]);
        // The boundary nodes held (no projector).
        let unknowns: Vec<Unknown> = patch
            .free
            .iter()
            .map(|&n| Unknown::free(node(n), dim))
            .chain(patch.sliding.iter().map(|&n| Unknown::fixed(node(n))))
            .collect();
        let vars = Variables::new(unknowns);
        let problem = work.problem(None);
        let nm = patch.free.len() + patch.sliding.len();
        let mut scratch = Scratch { trial: vec![[0.0; 3]; nm], ..Scratch::default() };
        let t: Vec<f64> = (0..vars.n_vars).map(|k| 1e-3 * (k as f64).sin()).collect();
        let mut g = vec![0.0; vars.n_vars];
        let e = problem.energy_grad(&vars, &t, &mut g, 0.0, &mut scratch).unwrap();
        // The same sum, cell by cell: each cell's energy at the moved nodes times its weight.
        let mut coords = mesh.coords.clone();
        for (j, &n) in patch.free.iter().enumerate() {
            for d in 0..dim {
                coords[n * dim + d] += t[j * dim + d];
            }
        }
        let by_cell: f64 = patch
            .cells
            .iter()
            .enumerate()
            .map(|(k, &c)| {
                let w = if q[c].q3 < below { focus } else { 1.0 };
                w * ctx.coarse.energy(&work.elements[k], &gather(&coords, mesh.cell(c), dim), 0.0).unwrap()
            })
            .sum();
        assert!((e - by_cell).abs() < 1e-12 * by_cell, "{e} against {by_cell}");
        let h = 1e-7;
        for k in (0..vars.n_vars).step_by(5) {
            let mut at = |v: f64| {
                let mut tk = t.clone();
                tk[k] += v;
                problem.energy_grad(&vars, &tk, &mut vec![0.0; vars.n_vars], 0.0, &mut scratch).unwrap()
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            assert!((fd - g[k]).abs() < 1e-5 * (1.0 + fd.abs()), "variable {k}: {fd} against {}", g[k]);
        }
        // A patch of every cell, its cells evaluated in several tasks: the
        // same bits on one thread as on three.
        let all: Vec<usize> = (0..mesh.n_cells()).collect();
        let whole = build_patches(&mesh, &NodeCells::new(&mesh), &all, 1).remove(0);
        assert!(whole.cells.len() >= 3 * CELLS_PER_TASK, "{} cells", whole.cells.len());
        let work = PatchWork::new(&ctx, &view, &whole, &ctx.coarse, (below, focus)).unwrap();
        let held = whole.sliding.iter().map(|&n| Unknown::fixed(node(n)));
        let vars = Variables::new(whole.free.iter().map(|&n| Unknown::free(node(n), dim)).chain(held).collect());
        let t: Vec<f64> = (0..vars.n_vars).map(|k| 2e-3 * (1.7 * k as f64).cos()).collect();
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut g = vec![0.0; vars.n_vars];
                let mut scratch = Scratch { trial: vec![[0.0; 3]; vars.unknowns.len()], ..Scratch::default() };
                let e = work.problem(None).energy_grad(&vars, &t, &mut g, 0.0, &mut scratch).unwrap();
                (e.to_bits(), g.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
            })
        };
        assert!(on(1) == on(3), "the energy or its gradient depends on the number of threads");
    }

    /// Where boundary nodes may slide, the interior nodes get a trial of
    /// L-BFGS iterations first ([`INTERIOR_TRIAL`]; here one). A patch they
    /// lift above the threshold in it goes on alone to convergence: its
    /// boundary nodes stay where they are, and it ends as high as without
    /// the trial. One they cannot lift slides after the trial.
    #[test]
    fn interior_nodes_get_a_trial_before_a_patch_slides() {
        let (mesh, straight, basis) = jittered_annulus();
        let case = crate::cases::annulus_2d(0.5, 1.0, 48, 3);
        let projector: &dyn Projector = &case.projector;
        let projector = Mutex::new(projector);
        let dim = 2;
        let sampling = quality::sampling_cache(&basis);
        let ctx = PatchContext::new(&basis, &sampling);
        let (q, cert) = cell_states(&ctx, &mesh, &straight);
        let view = view_of(&mesh, &straight, &q, &cert);
        // Every cell of the ring: one patch, with boundary nodes on both circles.
        let all: Vec<usize> = (0..mesh.n_cells()).collect();
        let patch = build_patches(&mesh, &NodeCells::new(&mesh), &all, 1).remove(0);
        assert!(!patch.free.is_empty() && !patch.sliding.is_empty());
        let before = view.score(&patch.cells);
        assert_eq!(before.0, 0);

        // The budget: one call takes at most that many iterations.
        let work = PatchWork::new(&ctx, &view, &patch, &ctx.coarse, (0.0, 1.0)).unwrap();
        let node = |n: usize| point(&mesh.coords[n * dim..(n + 1) * dim]);
        let start: Vec<[f64; 3]> = patch.free.iter().chain(&patch.sliding).map(|&n| node(n)).collect();
        let nf = patch.free.len();
        let interior: Vec<Unknown> = (0..start.len())
            .map(|j| if j < nf { Unknown::free(start[j], dim) } else { Unknown::fixed(start[j]) })
            .collect();
        let (mut short, mut long) = (start.clone(), start.clone());
        assert_eq!(work.problem(None).minimise(&mut short, interior.clone(), 0.05 * work.h, 3), 3);
        let taken = work.problem(None).minimise(&mut long, interior, 0.05 * work.h, usize::MAX);
        assert!(taken > 3 && short != long, "{taken} iterations");

        let run = |threshold: f64, trial: usize| {
            let pass = Pass {
                layers: 1,
                rule: &ctx.coarse,
                slide_below: threshold,
                tangent_first: true,
                baseline: None,
                focus: (0.0, 1.0),
                interior_trial: trial,
            };
            let x = ctx.optimize_patch(&view, &patch, pass, Some(&projector)).expect("the patch improves");
            let moved: Vec<[f64; 3]> = x.chunks_exact(dim).map(point).collect();
            let slid = moved[nf..] != start[nf..];
            let mut after = mesh.coords.clone();
            for (&n, x) in patch.free.iter().chain(&patch.sliding).zip(&moved) {
                after[n * dim..(n + 1) * dim].copy_from_slice(&x[..dim]);
            }
            let floor = patch
                .cells
                .iter()
                .map(|&c| ctx.cell_state(&after, mesh.cell(c), &straight).q.q3)
                .fold(f64::INFINITY, f64::min);
            (slid, floor)
        };
        // Reached in the trial: on alone, the boundary kept.
        let reachable = 0.5 * before.1;
        let (slid, floor) = run(reachable, 1);
        let (slid_full, floor_full) = run(reachable, usize::MAX);
        assert!(!slid && !slid_full);
        assert!(floor > before.1 && (floor - floor_full).abs() < 1e-3 * floor_full, "{floor} against {floor_full}");
        // Out of reach: the patch slides.
        let (slid, floor) = run(2.0, 1);
        assert!(slid && floor > before.1, "{} -> {floor}", before.1);
    }

    /// A polish round that does not lift the floor is retried around the
    /// worst cell on the fine rule. Here the coarse rule sees nothing (one
    /// point of weight 0), so no coarse round moves a node: without the
    /// retry the polish stops with the floor where it was, with it the
    /// floor rises.
    #[test]
    fn a_stalled_polish_round_is_retried_on_the_fine_rule() {
        let (mut mesh, straight, basis) = jittered_annulus();
        for (x, s) in mesh.coords.iter_mut().zip(&straight) {
            // Twice the jitter: the floor well below the ceiling.
            *x = s + 2.0 * (*x - s);
        }
        let sampling = quality::sampling_cache(&basis);
        let mut ctx = PatchContext::new(&basis, &sampling);
        let centroid = [1.0 / 3.0, 1.0 / 3.0, 0.0];
        let tab = basis.tabulate(&[centroid]);
        ctx.coarse = SampleRule::new(tab.dim, tab.n_basis, vec![0.0], &tab.grads);
        let polish = |fine_retry: bool| {
            let (mut mesh, mut straight) = (mesh.clone(), straight.clone());
            let (mut q, mut cert) = cell_states(&ctx, &mesh, &straight);
            assert_eq!(invalid_count(&cert), 0);
            let before = min_q3(&q);
            let mut state =
                MeshState { mesh: &mut mesh, straight: &mut straight, cell_quality: &mut q, certified: &mut cert };
            let mut report = OptimizeReport::default();
            let mut stage = Stage::new(&ctx, None, &OptimizeOptions::default(), &state, &mut report);
            stage.fine_retry = fine_retry;
            stage.polish(&mut state);
            (before, min_q3(state.cell_quality), invalid_count(state.certified))
        };
        let (before, without, invalid) = polish(false);
        assert_eq!(invalid, 0);
        assert!(before < 0.9 && without == before, "{before} -> {without}");
        let (_, with, invalid) = polish(true);
        assert_eq!(invalid, 0);
        assert!(with > before * (1.0 + POLISH_GAIN), "{before} -> {with} (without the retry: {without})");
    }

    /// The first rounds on cells that are all valid but below the
    /// threshold: one round, on one-layer patches; the larger second round
    /// is for invalid cells only.
    #[test]
    fn the_second_first_round_runs_only_while_a_cell_is_invalid() {
        let (mut mesh, mut straight, basis) = jittered_annulus();
        let sampling = quality::sampling_cache(&basis);
        let ctx = PatchContext::new(&basis, &sampling);
        let (mut q, mut cert) = cell_states(&ctx, &mesh, &straight);
        assert_eq!(invalid_count(&cert), 0);
        // Every cell below the threshold, before and after a round.
        let opts = OptimizeOptions { threshold: 1.1, ..OptimizeOptions::default() };
        let mut state = MeshState { mesh: &mut mesh, straight: &mut straight, cell_quality: &mut q, certified: &mut cert };
        let mut report = OptimizeReport::default();
        let mut stage = Stage::new(&ctx, None, &opts, &state, &mut report);
        stage.first_rounds(&mut state);
        assert_eq!(invalid_count(state.certified), 0);
        assert_eq!(report.rounds, 1);
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
