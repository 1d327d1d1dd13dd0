//! Load stepping: the increments of the elastic stage, adaptive splitting
//! of the rejected ones, and the predictor of each increment's solution.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;

use super::parallel::{self, Collective, Parallel};
use super::{Stage, Timings};
use crate::assembly::{cell_lines, multigrid_levels, DofMap, ElementKernel, System};
use crate::material::LinearElastic;
use crate::mesh::HighOrderMesh;
use crate::quality;
use crate::reference::{LagrangeBasis, NodeSet};
use crate::solver::{
    DirectOrdering, DirectSolver, ExternalAdapter, FallbackReason, IterativeParams, IterativeSolver, LinearSolver,
    ProductSolve, SolveLog, SolverChoice,
};
use crate::{Error, Result, SolverFailure};

/// How the load increments are driven (paper Table 1).
#[derive(Debug, Clone, PartialEq)]
pub struct Stepping {
    /// Number of load increments n ≥ 1.
    pub increments: usize,
    /// Put the internal force −R(x_n) on the right-hand side (IIL, CIL, Newton).
    pub residual: bool,
    /// Newton–Raphson to ‖R_f‖/‖R_0‖ < tolerance in at most max_iterations (NONLINEAR).
    pub newton: Option<(f64, usize)>,
    pub solver: SolverChoice,
    /// Fill-reducing ordering of the direct solver.
    pub direct_ordering: DirectOrdering,
    /// Adaptive load stepping: step back and halve an increment that makes a
    /// cell invalid (certified check, [`quality::ValidityCheck`]) or whose
    /// assembly or Newton iteration fails.
    pub adaptive: bool,
    /// Adaptive load stepping: at most this many halvings, so the smallest
    /// step is 1/(n·2^max_splits) of the load.
    pub max_splits: usize,
    /// Condense the cell-interior nodes out of the linear systems.
    pub condense: bool,
    /// At the limit of adaptive stepping, stop at the last accepted geometry
    /// and report where ([`IncrementsReport::stopped`]) instead of failing.
    pub finish: bool,
    /// Where the increments run: here, handed to a backend, or as one
    /// process's part of a distributed stage.
    pub parallel: Parallel,
}

impl Stepping {
    /// `increments` equal ILE steps, built-in solver, adaptive stepping on
    /// with [`DEFAULT_MAX_SPLITS`].
    #[cfg(any(test, feature = "internals"))]
    pub fn new(increments: usize) -> Stepping {
        Stepping {
            increments,
            residual: false,
            newton: None,
            solver: SolverChoice::Auto,
            direct_ordering: DirectOrdering::Auto,
            adaptive: true,
            max_splits: DEFAULT_MAX_SPLITS,
            condense: false,
            finish: false,
            parallel: Parallel::Serial,
        }
    }
}

/// Why adaptive load stepping rejected an increment.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepBackReason {
    /// An assembly on the new geometry, or the sampled check after an
    /// increment, met det J ≤ 0 at a quadrature point.
    SampledInvalid,
    /// The certified check found a cell with det J ≤ 0 somewhere after the increment.
    CertifiedInvalid,
    /// Newton–Raphson did not converge, or its residual was not finite.
    NewtonFailed,
    /// An earlier increment, checked only at sample points, had inverted a
    /// cell between them (found by the certified check, or by the assembly
    /// at the start of the next increment): the run went back to load 0 and
    /// certified every increment from there.
    Restarted,
}

impl StepBackReason {
    pub fn name(self) -> &'static str {
        match self {
            StepBackReason::SampledInvalid => "sampled-invalid",
            StepBackReason::CertifiedInvalid => "certified-invalid",
            StepBackReason::NewtonFailed => "newton-failed",
            StepBackReason::Restarted => "restarted",
        }
    }
}

/// One increment that adaptive load stepping rejected and split.
#[derive(Debug, Clone, PartialEq)]
pub struct StepBack {
    /// Load fraction at the start of the rejected increment.
    pub load: f64,
    /// Its size, as a fraction of the whole load.
    pub step: f64,
    pub reason: StepBackReason,
    /// The offending cell, when known.
    pub cell: Option<usize>,
}

/// What [`solve_increments`] reports.
#[derive(Debug, Clone, Default)]
pub struct IncrementsReport {
    /// Unknowns: the free degrees of freedom.
    pub n_free: usize,
    /// Unknowns of the linear systems: `n_free` less the condensed ones.
    pub n_system: usize,
    /// NONLINEAR: relative residual history of each attempted increment.
    pub newton_history: Vec<Vec<f64>>,
    /// The linear solves (rejected increments included).
    pub solves: SolveLog,
    /// Load fraction reached by each accepted increment (the last is 1); its
    /// length is the number of increments taken.
    pub load_fractions: Vec<f64>,
    /// The increments rejected by adaptive load stepping, in order.
    pub step_backs: Vec<StepBack>,
    /// Certified bounds of every cell on the geometry the run ended with,
    /// when its last check was the certified one.
    pub certified: Option<Vec<quality::CertifiedJacobian>>,
    /// With [`Stepping::finish`]: where adaptive stepping gave up; the mesh
    /// is left at the last accepted geometry.
    pub stopped: Option<ElasticStop>,
    /// The solution on the free dofs of the first increment attempted from
    /// load 0, per unit load (accepted or not): a start for another solve
    /// from the same geometry ([`solve_increments_from`]).
    pub first_rate: Option<Vec<f64>>,
}

impl IncrementsReport {
    /// An empty report for the unknowns of `dofs`.
    fn new(dofs: &DofMap) -> IncrementsReport {
        IncrementsReport { n_free: dofs.n_free, n_system: dofs.n_system, ..Default::default() }
    }

    /// Size of each accepted increment, as a fraction of the whole load.
    #[cfg(test)]
    pub fn steps(&self) -> Vec<f64> {
        let mut prev = 0.0;
        self.load_fractions
            .iter()
            .map(|&l| {
                let h = l - prev;
                prev = l;
                h
            })
            .collect()
    }
}

/// The point where adaptive load stepping gave up.
#[derive(Debug, Clone, PartialEq)]
pub struct ElasticStop {
    /// Load fraction reached (the start of the increment that failed).
    pub load: f64,
    pub reason: StepBackReason,
    /// The cell that could not be kept valid, when known.
    pub cell: Option<usize>,
    /// What went wrong, in words.
    pub detail: String,
    /// The optimisation from the stopped geometry (plus the rest of the load
    /// in one linear solve) left cells invalid, and the mesh returned is the
    /// optimisation of the whole load in one linear solve on the straight
    /// mesh instead, which left fewer.
    pub restarted: bool,
}

/// The system of `dofs` (pattern and assembly plan) and the solver `choice`
/// asks for, set up for it. `Auto`:
/// direct in 2D and for small 3D systems ([`crate::solver::auto_direct_max_dofs`]),
/// iterative above. The direct solver orders with `ordering`. In 3D, with
/// the `material` of a linear elastic kernel, the multigrid's first coarse
/// level is that material's stiffness assembled on the coarse mesh
/// ([`multigrid_levels`]). Not in 2D: there the fine cells' interior nodes,
/// condensed out of the fine matrix, are a larger share (3 of 15 at p = 4,
/// against 1 of 35 in 3D), the assembled level is further from PᵀAP, and
/// on the boundary-layer bench's 2D meshes at p = 4 PCG took 7 iterations
/// instead of 6 (stretching 1) and 5 instead of 4 (stretching 300), for a
/// product of 2 × 2 blocks that costs little.
fn make_solver(
    choice: SolverChoice,
    ordering: DirectOrdering,
    mesh: &HighOrderMesh,
    dofs: DofMap,
    material: Option<LinearElastic>,
) -> Result<(System, Box<dyn LinearSolver>)> {
    let iterative = match &choice {
        SolverChoice::External(_) | SolverChoice::Direct => false,
        SolverChoice::Iterative => true,
        SolverChoice::Auto => mesh.dim() == 3 && dofs.n_system > crate::solver::auto_direct_max_dofs(mesh.order),
    };
    if !iterative {
        let system = System::new(mesh, dofs);
        let solver: Box<dyn LinearSolver> = match choice {
            SolverChoice::External(host) => Box::new(ExternalAdapter::new(host, system.pattern())),
            _ => Box::new(DirectSolver::try_new_with(system.pattern(), ordering)?),
        };
        return Ok((system, solver));
    }
    // The multigrid's levels need only the dof map: they are made beside
    // the system's pattern and plan, each thread taking up the other's
    // serial stretches. The free dofs of a node are consecutive: nodal
    // blocks for the smoother, and line blocks through stretched layers.
    let ((system, layout), levels) = rayon::join(
        || System::with_nodes(mesh, dofs.clone()),
        || multigrid_levels(mesh, &dofs, &cell_lines(mesh), material.filter(|_| mesh.dim() == 3)),
    );
    let params = IterativeParams::default();
    let solver =
        IterativeSolver::try_new_with_layout(system.pattern(), mesh.dim(), levels.levels, params, Some(layout))?;
    let solver = solver.with_lines(levels.groups).with_first_coarse_values(levels.first_values);
    Ok((system, Box::new(solver)))
}

/// Move `mesh` by the prescribed boundary displacement `ubar` (one value per
/// dof; only the boundary entries are used) in `stepping.increments` steps:
/// each step assembles the kernel's matrix on the current geometry Ω_n and
/// solves K_ff u_f = −K_fd ū h − R_f(x_n) (the residual only with
/// `residual`) for a step h of the load (1/n unless split), then updates
/// x_{n+1} = x_n + u; with `newton`, it then iterates K Δx = −R until
/// convergence. Each solve starts from a polynomial extrapolation of the
/// previous increments' solutions ([`Predictor`]).
///
/// With `stepping.adaptive`, an increment is rejected when its Newton
/// iteration fails (or meets det J ≤ 0), or when it leaves a cell invalid
/// that was valid at its start ([`quality::ValidityCheck`]); the geometry is
/// then restored and the step halved, at most `max_splits` times per nominal
/// increment (the full step comes back at the next nominal increment). The
/// check after an increment is det J at the quadrature points of degree 2p
/// (cheap: about 1–2 % of an increment at p = 4 in 3D; a cell that has moved
/// too little since it was last evaluated to reach det J ≤ 0 there is
/// skipped, [`quality::ValidityCheck::invalid_cells_screened`]), and the certified one
/// (Bernstein bounds, det J > 0 everywhere) after the last increment and
/// after every increment once the run has stepped back. If the certified
/// check finds a cell that was already inverted before the increment, or an
/// assembly fails on the geometry an increment starts from, an earlier
/// increment inverted it between the sample points: the run starts again
/// from load 0, certifying every increment ([`StepBackReason::Restarted`]).
/// At the limit, or on a failure without `adaptive`, the run fails with
/// [`Error::InvalidElement`] or [`Error::Solver`], and `mesh` is left as it
/// was on entry.
pub fn solve_increments<K: ElementKernel>(
    mesh: &mut HighOrderMesh,
    kernel: &K,
    ubar: &[f64],
    stepping: Stepping,
    timings: &mut Timings,
    tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
) -> Result<IncrementsReport> {
    solve_increments_from(mesh, kernel, ubar, stepping, None, timings, tick)
}

/// [`solve_increments`], with the first increment's solve started from
/// `rate` (free dofs, per unit load; ignored if not of their length), e.g.
/// the [`IncrementsReport::first_rate`] of an earlier run from the same
/// geometry. The solution is the same to the solver's tolerance; a start
/// that already meets it takes no iteration.
pub fn solve_increments_from<K: ElementKernel>(
    mesh: &mut HighOrderMesh,
    kernel: &K,
    ubar: &[f64],
    stepping: Stepping,
    rate: Option<&[f64]>,
    timings: &mut Timings,
    tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
) -> Result<IncrementsReport> {
    let increments = stepping.increments;
    if increments == 0 {
        return Err(Error::InvalidInput("the number of increments must be at least 1".into()));
    }
    if stepping.adaptive && stepping.max_splits > MAX_SPLITS {
        return Err(Error::InvalidInput(format!(
            "max_splits must be at most {MAX_SPLITS}, got {}",
            stepping.max_splits
        )));
    }
    if let Parallel::Lead(backend) = &stepping.parallel {
        let material = kernel.linear_material().ok_or_else(|| {
            Error::InvalidInput(
                "a distributed run curves with the linear or ILE formulation and an isotropic material".into(),
            )
        })?;
        return backend.solve_increments(mesh, material, ubar, &stepping, rate, timings, tick);
    }
    let dofs = if stepping.condense { DofMap::condensed(mesh) } else { DofMap::new(mesh) };
    let collective = stepping.parallel.part();
    if !parallel::any(collective, dofs.n_free > 0 && ubar.iter().any(|&u| u != 0.0)) {
        for (x, u) in mesh.coords.iter_mut().zip(ubar) {
            *x += u;
        }
        let mut out = IncrementsReport::new(&dofs);
        out.load_fractions.push(1.0);
        return Ok(out);
    }
    let start = mesh.coords.clone();
    let rate = rate.filter(|r| r.len() == dofs.n_free);
    let result = step_through(mesh, kernel, ubar, &stepping, dofs, rate, timings, tick);
    if result.is_err() {
        mesh.coords.copy_from_slice(&start);
    }
    result
}

/// What [`solve_increments_from`] with one increment of the linear elastic
/// kernel gives on `mesh` when `rate` is the solution per unit load of that
/// same system (the [`IncrementsReport::first_rate`] of a run from this
/// geometry with that kernel), times the load `scale`, without solving it
/// again: the free dofs move by `rate`·scale and the prescribed ones by
/// `ubar`·scale. False, with `mesh` unchanged, if `rate` is not of the free
/// dofs' length.
pub fn add_rate(mesh: &mut HighOrderMesh, ubar: &[f64], rate: &[f64], scale: f64, condense: bool) -> bool {
    let dofs = if condense { DofMap::condensed(mesh) } else { DofMap::new(mesh) };
    if rate.len() != dofs.n_free || ubar.len() != mesh.coords.len() {
        return false;
    }
    let u: Vec<f64> = rate.iter().map(|r| r * scale).collect();
    let prescribed: Vec<f64> = ubar.iter().map(|b| b * scale).collect();
    dofs.add_to(&mut mesh.coords, &u, Some(&prescribed));
    true
}

/// Largest `max_splits` accepted: the smallest step is then 2⁻³⁰ of a nominal one.
pub const MAX_SPLITS: usize = 30;

/// Default `max_splits` of adaptive load stepping: the smallest step is 1/64 of a nominal one.
pub const DEFAULT_MAX_SPLITS: usize = 6;

/// A rejected increment: why, where, and the message of the error it becomes
/// when it cannot be split any more.
enum Failure {
    Retry {
        reason: StepBackReason,
        cell: Option<usize>,
        detail: String,
    },
    /// The assembly failed on the geometry at the start of the increment
    /// (at `cell` when known).
    AtStart {
        cell: Option<usize>,
        detail: String,
    },
    Fatal(Error),
}

impl From<Error> for Failure {
    fn from(e: Error) -> Failure {
        match e {
            Error::InvalidElement { cell, message } => {
                Failure::Retry { reason: StepBackReason::SampledInvalid, cell, detail: message }
            }
            e => Failure::Fatal(e),
        }
    }
}

/// The increment loop of [`solve_increments`]. The load is counted in ticks
/// of 1/(n·2^splits), so split steps add up exactly to the nominal ones.
#[allow(clippy::too_many_arguments)]
fn step_through<K: ElementKernel>(
    mesh: &mut HighOrderMesh,
    kernel: &K,
    ubar: &[f64],
    stepping: &Stepping,
    dofs: DofMap,
    rate: Option<&[f64]>,
    timings: &mut Timings,
    tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
) -> Result<IncrementsReport> {
    let mut out = IncrementsReport::new(&dofs);
    let n_free = dofs.n_free;
    // The set-up (pattern, assembly plan, ordering or preconditioner) is
    // the elastic stage's: reported as its first increment, not as the
    // projection that came before.
    tick(Stage::Increment, 0, stepping.increments)?;
    let mut ctx = IncrementContext::new(mesh, kernel, stepping, dofs, timings)?;
    out.solves.solver = ctx.solver.name();
    let mut walk = Walk::new(stepping, mesh);
    if let Some(rate) = rate {
        walk.predictor.start_from(rate);
    }
    let mut bufs = Buffers {
        step: vec![0.0; ubar.len()],
        u: vec![0.0; n_free],
        du: vec![0.0; n_free],
        saved: mesh.coords.clone(),
    };
    // The sampled check after each increment, the certified one after the
    // last, after any step back, and after every increment once an inversion
    // has slipped between the sample points. A stop at the limit of adaptive
    // stepping (with `finish`) ends the run at the geometry reached.
    while walk.at < walk.total && out.stopped.is_none() {
        let inc = walk.increment();
        tick(Stage::Increment, inc.k, walk.increments)?;
        for (s, b) in bufs.step.iter_mut().zip(ubar) {
            *s = b * inc.h;
        }
        bufs.saved.copy_from_slice(&mesh.coords);
        walk.predictor.predict_into(inc.h, &mut bufs.u);
        let certified = walk.certify_all || walk.at + inc.len == walk.total || !out.step_backs.is_empty();
        let result = ctx.attempt(mesh, &mut bufs, certified, timings, &mut out);
        if inc.from == 0.0 && out.first_rate.is_none() && bufs.u.iter().all(|x| x.is_finite()) {
            out.first_rate = Some(bufs.u.iter().map(|x| x / inc.h).collect());
        }
        walk.settle(result, &inc, certified, mesh, &bufs, &mut out)?;
    }
    Ok(out)
}

/// One attempted increment: its place in the load, in ticks and as fractions.
struct Increment {
    /// The nominal increment it belongs to, from 0.
    k: usize,
    /// Its length in ticks.
    len: u64,
    /// Load fraction at its start.
    from: f64,
    /// Its size, as a fraction of the whole load.
    h: f64,
}

/// Where the increment loop stands: the load reached in ticks, the splits of
/// the current nominal increment, the predictor and the check policy.
struct Walk {
    increments: usize,
    /// Halvings allowed per nominal increment (0 without adaptive stepping).
    splits: usize,
    adaptive: bool,
    finish: bool,
    /// With `finish`, stop at the first rejection of the whole load in one
    /// linear step ([`Walk::split`]).
    linear_whole: bool,
    /// Ticks per nominal increment, and in the whole load.
    nominal: u64,
    total: u64,
    /// Ticks of load reached, and halvings of the current step.
    at: u64,
    depth: usize,
    /// The cell blamed by the last rejection of the current nominal increment.
    last_rejected: Option<usize>,
    /// The certified check after every increment (an inversion has slipped
    /// between the sample points).
    certify_all: bool,
    predictor: Predictor,
    /// The geometry at load 0, for a restart.
    start: Vec<f64>,
}

impl Walk {
    /// At load 0 of `mesh`, before the first increment.
    fn new(stepping: &Stepping, mesh: &HighOrderMesh) -> Walk {
        let splits = if stepping.adaptive { stepping.max_splits } else { 0 };
        let nominal = 1u64 << splits;
        Walk {
            increments: stepping.increments,
            splits,
            adaptive: stepping.adaptive,
            finish: stepping.finish,
            linear_whole: stepping.increments == 1 && !stepping.residual && stepping.newton.is_none(),
            nominal,
            total: stepping.increments as u64 * nominal,
            at: 0,
            depth: 0,
            last_rejected: None,
            certify_all: false,
            predictor: Predictor::new(),
            start: mesh.coords.clone(),
        }
    }

    /// The next increment to attempt.
    fn increment(&self) -> Increment {
        let len = self.nominal >> self.depth;
        Increment {
            k: (self.at / self.nominal) as usize,
            len,
            from: self.at as f64 / self.total as f64,
            h: len as f64 / self.total as f64,
        }
    }

    /// Act on the outcome of attempting `inc`: accept it, start again from
    /// load 0, split it, stop (setting `out.stopped`) or fail.
    fn settle(
        &mut self,
        result: std::result::Result<Option<usize>, Failure>,
        inc: &Increment,
        certified: bool,
        mesh: &mut HighOrderMesh,
        bufs: &Buffers,
        out: &mut IncrementsReport,
    ) -> Result<()> {
        match result {
            // An earlier increment, checked only at the sample points,
            // inverted cell c between them: start again from the straight
            // mesh with the certified check after every step.
            Ok(Some(c)) if certified && !self.certify_all => self.restart(inc, Some(c), mesh, out),
            Ok(_) => self.accept(&bufs.u, inc, out),
            Err(Failure::Fatal(e)) => return Err(e),
            Err(Failure::AtStart { cell, detail }) if self.finish && self.certify_all => stop(
                out,
                ElasticStop { load: inc.from, reason: StepBackReason::SampledInvalid, cell, detail, restarted: false },
            ),
            Err(Failure::AtStart { cell, detail }) if !self.adaptive || self.certify_all => {
                return Err(Error::invalid_element(
                    cell,
                    format!(
                        "{detail} in increment {} of {}; try more increments or another Poisson ratio",
                        inc.k + 1,
                        self.increments
                    ),
                ))
            }
            // An earlier increment left det J ≤ 0 at a quadrature point of
            // the assembly between the points of the sampled check.
            Err(Failure::AtStart { cell, .. }) => self.restart(inc, cell, mesh, out),
            Err(Failure::Retry { reason, cell, detail }) => {
                mesh.coords.copy_from_slice(&bufs.saved);
                if bufs.u.iter().all(|x| x.is_finite()) {
                    self.predictor.reject(&bufs.u, inc.h);
                }
                return self.split(inc, reason, cell, detail, out);
            }
        }
        Ok(())
    }

    /// Accept `inc`, whose solution on the free dofs is `u`.
    fn accept(&mut self, u: &[f64], inc: &Increment, out: &mut IncrementsReport) {
        self.predictor.accept(u, inc.h);
        self.at += inc.len;
        out.load_fractions.push(self.at as f64 / self.total as f64);
        if self.at.is_multiple_of(self.nominal) {
            (self.depth, self.last_rejected) = (0, None);
        }
    }

    /// Start again from load 0 with the certified check after every
    /// increment, recording `inc` as a step back (cell `cell` when known).
    fn restart(&mut self, inc: &Increment, cell: Option<usize>, mesh: &mut HighOrderMesh, out: &mut IncrementsReport) {
        out.step_backs.push(StepBack { load: inc.from, step: inc.h, reason: StepBackReason::Restarted, cell });
        mesh.coords.copy_from_slice(&self.start);
        out.load_fractions.clear();
        (self.at, self.depth, self.certify_all, self.last_rejected) = (0, 0, true, None);
        self.predictor = Predictor::new();
    }

    /// Halve the rejected `inc` (the geometry is already restored), or at the
    /// limit stop with `finish` (unless Newton–Raphson failed) or fail.
    fn split(
        &mut self,
        inc: &Increment,
        reason: StepBackReason,
        cell: Option<usize>,
        detail: String,
        out: &mut IncrementsReport,
    ) -> Result<()> {
        // With `finish`, a cell that rejects a second step of the same
        // nominal increment, after the first was halved, is one that smaller
        // steps only approach: the optimisation stage takes over now rather
        // than after halving to the limit.
        //
        // So does a cell that inverts when the whole load is one ILE step
        // (one increment asked for): its first half is that linear solution
        // halved, and its second half, on the matrix reassembled there, kept
        // the cell valid in 3 of 20 such runs of the robustness corpus at
        // p = 2 and 3 (min Q3 after the optimisation within 0.02 either way)
        // and in none of 6 on STEP parts, where it cost an assembly and a
        // solve for nothing: stopping there or at load 0 hands the
        // optimisation the same mesh, the whole linear solution (for an
        // isotropic material).
        let again = self.finish && cell.is_some() && cell == self.last_rejected;
        let whole = self.linear_whole && cell.is_some() && inc.from == 0.0 && inc.len == self.total;
        if (self.depth >= self.splits || again || whole) && self.finish && reason != StepBackReason::NewtonFailed {
            stop(out, ElasticStop { load: inc.from, reason, cell, detail, restarted: false });
            return Ok(());
        }
        self.last_rejected = cell;
        if self.depth >= self.splits {
            return Err(self.limit_error(inc, reason, cell, &detail));
        }
        out.step_backs.push(StepBack { load: inc.from, step: inc.h, reason, cell });
        self.depth += 1;
        self.predictor.step_back();
        Ok(())
    }

    /// The error of `inc`, rejected for `reason` when it cannot be split any more.
    fn limit_error(&self, inc: &Increment, reason: StepBackReason, cell: Option<usize>, detail: &str) -> Error {
        let (increments, splits, from) = (self.increments, self.splits, inc.from);
        let mut place = format!("in increment {} of {increments}", inc.k + 1);
        if self.adaptive {
            place += &format!(
                " (load {from:.4} to {:.4}, after halving the step {splits} times: the limit of adaptive stepping)",
                from + inc.h
            );
        }
        match reason {
            StepBackReason::NewtonFailed => Error::solver(
                SolverFailure::NotConverged,
                format!("{detail} {place}; try more increments, or the CIL or ILE formulation"),
            ),
            _ if self.adaptive => Error::invalid_element(
                cell,
                format!(
                    "{detail} {place}; try more increments or another Poisson ratio, or turn adaptive stepping off \
                     to get the mesh with its invalid cells reported (a cell no step keeps valid, e.g. a kept \
                     boundary cap)"
                ),
            ),
            _ => {
                Error::invalid_element(cell, format!("{detail} {place}; try more increments or another Poisson ratio"))
            }
        }
    }
}

/// Stop the run at the last accepted geometry, where adaptive stepping gave up.
fn stop(out: &mut IncrementsReport, stopped: ElasticStop) {
    out.stopped = Some(stopped);
    out.certified = None;
}

/// The vectors of one increment, reused from one to the next.
struct Buffers {
    /// The prescribed values of the increment: ū times its step.
    step: Vec<f64>,
    /// Its solution on the free dofs, started from the predictor.
    u: Vec<f64>,
    /// A Newton–Raphson correction on the free dofs.
    du: Vec<f64>,
    /// The geometry the increment starts from.
    saved: Vec<f64>,
}

/// What an attempt to solve an increment from its products spent before
/// the matrix was needed: its iterations, and the breakdown if any.
#[derive(Debug, Clone, Copy, Default)]
struct Spent {
    iterations: usize,
    breakdown: Option<FallbackReason>,
}

/// A failed assembly (or cell operator) as a rejection of the increment:
/// an invalid cell at its start, or a fatal error.
fn rejection(e: Error) -> Failure {
    match e {
        Error::InvalidElement { cell, message } => Failure::AtStart { cell, detail: message },
        e => Failure::Fatal(e),
    }
}

/// What one increment needs besides the geometry.
struct IncrementContext<'a, K> {
    /// The last assembled system; its buffers are reused.
    system: System,
    solver: Box<dyn LinearSolver>,
    kernel: &'a K,
    residual: bool,
    newton: Option<(f64, usize)>,
    check: Option<quality::ValidityCheck>,
    /// What the sampled check keeps to skip the cells that barely moved.
    margins: quality::SampledMargins,
    /// The other processes of a distributed stage.
    collective: Option<Arc<dyn Collective>>,
}

impl<'a, K: ElementKernel> IncrementContext<'a, K> {
    /// The system (pattern and assembly plan), linear solver and validity
    /// check of the whole run, set up once (timed as `setup`).
    fn new(
        mesh: &HighOrderMesh,
        kernel: &'a K,
        stepping: &Stepping,
        dofs: DofMap,
        timings: &mut Timings,
    ) -> Result<IncrementContext<'a, K>> {
        let t = Instant::now();
        let material = kernel.linear_material();
        let (system, solver) = make_solver(stepping.solver.clone(), stepping.direct_ordering, mesh, dofs, material)?;
        let check = stepping.adaptive.then(|| {
            quality::ValidityCheck::new(LagrangeBasis::new(&NodeSet::new(mesh.simplex, mesh.order, mesh.spacing)))
        });
        timings.setup += t.elapsed().as_secs_f64();
        Ok(IncrementContext {
            system,
            solver,
            kernel,
            residual: stepping.residual || stepping.newton.is_some(),
            newton: stepping.newton,
            check,
            margins: quality::SampledMargins::default(),
            collective: match &stepping.parallel {
                Parallel::Part(c) => Some(c.clone()),
                _ => None,
            },
        })
    }

    /// One increment from the geometry `bufs.saved` (= `mesh.coords` on
    /// entry) with prescribed values `bufs.step`, starting the solve from
    /// `bufs.u`, then the validity check (certified or sampled). Ok(Some(c)):
    /// accepted, but cell c was already invalid at the start.
    fn attempt(
        &mut self,
        mesh: &mut HighOrderMesh,
        bufs: &mut Buffers,
        certified: bool,
        timings: &mut Timings,
        out: &mut IncrementsReport,
    ) -> std::result::Result<Option<usize>, Failure> {
        let r0 = self.linear_step(mesh, bufs, timings, out)?;
        self.newton(mesh, bufs, r0, timings, out)?;
        self.check_cells(mesh, &bufs.saved, certified, timings, out)
    }

    /// The linear solve of the increment on the geometry at its start, added
    /// to `mesh`; returns the norm of its right-hand side, ‖R₀‖.
    fn linear_step(
        &mut self,
        mesh: &mut HighOrderMesh,
        bufs: &mut Buffers,
        timings: &mut Timings,
        out: &mut IncrementsReport,
    ) -> std::result::Result<f64, Failure> {
        let spent = match self.step_by_products(mesh, bufs, timings, out)? {
            Ok(r0) => return Ok(r0),
            Err(spent) => spent,
        };
        let t = Instant::now();
        // det J ≤ 0 here is at the start geometry: no split of this increment helps.
        let assembled = self.system.assemble(mesh, &mesh.coords, self.kernel, &bufs.step, self.residual);
        self.agree_on_assembly(assembled)?;
        timings.assembly += t.elapsed().as_secs_f64();
        let r0 = self.system.rhs_norm().max(f64::MIN_POSITIVE);
        self.solve(mesh, &bufs.step, &mut bufs.u, spent, timings, out)?;
        self.system.dofs().add_to(&mut mesh.coords, &bufs.u, Some(&bufs.step));
        Ok(r0)
    }

    /// The linear step of an ILE increment without its matrix, when the
    /// solver keeps a preconditioner from an earlier one: the products and
    /// the right-hand side cell by cell ([`System::cell_operator`], timed as
    /// assembly), then PCG. Ok(‖R₀‖) when it solved the system; else what
    /// the attempt spent, and `bufs.u` holds the iterate to go on from with
    /// the assembled matrix.
    fn step_by_products(
        &mut self,
        mesh: &mut HighOrderMesh,
        bufs: &mut Buffers,
        timings: &mut Timings,
        out: &mut IncrementsReport,
    ) -> std::result::Result<std::result::Result<f64, Spent>, Failure> {
        let not_tried = Ok(Err(Spent::default()));
        let Some(kernel) = self.kernel.cell_kernel() else { return not_tried };
        if self.residual || self.collective.is_some() || !self.solver.solves_by_products() {
            return not_tried;
        }
        let t = Instant::now();
        let op = self.system.cell_operator(mesh, &mesh.coords, kernel);
        let op = op.map_err(rejection)?;
        self.system.release_values();
        let system = &self.system;
        let n = system.dofs().n_system;
        let mut rhs = vec![0.0; n];
        system.apply_cells(&op, mesh, kernel, None, Some(&bufs.step), &mut rhs);
        rhs.iter_mut().for_each(|v| *v = -*v);
        timings.assembly += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let r0 = rhs.iter().map(|v| v * v).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
        let mut apply = |v: &[f64], y: &mut [f64]| system.apply_cells(&op, mesh, kernel, Some(v), None, y);
        let outcome = self.solver.solve_by_products(&mut apply, &rhs, &mut bufs.u[..n]).map_err(Failure::Fatal)?;
        timings.solve += t.elapsed().as_secs_f64();
        let result = match outcome {
            ProductSolve::Solved(stats) => {
                out.solves.record(&stats);
                out.solves.by_products += 1;
                system.recover_interior(mesh, &bufs.step, &mut bufs.u);
                system.dofs().add_to(&mut mesh.coords, &bufs.u, Some(&bufs.step));
                Ok(r0)
            }
            ProductSolve::NeedsMatrix { iterations, breakdown } => {
                out.solves.assembled_after_products += 1;
                Err(Spent { iterations, breakdown })
            }
        };
        self.system.recycle(op);
        Ok(result)
    }

    /// A failed assembly as a rejection of the increment, the same on every
    /// process of a distributed stage: an error other than an invalid cell
    /// first, else the invalid cell with the smallest index.
    fn agree_on_assembly(&self, assembled: Result<()>) -> std::result::Result<(), Failure> {
        let Some(collective) = self.collective.as_deref() else {
            return assembled.map_err(rejection);
        };
        // Keys: 0 for another error, 1 + the cell's index for an invalid cell.
        let (fatal, invalid) = match assembled {
            Ok(()) => (None, None),
            Err(Error::InvalidElement { cell: Some(c), message }) => (None, Some((c, message))),
            Err(e) => (Some(e), None),
        };
        let invalid = parallel::first_cell(Some(collective), invalid).map(|(g, m)| (1 + g as u64, m));
        let local = fatal.as_ref().map(|e| (0, e.to_string())).or(invalid);
        match (collective.first(local), fatal) {
            (None, _) => Ok(()),
            (Some((0, _)), Some(e)) => Err(Failure::Fatal(e)),
            (Some((0, message)), None) => {
                Err(Failure::Fatal(Error::solver(SolverFailure::External, format!("on another process: {message}"))))
            }
            (Some((key, detail)), _) => Err(Failure::AtStart { cell: Some(key as usize - 1), detail }),
        }
    }

    /// Solve the assembled system into `x` (free dofs), then recover the
    /// condensed cell-interior values with prescribed values `prescribed`.
    fn solve(
        &mut self,
        mesh: &HighOrderMesh,
        prescribed: &[f64],
        x: &mut [f64],
        spent: Spent,
        timings: &mut Timings,
        out: &mut IncrementsReport,
    ) -> std::result::Result<(), Failure> {
        let t = Instant::now();
        let setup = self.solver.setup_seconds();
        let system = &self.system;
        let n = system.dofs().n_system;
        let mut stats =
            self.solver.solve(system.pattern(), system.values(), system.rhs(), &mut x[..n]).map_err(Failure::Fatal)?;
        stats.iterations += spent.iterations;
        stats.fallback = spent.breakdown.or(stats.fallback);
        out.solves.record(&stats);
        system.recover_interior(mesh, prescribed, x);
        // The preconditioner's set-up is timed as set-up, the rest as solving.
        let setup = self.solver.setup_seconds() - setup;
        timings.setup += setup;
        timings.solve += t.elapsed().as_secs_f64() - setup;
        Ok(())
    }

    /// NONLINEAR: Newton–Raphson from the geometry the linear step reached,
    /// K Δx = −R until ‖R‖/‖R₀‖ < tolerance; the history goes to `out`.
    fn newton(
        &mut self,
        mesh: &mut HighOrderMesh,
        bufs: &mut Buffers,
        r0: f64,
        timings: &mut Timings,
        out: &mut IncrementsReport,
    ) -> std::result::Result<(), Failure> {
        let Some((tolerance, max_iterations)) = self.newton else { return Ok(()) };
        let zero = vec![0.0; bufs.step.len()];
        let mut hist = vec![1.0];
        let mut converged = false;
        for _ in 0..max_iterations {
            let t = Instant::now();
            let assembled = self.system.assemble(mesh, &mesh.coords, self.kernel, &zero, true);
            timings.assembly += t.elapsed().as_secs_f64();
            if let Err(e) = assembled {
                out.newton_history.push(hist);
                return Err(e.into());
            }
            let ratio = self.system.rhs_norm() / r0;
            hist.push(ratio);
            if !ratio.is_finite() {
                out.newton_history.push(hist);
                return Err(Failure::Retry {
                    reason: StepBackReason::NewtonFailed,
                    cell: None,
                    detail: "Newton residual is not finite".into(),
                });
            }
            if ratio < tolerance {
                converged = true;
                break;
            }
            bufs.du.fill(0.0);
            self.solve(mesh, &zero, &mut bufs.du, Spent::default(), timings, out)?;
            self.system.dofs().add_to(&mut mesh.coords, &bufs.du, None);
        }
        let last = *hist.last().expect("history starts with 1");
        out.newton_history.push(hist);
        if !converged {
            return Err(Failure::Retry {
                reason: StepBackReason::NewtonFailed,
                cell: None,
                detail: format!(
                    "Newton-Raphson did not converge in {max_iterations} iterations (relative residual {last:.2e})"
                ),
            });
        }
        Ok(())
    }

    /// The validity check after the increment (certified or sampled), against
    /// the geometry `saved` it started from: Err(Retry) when it made a cell
    /// invalid, Ok(Some(c)) when cell c was already invalid at its start.
    fn check_cells(
        &mut self,
        mesh: &HighOrderMesh,
        saved: &[f64],
        certified: bool,
        timings: &mut Timings,
        out: &mut IncrementsReport,
    ) -> std::result::Result<Option<usize>, Failure> {
        let Some(check) = &self.check else { return Ok(None) };
        let t = Instant::now();
        // Only a cell that this increment made invalid rejects it; one that
        // was already invalid at its start is returned to the caller.
        let (mut new, mut old) = (None, None);
        // Certified: the bounds of every cell are kept for the quality stage,
        // which would otherwise compute them again on the final mesh.
        out.certified = certified.then(|| check.certify_cells(&mesh.coords, &mesh.cells));
        let invalid: Vec<usize> = match &out.certified {
            Some(cells) => (0..cells.len()).filter(|&c| cells[c].verdict == quality::Verdict::Invalid).collect(),
            // Sampled: the cells that moved too little since they were last
            // evaluated to have met det J ≤ 0 are skipped, with the same result.
            None => check.invalid_cells_screened(&mesh.coords, &mesh.cells, &mut self.margins).0,
        };
        for c in invalid {
            if check.cell_is_invalid(saved, mesh.cell(c), certified) {
                old = old.or(Some(c));
            } else {
                new = Some(c);
                break;
            }
        }
        timings.check += t.elapsed().as_secs_f64();
        // In a distributed stage, the first cell (in the whole mesh) of any process.
        let collective = self.collective.as_deref();
        let agree = |c: Option<usize>| parallel::first_cell(collective, c.map(|c| (c, String::new()))).map(|(g, _)| g);
        let (new, old) = (agree(new), agree(old));
        match new {
            Some(c) if certified => Err(Failure::Retry {
                reason: StepBackReason::CertifiedInvalid,
                cell: Some(c),
                detail: format!("cell {c} is inverted (certified: det J <= 0 somewhere in it)"),
            }),
            Some(c) => Err(Failure::Retry {
                reason: StepBackReason::SampledInvalid,
                cell: Some(c),
                detail: format!("cell {c} has det J <= 0 at a quadrature point"),
            }),
            None => Ok(old),
        }
    }
}

/// Rates kept by the [`Predictor`]: the fit is a least-squares one from four on.
const PREDICTOR_RATES: usize = 5;

/// Predictor of the increment solutions u_k (free dofs) for steps of any
/// size h_k, from the rates v_k = u_k / h_k (the mean of dx/dλ over
/// increment k) of the last five accepted increments.
///
/// The rate is taken to be a polynomial q(λ) of degree d = min(m − 1, 2)
/// for m known rates, fitted so that its mean over each known increment's
/// interval matches that increment's rate (by least squares when m > d + 1),
/// and the guess is h_k times the mean of q over the new interval. With one
/// rate it is h_k v_(k-1); with two, the secant through them, 2 u_(k-1) −
/// u_(k-2) for equal steps; with three, exact when x(λ) is cubic in the
/// load; with more, a least-squares quadratic, which also reproduces cubic
/// paths exactly and with steps of any size.
///
/// Why least squares. Each rate carries its solve's error, and interpolating
/// three rates multiplies that noise by √19 ≈ 4.4 (weights 3, −3, 1 for
/// equal steps), against √5 ≈ 2.2 for the secant and ≈ 2.1 for the fit to
/// five rates (weights 1.8, 0, −0.8, −0.6, 0.6). On the torus cavity of
/// bench/compare_gmsh.sh (p = 4, ten increments), each later solve starting
/// from the secant had 7.1–7.9e-5 of relative residual, of which the
/// truncation is 7.1–7.6e-5 (a solve to 1e-9 shows it); interpolating three
/// rates cuts that truncation to 3.3–3.5e-6 but, at the solver's tolerance
/// of 1e-5, leaves 2.2–3.2e-5 of noise; the fit to five leaves 1.3–2.1e-5.
/// PCG iterations over the ten increments: 44 (secant), 42 (three rates),
/// 38 (five); on the sphere cavity 33, 36, 32.
///
/// After a step back only the last rate is kept until more increments are
/// known again (the path was just found to bend). An increment retried from
/// the same geometry (after a step back) starts instead from the rejected
/// attempt's solution scaled to the new step: its linear step has the same
/// matrix and a right-hand side scaled by the step, so for the linear
/// formulations that start already solves it.
#[derive(Debug, Clone, Default)]
pub struct Predictor {
    /// The last accepted increments' rates and steps, oldest first.
    rates: VecDeque<(Vec<f64>, f64)>,
    /// The solution per unit load of an attempt from the current start
    /// geometry (a rejected one, or one given), until an increment is accepted.
    here: Option<Vec<f64>>,
}

impl Predictor {
    pub fn new() -> Predictor {
        Predictor { rates: VecDeque::with_capacity(PREDICTOR_RATES), here: None }
    }

    /// The guess for an increment of size `h`, written into `u`.
    pub fn predict_into(&self, h: f64, u: &mut [f64]) {
        if let Some(rate) = &self.here {
            for (x, v) in u.iter_mut().zip(rate) {
                *x = h * v;
            }
            return;
        }
        let weights = self.weights(h);
        u.par_chunks_mut(PREDICT_CHUNK).enumerate().for_each(|(c, part)| {
            let at = c * PREDICT_CHUNK;
            part.fill(0.0);
            for ((v, _), w) in self.rates.iter().zip(&weights) {
                for (x, r) in part.iter_mut().zip(&v[at..]) {
                    *x += h * w * r;
                }
            }
        });
    }

    /// The weights of the known rates (oldest first) in the guess of the
    /// mean rate over the next increment, of size `h`.
    fn weights(&self, h: f64) -> Vec<f64> {
        let m = self.rates.len();
        if m <= 1 {
            return vec![1.0; m];
        }
        let d = (m - 1).min(2);
        // Load in units of h from the end of the last increment: the mean
        // of 1, λ and λ² over [a, b].
        let means = |a: f64, b: f64| [1.0, (a + b) / 2.0, (a * a + a * b + b * b) / 3.0];
        let mut b = 0.0;
        let mut rows = vec![[0.0; 3]; m];
        for (row, (_, step)) in rows.iter_mut().zip(&self.rates).rev() {
            let a = b - step / h;
            *row = means(a, b);
            b = a;
        }
        // Normal equations: w = (AᵀA)⁻¹ e, e the means over [0, 1]; weight_i = A_i · w.
        let mut ata = [[0.0; 3]; 3];
        for row in &rows {
            for i in 0..=d {
                for j in 0..=d {
                    ata[i][j] += row[i] * row[j];
                }
            }
        }
        let e = means(0.0, 1.0);
        let (inv, _) = crate::linalg::inverse(d + 1, &ata);
        let w: Vec<f64> = (0..=d).map(|i| (0..=d).map(|j| inv[i][j] * e[j]).sum()).collect();
        rows.iter().map(|row| (0..=d).map(|i| row[i] * w[i]).sum()).collect()
    }

    /// Record the solution `u` of an accepted increment of size `h`.
    pub fn accept(&mut self, u: &[f64], h: f64) {
        self.here = None;
        let mut v = match self.rates.len() {
            PREDICTOR_RATES => self.rates.pop_front().map(|(v, _)| v).unwrap_or_default(),
            _ => Vec::with_capacity(u.len()),
        };
        v.clear();
        v.extend(u.iter().map(|x| x / h));
        self.rates.push_back((v, h));
    }

    /// Keep only the last rate after a rejected increment.
    pub fn step_back(&mut self) {
        while self.rates.len() > 1 {
            self.rates.pop_front();
        }
    }

    /// Record the solution `u` of an increment of size `h` rejected from the
    /// geometry the next attempt starts from.
    pub fn reject(&mut self, u: &[f64], h: f64) {
        self.here = Some(u.iter().map(|x| x / h).collect());
    }

    /// Start the next increment from `rate` (per unit load), a solution from
    /// the geometry it starts from.
    pub fn start_from(&mut self, rate: &[f64]) {
        self.here = Some(rate.to_vec());
    }
}

/// Entries of the guess per parallel task of [`Predictor::predict_into`].
const PREDICT_CHUNK: usize = 1 << 14;

#[cfg(test)]
mod tests {
    use super::*;

    /// x(λ) = a λ + b λ² + c λ³ per dof: the increment over [λ0, λ0 + h].
    fn increment(l0: f64, h: f64, c: [f64; 3]) -> Vec<f64> {
        let (a, b) = ([1.0, -2.0, 0.5], [3.0, 0.25, -4.0]);
        let x = |l: f64, i: usize| a[i] * l + b[i] * l * l + c[i] * l * l * l;
        (0..3).map(|i| x(l0 + h, i) - x(l0, i)).collect()
    }

    /// The largest error of the predictions along a path of `steps` from
    /// the `from`-th on.
    fn worst_prediction(steps: &[f64], cubic: [f64; 3], from: usize) -> f64 {
        let mut p = Predictor::new();
        let (mut l, mut worst) = (0.0, 0.0f64);
        let mut u = vec![0.0; 3];
        for (k, &h) in steps.iter().enumerate() {
            p.predict_into(h, &mut u);
            let exact = increment(l, h, cubic);
            if k >= from {
                worst = u.iter().zip(&exact).fold(worst, |m, (g, e)| m.max((g - e).abs()));
            }
            p.accept(&exact, h);
            l += h;
        }
        worst
    }

    const UNEQUAL: [f64; 9] = [0.25, 0.125, 0.0625, 0.0625, 0.25, 0.03125, 0.1, 0.05, 0.05];

    #[test]
    fn predictor_is_exact_on_quadratic_paths_from_two_increments_on() {
        assert!(worst_prediction(&UNEQUAL, [0.0; 3], 2) < 1e-13);
        // and not from one increment: the guess is then the last rate.
        assert!(worst_prediction(&UNEQUAL, [0.0; 3], 1) > 1e-3);
    }

    #[test]
    fn predictor_is_exact_on_cubic_paths_from_three_increments_on_with_any_steps() {
        let cubic = [2.0, -1.5, 0.75];
        // Three rates interpolated, then least squares over up to five.
        assert!(worst_prediction(&UNEQUAL, cubic, 3) < 1e-12, "{}", worst_prediction(&UNEQUAL, cubic, 3));
        // The secant alone (two rates) is not.
        assert!(worst_prediction(&UNEQUAL[..3], cubic, 2) > 1e-4);
    }

    #[test]
    fn predictor_weighs_five_equal_steps_by_least_squares_and_keeps_only_five() {
        // Rate e_j in increment j: the guess per unit load is the weights.
        let h = 0.1;
        let mut p = Predictor::new();
        let mut u = vec![0.0; 6];
        for j in 0..6 {
            let mut rate = vec![0.0; 6];
            rate[j] = h;
            p.accept(&rate, h);
        }
        p.predict_into(h, &mut u);
        // Least-squares quadratic through the last five midpoints, at the next
        // one (numpy.polyfit weights): 0.6, −0.6, −0.8, 0, 1.8, oldest first.
        let expected = [0.0, 0.6, -0.6, -0.8, 0.0, 1.8];
        for (g, e) in u.iter().zip(expected) {
            assert!((g / h - e).abs() < 1e-12, "{u:?}");
        }
        // Their noise gain, √Σw² ≈ 2.1, against √19 ≈ 4.4 for three rates.
        let gain = u.iter().map(|x| (x / h).powi(2)).sum::<f64>().sqrt();
        assert!((gain - 4.6f64.sqrt()).abs() < 1e-12, "{gain}");
    }

    #[test]
    fn secant_predictor_with_equal_steps_is_two_u1_minus_u2_and_resets_after_a_step_back() {
        let mut p = Predictor::new();
        let mut u = vec![9.0; 2];
        p.predict_into(0.1, &mut u);
        assert_eq!(u, [0.0, 0.0]);
        p.accept(&[1.0, 2.0], 0.1);
        p.predict_into(0.1, &mut u);
        assert!((u[0] - 1.0).abs() < 1e-15 && (u[1] - 2.0).abs() < 1e-15);
        p.accept(&[1.5, 2.0], 0.1);
        p.predict_into(0.1, &mut u);
        assert!((u[0] - 2.0).abs() < 1e-14 && (u[1] - 2.0).abs() < 1e-14, "{u:?}");
        p.accept(&[2.5, 2.0], 0.1);
        p.accept(&[1.5, 2.0], 0.1);
        // After a step back: the last rate only, scaled by the step ratio.
        p.step_back();
        p.predict_into(0.05, &mut u);
        assert!((u[0] - 0.75).abs() < 1e-14 && (u[1] - 1.0).abs() < 1e-14, "{u:?}");
    }

    #[test]
    fn a_retried_increment_starts_from_the_rejected_solution_scaled_until_one_is_accepted() {
        let mut p = Predictor::new();
        let mut u = vec![9.0; 2];
        p.accept(&[1.0, 2.0], 0.1);
        // Rejected from the geometry the retry starts from: its solution, scaled.
        p.reject(&[3.0, -1.0], 0.2);
        p.step_back();
        p.predict_into(0.1, &mut u);
        assert!((u[0] - 1.5).abs() < 1e-15 && (u[1] + 0.5).abs() < 1e-15, "{u:?}");
        // Accepted: the history again, 2 u1 - u2 for equal steps.
        p.accept(&[1.5, -0.5], 0.1);
        p.predict_into(0.1, &mut u);
        assert!((u[0] - 2.0).abs() < 1e-14 && (u[1] + 3.0).abs() < 1e-14, "{u:?}");
        // A start given for the first increment.
        let mut q = Predictor::new();
        q.start_from(&[4.0, 2.0]);
        q.predict_into(0.5, &mut u);
        assert_eq!(u, [2.0, 1.0]);
    }

    #[test]
    fn steps_are_the_differences_of_the_load_fractions() {
        let r = IncrementsReport { load_fractions: vec![0.5, 0.75, 1.0], ..Default::default() };
        assert_eq!(r.steps(), [0.5, 0.25, 0.25]);
    }
}
