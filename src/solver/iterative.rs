//! The iterative solver: PCG preconditioned by the p-multigrid V-cycle of
//! [`super::pmg`], with a direct fallback for indefinite systems.
//!
//! Decisions (sphere_in_box_3d, ILE, ν = 0.45, 2 cores):
//! - Tolerance ‖r‖ ≤ 1e-5 ‖b‖ ([`PcgParams`]): the nodes then agree with the
//!   direct solver's to ~1e-6 of the mesh size (tests/solvers.rs checks 2e-5),
//!   far below the geometric error of the curved boundary; 1e-8 took 27
//!   iterations at p = 4 against 16.
//! - The coarse levels (Galerkin products, coarsest factor) are built on the
//!   first matrix and reused: rebuilding them gave the same iteration counts
//!   for ~1 s more per increment at 106k unknowns.
//! - The fine smoother (its single-precision matrix, diagonal blocks and
//!   λ_max) is kept for the next matrices too: with its own
//!   single-precision matrix, the V-cycle is that of the matrix it was
//!   built for, as positive definite as when it was built, whatever the
//!   current matrix (PCG's products use the current one, so the solution is
//!   that of the current system). A solve with a kept smoother gets the
//!   iterations that the last fresh smoother's rate (residual digits per
//!   iteration) gives for its digits, plus [`REUSE_SLACK`]; past them, PCG
//!   goes on from its iterate with a smoother built for the matrix, which
//!   is kept in turn. Ten ILE increments at p = 4 on the sphere cavity (68k
//!   unknowns): the same 1–2 iterations per later increment, and about
//!   0.05 s less of the 0.3 s each (the single-precision copy 0.022 s, the
//!   power steps 0.023 s, the blocks 0.004 s). A matrix with a new sliver
//!   cell (tests/solvers.rs) took 168 iterations with the first matrix's
//!   smoother, against 8 for that one: hence the budget. A rebuilt
//!   smoother's λ_max power iteration restarts from the previous dominant
//!   vector: 2 steps, not 12.
//! - Stretched boundary layers: with nodal blocks only, the iterations grew
//!   with the stretching (2D layers at p = 4: 24 to 28 against 6 on an
//!   isotropic mesh). The caller's lines of stretched cells
//!   ([`Self::with_lines`]) make the smoother's blocks there whole lines of
//!   nodes, factored for every matrix: 3 to 11 iterations at stretching 100
//!   to 1000 in 2D and 3D, no more than 1.22 times the isotropic mesh's.
//! - Chebyshev degree 3 on [λ_max/30, λ_max]: at p = 4 degrees 2/3/4 took
//!   34/26/21 iterations (tolerance 1e-8), i.e. 170/182/189 products: flat, so 3.
//! - The V-cycle's fine-level products use a single-precision nodal-block copy
//!   of the matrix ([`BlockSym32`]: 4.4 bytes per entry against 12); PCG's own
//!   products stay in double precision, so the converged solution is not
//!   limited by single precision. Same iteration counts.
//! - Breakdowns (tests/solvers.rs: a cube whose second matrix has a sliver cell of
//!   quality 1e-5): the smoother's λ_max estimate, warm-started from the
//!   previous matrix, missed the sliver's mode, the V-cycle was indefinite
//!   and PCG stopped with rᵀz < 0 or did not converge. PCG now stops on
//!   rᵀz ≤ 0, a non-finite residual, stagnation ([`STAGNATION_WINDOW`]) or,
//!   in a warm-started solve slower than 2k + [`CHECKPOINT_SLACK`]
//!   iterations (k those of the previous solve), a fresh estimate above the
//!   smoother's by [`UNDERESTIMATE_FACTOR`]. The preconditioner is then
//!   rebuilt in its safe mode ([`Chebyshev::try_new_safe`]: Gershgorin bound,
//!   double precision, coarse levels rebuilt; SPD by construction, 1.5–2×
//!   the iterations) and PCG restarts from its last iterate. None of the
//!   checks changes the iterates, so a solve that does not fall back is
//!   bitwise the same as without them.
//! - Indefinite tangents (CIL, NONLINEAR): PCG reports pᵀAp ≤ 0 (or a
//!   diagonal block is not positive definite); that, or a failed restart,
//!   sends systems of at most [`FALLBACK_DIRECT_MAX_DOFS`] unknowns to the
//!   direct solver, and larger ones return [`Error::Solver`].
//!   [`SolveStats`] says which solver produced the solution and why.
//!
//! Measured 2026-11-23, other jobs paused (`hocurve bench`, bench/README.md),
//! one increment from a zero start: iterations 10, 9, 13–14, 12, 16 at
//! p = 2..6, the same at every mesh size; solve time ∝ N^0.94 at p = 4 from
//! 2,000 to 1,161,402 unknowns, which five increments curve in 62–66 s and 6.8 GB.
//! With static condensation: iterations 10, 9, 13, 9–10, 13;
//! solve ∝ N^0.97; the 1,161,402 unknowns in 40.6 s and 6.3 GB.
//! The solve is dominated by products with the fine matrix (memory-bound); at
//! p = 5–6 the numeric set-up of the coarse levels in the first increment
//! (Galerkin products, coarsest factorisation) is about half of it.

use super::bsr::{BlockSym32, Operator};
use super::lines::LineFactors;
use super::pcg::{axpby_in_place, dot, pcg, BlockJacobi, PcgFailure, PcgParams, SymmetricOperator, WithValues};
use super::pmg::{Chebyshev, ChebyshevParams, Hierarchy, VCycle};
use super::SparseRows;
use super::{DirectSolver, FallbackReason, LinearSolver, NodeGroups, ProductSolve, SolveStats, SolvedBy, SymmetricCsc};
use crate::{Error, Result, SolverFailure};

/// Largest system the iterative solver hands to the direct one when PCG breaks
/// down (an indefinite CIL or Newton tangent); above it the error is returned.
/// About 10 s and 2 GB for a 3D p = 4 factorisation.
pub const FALLBACK_DIRECT_MAX_DOFS: usize = 150_000;

/// Settings of [`IterativeSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterativeParams {
    pub pcg: PcgParams,
    pub smoother: ChebyshevParams,
    /// Keep the coarse operator and its factor from the first matrix for all
    /// later ones.
    pub reuse_coarse: bool,
    /// Keep the fine smoother of one matrix for the next ones, within an
    /// iteration budget ([`REUSE_SLACK`]); only with the single-precision
    /// copy, which keeps the matrix it was built for.
    pub reuse_smoother: bool,
    pub fallback_max_dofs: usize,
    /// Fine-level smoothing and residuals of the V-cycle with a single-precision
    /// copy of the matrix ([`BlockSym32`]).
    pub single_precision_smoother: bool,
    /// With that copy, PCG's own products too; the solution it converges to
    /// is then checked with the double-precision matrix, and PCG goes on
    /// from it with that matrix if its true residual is still above the
    /// tolerance ([`single_then_checked`]).
    pub single_precision_krylov: bool,
    /// Stop PCG when its smallest residual of this many iterations is not
    /// 10 % below that of the as many before ([`super::pcg::pcg`]); 0: never.
    pub stagnation_window: usize,
    /// When PCG breaks down (rᵀz ≤ 0, stagnation, a non-finite residual, a
    /// preconditioner that cannot be built), rebuild the preconditioner in
    /// its safe mode and restart PCG from the last iterate before any
    /// direct fallback.
    pub safe_restart: bool,
    /// Build the preconditioner in its safe mode from the start (slower,
    /// for systems known to break the default one).
    pub safe_preconditioner: bool,
}

impl Default for IterativeParams {
    fn default() -> Self {
        IterativeParams {
            pcg: PcgParams::default(),
            smoother: ChebyshevParams::default(),
            reuse_coarse: true,
            reuse_smoother: true,
            fallback_max_dofs: FALLBACK_DIRECT_MAX_DOFS,
            single_precision_smoother: true,
            single_precision_krylov: true,
            stagnation_window: STAGNATION_WINDOW,
            safe_restart: true,
            safe_preconditioner: false,
        }
    }
}

/// Default [`IterativeParams::stagnation_window`]. Normal solves take 8–100
/// iterations. Measured on the 6×6×6 cube of `tests/common` with four sliver
/// cells of quality 1e-5 at p = 4: 375 iterations, 677 with the safe
/// preconditioner, whose residual fell by only 10–20 % over some windows of
/// 50 iterations but by 40 % or more over every window of 100.
pub const STAGNATION_WINDOW: usize = 100;

/// A warm-started solve that is still running after 2·k + `CHECKPOINT_SLACK`
/// iterations, k those of the previous solve, checks its smoother's λ_max
/// estimate against a fresh one ([`Chebyshev::cold_estimate`]).
pub const CHECKPOINT_SLACK: usize = 10;

/// The warm-started estimate is deemed too low when a fresh one exceeds it
/// by this factor (the smoother is positive definite up to 1.1·(1 + 1/30)
/// = 1.14 times it).
pub const UNDERESTIMATE_FACTOR: f64 = 1.05;

/// A solve with a kept smoother may take this many iterations more than
/// the last fresh smoother's rate (residual digits per iteration) gives for
/// the digits it has to gain; then its smoother is built afresh. One
/// iteration costs more than the rebuild (0.07 s against 0.05 s at p = 4).
pub const REUSE_SLACK: usize = 1;

/// How the preconditioner is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// Single-precision fine products, λ_max by power iteration warm-started
    /// from the previous matrix, coarse levels reused.
    Fast,
    /// Double precision, λ_max from the Gershgorin bound of D⁻¹A at every
    /// level, coarse levels rebuilt from this matrix: SPD by construction.
    Safe,
}

/// A PCG attempt that did not converge.
struct Breakdown {
    reason: FallbackReason,
    iterations: usize,
    error: Error,
}

impl Breakdown {
    fn setup(error: Error) -> Breakdown {
        Breakdown { reason: FallbackReason::PreconditionerSetup, iterations: 0, error }
    }

    fn from_pcg(f: PcgFailure) -> Breakdown {
        let (reason, iterations) = match &f {
            PcgFailure::PreconditionerNotPositive { iteration, .. } => {
                (FallbackReason::PreconditionerNotPositive, iteration - 1)
            }
            PcgFailure::MatrixNotPositive { iteration, .. } => (FallbackReason::MatrixNotPositive, iteration - 1),
            PcgFailure::NonFinite { iteration } => (FallbackReason::NonFinite, *iteration),
            PcgFailure::Stagnated { iteration, .. } => (FallbackReason::Stagnation, *iteration),
            PcgFailure::NotConverged { iterations, .. } => (FallbackReason::NotConverged, *iterations),
            PcgFailure::Stopped { iteration } => (FallbackReason::NotConverged, *iteration),
            PcgFailure::Preconditioner(_) => (FallbackReason::PreconditionerSetup, 0),
        };
        Breakdown { reason, iterations, error: f.into() }
    }

    /// The kind of solver failure this breakdown is.
    fn kind(&self) -> SolverFailure {
        match &self.error {
            Error::Solver { kind, .. } => *kind,
            _ => SolverFailure::Setup,
        }
    }

    fn message(&self) -> String {
        match &self.error {
            Error::Solver { message, .. } => message.clone(),
            e => e.to_string(),
        }
    }

    /// Whether a preconditioner built in the safe mode may succeed (not for
    /// an indefinite matrix, nor for a slow but steady convergence).
    fn worth_a_restart(&self) -> bool {
        matches!(
            self.reason,
            FallbackReason::PreconditionerNotPositive
                | FallbackReason::Stagnation
                | FallbackReason::EigenvalueUnderestimated
                | FallbackReason::NonFinite
                | FallbackReason::PreconditionerSetup
        )
    }
}

/// PCG with a p-multigrid preconditioner (or Chebyshev–Jacobi alone without a
/// coarse level). Symbolic set-up in [`IterativeSolver::try_new`]; per matrix,
/// the smoother (diagonal blocks, λ_max) and, unless reused, the coarse
/// operator. If PCG fails (indefinite matrix, no convergence) on a system of
/// at most `fallback_max_dofs` unknowns, that system is solved directly.
pub struct IterativeSolver {
    op: SymmetricOperator,
    block: usize,
    coarse: Option<Hierarchy>,
    params: IterativeParams,
    direct: Option<DirectSolver>,
    /// Dominant vector of D⁻¹A of the previous matrix.
    power: Option<Vec<f64>>,
    /// Single-precision copy of the fine matrix for the preconditioner's
    /// products (when `params.single_precision_smoother` and the pattern is in
    /// nodal blocks).
    fine32: Option<BlockSym32>,
    /// PCG iterations of the last solve with the default preconditioner.
    last_iterations: Option<usize>,
    /// Line blocks of the fine level's smoother ([`Self::with_lines`]).
    lines: Option<NodeGroups>,
    /// The fine smoother of an earlier matrix, kept for the next solve
    /// ([`IterativeParams::reuse_smoother`]); its single-precision matrix is `fine32`.
    kept: Option<Chebyshev>,
    /// Residual digits per iteration of the last solve with a fresh smoother.
    fresh_rate: Option<f64>,
    /// Seconds spent building preconditioners ([`LinearSolver::setup_seconds`]).
    setup_seconds: f64,
}

impl IterativeSolver {
    /// `block`: size of the diagonal blocks of the smoother (the spatial
    /// dimension when the free dofs of a node are consecutive, else 1).
    /// `levels`: per coarse level, finest first, the prolongation P_k to the
    /// level above (P_1 has a row per unknown of `pattern`) and the
    /// lower-triangle pattern of P_kᵀ A_{k−1} P_k; empty for Chebyshev–Jacobi alone.
    pub fn try_new(
        pattern: &SymmetricCsc,
        block: usize,
        levels: Vec<(SparseRows, SymmetricCsc)>,
        params: IterativeParams,
    ) -> Result<IterativeSolver> {
        Self::try_new_with_layout(pattern, block, levels, params, None)
    }

    /// [`Self::try_new`] given the nodal-block layout of `pattern` when the
    /// caller built the pattern in that layout and kept it (per node J, the
    /// nodes I ≥ J coupled to it, ascending, J first: what the solver would
    /// otherwise read back from the pattern and check). A layout of the
    /// wrong number of nodes is ignored.
    pub fn try_new_with_layout(
        pattern: &SymmetricCsc,
        block: usize,
        levels: Vec<(SparseRows, SymmetricCsc)>,
        params: IterativeParams,
        layout: Option<Vec<Vec<u32>>>,
    ) -> Result<IterativeSolver> {
        if let Some((p, _)) = levels.first() {
            if p.n_rows != pattern.n {
                return Err(Error::solver(
                    SolverFailure::Setup,
                    format!("P has {} rows for {} unknowns", p.n_rows, pattern.n),
                ));
            }
        }
        let coarse = if levels.is_empty() { None } else { Some(Hierarchy::try_new(levels, block, params.smoother)?) };
        // A pattern not in nodal blocks (an external caller's) keeps double
        // precision. The layout is read once for both operators.
        let upper = match layout.filter(|nodes| block > 1 && nodes.len() * block == pattern.n) {
            Some(nodes) => {
                debug_assert_eq!(Some(&nodes), super::bsr::nodal_blocks(pattern, block).ok().as_ref());
                Some(nodes)
            }
            None => super::bsr::nodal_blocks(pattern, block).ok(),
        };
        let fine32 = match (&upper, params.single_precision_smoother) {
            (Some(upper), true) => BlockSym32::from_nodal_blocks(upper, block).ok(),
            _ => None,
        };
        Ok(IterativeSolver {
            fine32,
            op: SymmetricOperator::from_nodal_blocks(pattern, block, upper.filter(|_| block > 1))?,
            block,
            coarse,
            params,
            direct: None,
            power: None,
            last_iterations: None,
            lines: None,
            kept: None,
            fresh_rate: None,
            setup_seconds: 0.0,
        })
    }

    /// Smooth in line blocks: `lines[0]` on the fine level, `lines[k]` on
    /// coarse level k (groups of nodes, nodal blocks of size `block`; the
    /// coarsest level, factored, needs none). The safe mode of a restart
    /// keeps nodal blocks.
    /// The first coarse level's operator assembled on its own mesh, for the
    /// first set-up of the coarse levels ([`Hierarchy::set_first_values`]).
    pub fn with_first_coarse_values(mut self, values: Option<Vec<f64>>) -> IterativeSolver {
        if let (Some(c), Some(values)) = (&mut self.coarse, values) {
            c.set_first_values(values);
        }
        self
    }

    pub fn with_lines(mut self, mut lines: Vec<NodeGroups>) -> IterativeSolver {
        if lines.is_empty() {
            return self;
        }
        let coarse = lines.split_off(1);
        self.lines = lines.pop().filter(|g| !g.is_empty());
        if let Some(c) = &mut self.coarse {
            c.set_lines(coarse);
        }
        self
    }

    /// The line blocks of the fine level factored for the matrix (`pattern`, `values`).
    fn line_blocks(
        &self,
        pattern: &SymmetricCsc,
        values: &[f64],
    ) -> std::result::Result<Option<LineFactors>, Breakdown> {
        self.lines
            .as_ref()
            .map(|g| LineFactors::try_new(pattern, values, self.block, g).map_err(not_positive))
            .transpose()
    }

    /// The decimal digits by which PCG must reduce the residual of the start
    /// `x`, log₁₀(‖b − A x‖ / (rtol ‖b‖)): at most 0 if `x` solves the system
    /// already; infinite for b = 0 (PCG's own case). With it, the residual
    /// b − A x when it took a product to find (a nonzero start), for PCG.
    fn digits_to_gain(
        &self,
        pattern: &SymmetricCsc,
        values: &[f64],
        rhs: &[f64],
        x: &[f64],
    ) -> (f64, Option<Vec<f64>>) {
        let b = rhs.iter().map(|v| v * v).sum::<f64>().sqrt();
        if b == 0.0 {
            return (f64::INFINITY, None);
        }
        if x.iter().all(|&v| v == 0.0) {
            return ((b / (self.params.pcg.rtol * b)).log10(), None);
        }
        let mut r = vec![0.0; rhs.len()];
        self.op.with(pattern, values).matvec_into(x, &mut r);
        axpby_in_place(1.0, rhs, -1.0, &mut r);
        let norm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        ((norm / (self.params.pcg.rtol * b)).log10(), Some(r))
    }

    /// The iterations a solve with the kept smoother may take to gain
    /// `digits` ([`REUSE_SLACK`]); None if no smoother is kept.
    fn reuse_budget(&self, digits: f64) -> Option<usize> {
        let rate = self.fresh_rate?;
        self.kept.as_ref()?;
        Some((digits / rate).ceil().max(1.0) as usize + REUSE_SLACK)
    }

    /// One PCG attempt with the preconditioner built in `mode`, or, in the
    /// fast mode with `budget` iterations, with the kept smoother first;
    /// `residual` is b − A x of the start when already computed.
    #[allow(clippy::too_many_arguments)]
    fn try_pcg_solve(
        &mut self,
        pattern: &SymmetricCsc,
        values: &[f64],
        rhs: &[f64],
        x: &mut [f64],
        mode: Mode,
        budget: Option<usize>,
        residual: Option<Vec<f64>>,
    ) -> std::result::Result<usize, Breakdown> {
        let kept = self.kept.take().filter(|_| mode == Mode::Fast && budget.is_some());
        let reused = kept.is_some();
        let start = self.power.take();
        let warm = start.is_some();
        let smoother = self.smoother_for(pattern, values, mode, kept, start)?;
        let exact = self.op.with(pattern, values);
        let fine: &dyn Operator = match (&self.fine32, mode) {
            (Some(f), Mode::Fast) => f,
            _ => &exact,
        };
        // The copy holds this matrix unless a kept smoother's (an earlier one).
        let single = mode == Mode::Fast && !reused && self.fine32.is_some() && self.params.single_precision_krylov;
        // A warm-started estimate can miss a mode that the new matrix has
        // and the previous one had not (a nearly degenerate cell): a slow
        // solve compares it with a fresh one (not changing the iterates).
        let checkpoint = match (mode, warm, reused) {
            (Mode::Fast, true, false) => self.last_iterations.map(|k| 2 * k + CHECKPOINT_SLACK),
            _ => None,
        };
        let steps = self.params.smoother.power_iterations;
        let mut fresh = None;
        let budget = budget.filter(|_| reused);
        let it = {
            let mut eigenvalues = eigenvalue_check(checkpoint, &smoother, fine, steps, &mut fresh);
            let mut pre = VCycle::new(fine, &smoother, self.coarse.as_mut());
            // PCG with the operator `a`; `checked`: stopped by the eigenvalue
            // check or the budget (not when it goes on from a checked solution).
            let mut pcg_with = |a: &dyn Operator, x: &mut [f64], residual, checked: bool| {
                pcg(
                    &mut |v, y| a.apply_into(v, y),
                    &mut |r, z| pre.apply_into(r, z),
                    rhs,
                    x,
                    residual,
                    self.params.pcg,
                    self.params.stagnation_window,
                    &mut |it| !checked || (eigenvalues(it) && Some(it) != budget),
                )
            };
            if single {
                single_then_checked(&exact, fine, rhs, x, residual, self.params.pcg.rtol, &mut pcg_with)
            } else {
                pcg_with(&exact, x, residual, true)
            }
        };
        if let (Some(spent), Err(PcgFailure::Stopped { .. })) = (budget, &it) {
            // The kept smoother is too slow for this matrix: on from the
            // iterate with one built for it.
            self.set_aside(smoother, false);
            return self.try_pcg_solve(pattern, values, rhs, x, mode, None, None).map(|it| it + spent).map_err(
                |mut b| {
                    b.iterations += spent;
                    b
                },
            );
        }
        let estimate = smoother.estimate();
        let outcome = pcg_outcome(it, fresh, estimate);
        if let (Ok(it), Mode::Fast) = (&outcome, mode) {
            self.last_iterations = Some(*it);
        }
        self.set_aside(smoother, outcome.is_ok() && mode == Mode::Fast);
        outcome
    }

    /// The fine smoother of a solve in `mode`: `kept` if given, else one
    /// built for the matrix (its single-precision copy updated in the fast
    /// mode, λ_max warm-started from `start`); and the coarse levels set up
    /// for it unless kept. Timed as set-up.
    fn smoother_for(
        &mut self,
        pattern: &SymmetricCsc,
        values: &[f64],
        mode: Mode,
        kept: Option<Chebyshev>,
        start: Option<Vec<f64>>,
    ) -> std::result::Result<Chebyshev, Breakdown> {
        let setup = std::time::Instant::now();
        let lines = if mode == Mode::Fast && kept.is_none() { self.line_blocks(pattern, values)? } else { None };
        let exact = self.op.with(pattern, values);
        let fine: &dyn Operator = match (&mut self.fine32, mode) {
            (Some(f), Mode::Fast) => {
                if kept.is_none() {
                    f.update(pattern, values);
                }
                f
            }
            _ => &exact,
        };
        // The fine smoother and the coarse levels side by side: each has
        // serial stretches (the Lanczos recurrence, the coarsest factor).
        let (block, params) = (self.block, self.params);
        let (smoother, coarse) = rayon::join(
            || match kept {
                Some(kept) => Ok(kept),
                None => {
                    let jacobi = diagonal_blocks(pattern, values, block, lines)?;
                    mode.smoother(fine, exact, jacobi, params.smoother, start)
                }
            },
            || self.coarse.as_mut().map_or(Ok(()), |c| mode.update_coarse(c, exact, params.reuse_coarse)),
        );
        let smoother = smoother?;
        coarse?;
        self.setup_seconds += setup.elapsed().as_secs_f64();
        Ok(smoother)
    }

    /// After a solve, keep `smoother` if it may serve the next one (with the
    /// single-precision matrix it smooths, whose values it was built for);
    /// else keep its dominant vector, which warm-starts the next one's λ_max.
    fn set_aside(&mut self, smoother: Chebyshev, may_serve: bool) {
        if may_serve && self.params.reuse_smoother && self.fine32.is_some() {
            self.kept = Some(smoother);
        } else {
            self.power = Some(smoother.power_vector());
        }
    }
}

/// PCG with an operator, from `x` and its residual if known; `checked`:
/// stoppable by the caller's check.
type PcgWith<'a> =
    dyn FnMut(&dyn Operator, &mut [f64], Option<Vec<f64>>, bool) -> std::result::Result<usize, PcgFailure> + 'a;

/// PCG (`pcg_with(operator, x, start residual, checked)`) with the
/// single-precision copy `single` as its operator, then the true residual of
/// what it converged to, b − A x with the double-precision `exact`: within
/// `rtol` ‖b‖ it is the solution, else PCG goes on from it with `exact`
/// (the iterations of both counted). The copy's entries are the matrix's
/// rounded to 24 bits, so its products differ from the matrix's by about
/// 1e-7 of ‖b‖ at the solution (2e-7 on the sphere and torus cavities at
/// p = 4), well inside the tolerance of 1e-5: the check passes and the solve
/// costs one double-precision product instead of one per iteration. A
/// breakdown of the first pass is returned as it is (the safe mode, which
/// uses no copy, restarts from it).
fn single_then_checked(
    exact: &WithValues,
    single: &dyn Operator,
    rhs: &[f64],
    x: &mut [f64],
    residual: Option<Vec<f64>>,
    rtol: f64,
    pcg_with: &mut PcgWith,
) -> std::result::Result<usize, PcgFailure> {
    let first = pcg_with(single, x, residual, true)?;
    let mut r = vec![0.0; rhs.len()];
    exact.matvec_into(x, &mut r);
    axpby_in_place(1.0, rhs, -1.0, &mut r);
    let (r_norm, b_norm) = (dot(&r, &r).sqrt(), dot(rhs, rhs).sqrt());
    if r_norm <= rtol * b_norm {
        return Ok(first);
    }
    pcg_with(exact, x, Some(r), false).map(|it| first + it).map_err(|f| f.after(first))
}

/// The smoother's inverted diagonal blocks; one not positive definite makes the matrix indefinite.
fn diagonal_blocks(
    pattern: &SymmetricCsc,
    values: &[f64],
    block: usize,
    lines: Option<LineFactors>,
) -> std::result::Result<BlockJacobi, Breakdown> {
    BlockJacobi::try_new_with_lines(pattern, values, block, lines).map_err(not_positive)
}

/// A block of the matrix that is not positive definite: so is the matrix.
fn not_positive(error: Error) -> Breakdown {
    Breakdown { reason: FallbackReason::MatrixNotPositive, iterations: 0, error }
}

impl Mode {
    /// Rebuild the coarse levels `c` for `values` unless the fast mode may `reuse` ready ones.
    fn update_coarse(self, c: &mut Hierarchy, a: WithValues, reuse: bool) -> std::result::Result<(), Breakdown> {
        if self == Mode::Safe || !(reuse && c.is_ready()) {
            c.try_update_with(a, self == Mode::Safe).map_err(Breakdown::setup)?;
        }
        Ok(())
    }

    /// The fine-level Chebyshev smoother of this mode for the matrix `values`.
    fn smoother(
        self,
        fine: &dyn Operator,
        a: WithValues,
        jacobi: BlockJacobi,
        params: ChebyshevParams,
        start: Option<Vec<f64>>,
    ) -> std::result::Result<Chebyshev, Breakdown> {
        match self {
            Mode::Fast => Chebyshev::try_with_jacobi(fine, jacobi, params, start),
            Mode::Safe => Chebyshev::try_safe_with_jacobi(a, jacobi, params),
        }
        .map_err(Breakdown::setup)
    }
}

/// PCG's check: at `checkpoint`, stop if a fresh λ_max estimate beats the warm one (kept in `fresh`).
fn eigenvalue_check<'a>(
    checkpoint: Option<usize>,
    smoother: &'a Chebyshev,
    fine: &'a dyn Operator,
    steps: usize,
    fresh: &'a mut Option<f64>,
) -> impl FnMut(usize) -> bool + 'a {
    move |it: usize| {
        if Some(it) != checkpoint {
            return true;
        }
        match smoother.cold_estimate(fine, steps) {
            Ok(cold) if cold > UNDERESTIMATE_FACTOR * smoother.estimate() => {
                *fresh = Some(cold);
                false
            }
            _ => true,
        }
    }
}

/// The iterations of a PCG run, or its breakdown (λ_max underestimated if stopped with `fresh`).
fn pcg_outcome(
    it: std::result::Result<usize, PcgFailure>,
    fresh: Option<f64>,
    estimate: f64,
) -> std::result::Result<usize, Breakdown> {
    match (it, fresh) {
        (Err(PcgFailure::Stopped { iteration }), Some(cold)) => Err(Breakdown {
            reason: FallbackReason::EigenvalueUnderestimated,
            iterations: iteration,
            error: Error::solver(
                SolverFailure::NotConverged,
                format!(
                    "PCG: {iteration} iterations, and the smoother's warm-started estimate of λ_max(D⁻¹A), \
                 {estimate:.3}, is below a fresh one, {cold:.3}"
                ),
            ),
        }),
        (Ok(it), _) => Ok(it),
        (Err(f), _) => Err(Breakdown::from_pcg(f)),
    }
}

impl LinearSolver for IterativeSolver {
    fn name(&self) -> &'static str {
        if self.coarse.is_some() {
            "pcg-pmg"
        } else {
            "pcg-chebyshev"
        }
    }

    /// PCG with the fast preconditioner; on a breakdown that a better
    /// preconditioner can cure, PCG again from the last iterate with the
    /// preconditioner of the safe mode; then, for at most
    /// `fallback_max_dofs` unknowns, the direct solver. The stats say which
    /// one solved the system and why the first attempt failed.
    fn setup_seconds(&self) -> f64 {
        self.setup_seconds
    }

    /// With the kept smoother and coarse levels of an earlier matrix (the
    /// fast mode), and its single-precision copy for the V-cycle.
    fn solves_by_products(&self) -> bool {
        !self.params.safe_preconditioner
            && self.params.reuse_coarse
            && self.kept.is_some()
            && self.fine32.is_some()
            && self.fresh_rate.is_some()
            && self.coarse.as_ref().is_none_or(Hierarchy::is_ready)
    }

    /// PCG with the kept preconditioner, within the iteration budget of a
    /// kept smoother ([`REUSE_SLACK`]), as [`Self::solve`] runs it with the
    /// matrix. Past the budget, or on a breakdown, the smoother is set aside
    /// and the caller assembles: the assembled solve builds a fresh one.
    fn solve_by_products(
        &mut self,
        apply: &mut dyn FnMut(&[f64], &mut [f64]),
        rhs: &[f64],
        x: &mut [f64],
    ) -> Result<ProductSolve> {
        let solved =
            |iterations| ProductSolve::Solved(SolveStats { iterations, solved_by: SolvedBy::Pcg, fallback: None });
        if !self.solves_by_products() {
            return Ok(ProductSolve::NeedsMatrix { iterations: 0, breakdown: None });
        }
        let b = rhs.iter().map(|v| v * v).sum::<f64>().sqrt();
        if b == 0.0 {
            x.fill(0.0);
            return Ok(solved(0));
        }
        let mut r = vec![0.0; rhs.len()];
        apply(x, &mut r);
        axpby_in_place(1.0, rhs, -1.0, &mut r);
        let digits = (r.iter().map(|v| v * v).sum::<f64>().sqrt() / (self.params.pcg.rtol * b)).log10();
        if digits <= 0.0 {
            return Ok(solved(0));
        }
        let budget = self.reuse_budget(digits).expect("a smoother is kept");
        let x0 = x.to_vec();
        let smoother = self.kept.take().expect("a smoother is kept");
        let fine: &dyn Operator = self.fine32.as_ref().expect("a single-precision copy");
        let it = {
            let mut pre = VCycle::new(fine, &smoother, self.coarse.as_mut());
            pcg(
                apply,
                &mut |r, z| pre.apply_into(r, z),
                rhs,
                x,
                Some(r),
                self.params.pcg,
                self.params.stagnation_window,
                &mut |it| it != budget,
            )
        };
        match it {
            Ok(it) => {
                self.last_iterations = Some(it);
                self.set_aside(smoother, true);
                Ok(solved(it))
            }
            Err(PcgFailure::Stopped { iteration }) => {
                self.set_aside(smoother, false);
                Ok(ProductSolve::NeedsMatrix { iterations: iteration, breakdown: None })
            }
            Err(f) => {
                self.set_aside(smoother, false);
                x.copy_from_slice(&x0);
                let b = Breakdown::from_pcg(f);
                Ok(ProductSolve::NeedsMatrix { iterations: b.iterations, breakdown: Some(b.reason) })
            }
        }
    }

    fn solve(&mut self, pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], x: &mut [f64]) -> Result<SolveStats> {
        // A start that already meets the tolerance (a step retried from the
        // same matrix) needs no preconditioner.
        let (digits, residual) = self.digits_to_gain(pattern, values, rhs, x);
        if digits <= 0.0 {
            return Ok(SolveStats { iterations: 0, solved_by: SolvedBy::Pcg, fallback: None });
        }
        let x0 = x.to_vec();
        let mode = if self.params.safe_preconditioner { Mode::Safe } else { Mode::Fast };
        let budget = self.reuse_budget(digits);
        let first = match self.try_pcg_solve(pattern, values, rhs, x, mode, budget, residual) {
            Ok(iterations) => {
                // A fresh smoother's rate: the yardstick of the kept one.
                if budget.is_none() && digits.is_finite() && iterations > 0 {
                    self.fresh_rate = Some(digits / iterations as f64);
                }
                return Ok(SolveStats { iterations, solved_by: SolvedBy::Pcg, fallback: None });
            }
            Err(Breakdown { error, .. }) if !matches!(error, Error::Solver { .. }) => return Err(error),
            Err(b) => b,
        };
        let fallback = Some(first.reason);
        let mut iterations = first.iterations;
        let mut message = first.message();
        if self.params.safe_restart && mode == Mode::Fast && first.worth_a_restart() {
            if !x.iter().all(|v| v.is_finite()) {
                x.copy_from_slice(&x0);
            }
            match self.try_pcg_solve(pattern, values, rhs, x, Mode::Safe, None, None) {
                Ok(it) => {
                    return Ok(SolveStats { iterations: iterations + it, solved_by: SolvedBy::PcgRestarted, fallback })
                }
                Err(Breakdown { error, .. }) if !matches!(error, Error::Solver { .. }) => return Err(error),
                Err(again) => {
                    iterations += again.iterations;
                    message = format!("{message}; restarted with the safe preconditioner: {}", again.message());
                }
            }
        }
        if pattern.n > self.params.fallback_max_dofs {
            return Err(Error::solver(
                first.kind(),
                format!(
                    "{message}; {} unknowns is too many for the direct fallback (at most {}): try the ILE formulation",
                    pattern.n, self.params.fallback_max_dofs
                ),
            ));
        }
        // The direct solver handles indefinite matrices (LU); a coarse
        // hierarchy that failed is left unset and rebuilt next time.
        x.copy_from_slice(&x0);
        if self.direct.is_none() {
            self.direct = Some(DirectSolver::try_new(pattern)?);
        }
        let direct = self.direct.as_mut().expect("just set").solve(pattern, values, rhs, x)?;
        Ok(SolveStats { iterations, solved_by: direct.solved_by, fallback })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::pcg::tests::grid_laplacian;

    #[test]
    fn indefinite_systems_fall_back_to_the_direct_solver_or_report_the_breakdown() {
        let (a, mut v) = grid_laplacian(12, 1);
        for c in 0..a.n {
            v[a.col_ptr[c]] -= if c % 7 == 0 { 9.0 } else { 0.0 }; // a few negative diagonal entries
        }
        let x_true: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let b = a.sym_matvec(&v, &x_true);
        let mut solver = IterativeSolver::try_new(&a, 1, Vec::new(), IterativeParams::default()).unwrap();
        let mut x = vec![0.0; a.n];
        let stats = solver.solve(&a, &v, &b, &mut x).unwrap();
        assert_eq!(stats.solved_by, SolvedBy::DirectLu, "solved by the direct fallback");
        assert_eq!(stats.fallback, Some(FallbackReason::MatrixNotPositive), "{stats:?}");
        assert!(x.iter().zip(&x_true).all(|(p, q)| (p - q).abs() < 1e-9));
        let params = IterativeParams { fallback_max_dofs: 10, ..Default::default() };
        let mut solver = IterativeSolver::try_new(&a, 1, Vec::new(), params).unwrap();
        let r = solver.solve(&a, &v, &b, &mut vec![0.0; a.n]);
        assert!(matches!(r, Err(Error::Solver { message: ref m, .. }) if m.contains("direct fallback")), "{r:?}");
    }

    /// ‖b − A x‖ / ‖b‖.
    fn relative_residual(a: &SymmetricCsc, v: &[f64], b: &[f64], x: &[f64]) -> f64 {
        let ax = a.sym_matvec(v, x);
        let (r, n) = ax.iter().zip(b).fold((0.0, 0.0), |(r, n), (p, q)| (r + (p - q) * (p - q), n + q * q));
        (r / n).sqrt()
    }

    /// The values of S A S for A = (`a`, `v`) with S = diag(1 + amp sin(0.37 i))
    /// for the dofs of node i (`block` a node), as a later increment's matrix.
    fn scaled_by_nodes(a: &SymmetricCsc, v: &[f64], block: usize, amp: f64) -> Vec<f64> {
        let s = |i: usize| 1.0 + amp * ((i / block) as f64 * 0.37).sin();
        (0..a.n)
            .flat_map(|c| (a.col_ptr[c]..a.col_ptr[c + 1]).map(move |k| (c, k)))
            .map(|(c, k)| v[k] * s(c) * s(a.row_idx[k] as usize))
            .collect()
    }

    #[test]
    fn a_kept_smoother_serves_a_close_matrix_and_is_rebuilt_within_its_budget_for_a_far_one() {
        let (a, v) = grid_laplacian(24, 1);
        let scaled = |amp: f64| scaled_by_nodes(&a, &v, 1, amp);
        let b: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let rtol = IterativeParams::default().pcg.rtol;
        let mut solver = IterativeSolver::try_new(&a, 1, Vec::new(), IterativeParams::default()).unwrap();
        let kept = |s: &IterativeSolver| s.kept.as_ref().map(|k| k.estimate());
        solver.solve(&a, &v, &b, &mut vec![0.0; a.n]).unwrap();
        let first = kept(&solver).expect("a fast solve keeps its smoother");
        // Within 0.5 %: the same smoother solves it.
        let close = scaled(0.005);
        let mut x = vec![0.0; a.n];
        assert_eq!(solver.solve(&a, &close, &b, &mut x).unwrap().fallback, None);
        assert_eq!(kept(&solver), Some(first));
        assert!(relative_residual(&a, &close, &b, &x) <= rtol);
        // Within 90 %: the kept smoother's D⁻¹ no longer scales it; after
        // its budget, PCG goes on with a smoother built for it, kept next.
        let far = scaled(0.9);
        let fresh_params = IterativeParams { reuse_smoother: false, ..Default::default() };
        let mut fresh = IterativeSolver::try_new(&a, 1, Vec::new(), fresh_params).unwrap();
        let alone = fresh.solve(&a, &far, &b, &mut vec![0.0; a.n]).unwrap().iterations;
        let budget = solver.reuse_budget(-rtol.log10()).expect("a smoother is kept");
        let mut x = vec![0.0; a.n];
        let stats = solver.solve(&a, &far, &b, &mut x).unwrap();
        assert_eq!((stats.solved_by, stats.fallback), (SolvedBy::Pcg, None));
        assert!(stats.iterations <= budget + alone, "{} iterations, budget {budget}, fresh {alone}", stats.iterations);
        assert!(kept(&solver).is_some_and(|e| e != first));
        assert!(relative_residual(&a, &far, &b, &x) <= rtol);
    }

    /// A solve from products alone takes the kept smoother, solves a close
    /// matrix as the assembled solve does, and hands a far one back after
    /// its budget with the smoother set aside; the assembled solve then
    /// finishes from the iterate.
    #[test]
    fn a_solve_by_products_keeps_to_the_kept_smoother_and_its_budget() {
        let (a, v) = grid_laplacian(16, 3);
        let scaled = |amp: f64| scaled_by_nodes(&a, &v, 3, amp);
        let b: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let rtol = IterativeParams::default().pcg.rtol;
        let mut solver = IterativeSolver::try_new(&a, 3, Vec::new(), IterativeParams::default()).unwrap();
        assert!(!solver.solves_by_products(), "no smoother is kept before a first solve");
        solver.solve(&a, &v, &b, &mut vec![0.0; a.n]).unwrap();
        assert!(solver.solves_by_products());
        let op = SymmetricOperator::try_new(&a, 3).unwrap();
        let close = scaled(0.005);
        let mut x = vec![0.0; a.n];
        let mut apply = |u: &[f64], y: &mut [f64]| op.with(&a, &close).matvec_into(u, y);
        let by_products = solver.solve_by_products(&mut apply, &b, &mut x).unwrap();
        let mut y = vec![0.0; a.n];
        let assembled = {
            // PCG's products in double precision, as the products from the cells are.
            let params = IterativeParams { single_precision_krylov: false, ..Default::default() };
            let mut again = IterativeSolver::try_new(&a, 3, Vec::new(), params).unwrap();
            again.solve(&a, &v, &b, &mut y).unwrap();
            y.fill(0.0);
            again.solve(&a, &close, &b, &mut y).unwrap()
        };
        assert_eq!(by_products, ProductSolve::Solved(assembled));
        assert_eq!(x, y, "the same iterates as with the matrix");
        assert!(solver.solves_by_products(), "the smoother is kept for the next one");
        // Far: past the budget the matrix is asked for, and the assembled
        // solve goes on from the iterate with a smoother built for it.
        let far = scaled(0.9);
        let mut x = vec![0.0; a.n];
        let mut apply = |u: &[f64], y: &mut [f64]| op.with(&a, &far).matvec_into(u, y);
        let budget = solver.reuse_budget(-rtol.log10()).expect("a smoother is kept");
        let outcome = solver.solve_by_products(&mut apply, &b, &mut x).unwrap();
        assert_eq!(outcome, ProductSolve::NeedsMatrix { iterations: budget, breakdown: None });
        assert!(!solver.solves_by_products());
        assert!(relative_residual(&a, &far, &b, &x) > rtol);
        solver.solve(&a, &far, &b, &mut x).unwrap();
        assert!(relative_residual(&a, &far, &b, &x) <= rtol);
    }

    /// PCG on the single-precision copy takes the iterations it takes on
    /// the matrix, and its solution meets the tolerance with the matrix.
    #[test]
    fn pcg_on_the_single_precision_copy_meets_the_tolerance_with_the_matrix() {
        let (a, v) = grid_laplacian(16, 3);
        let b: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let solve = |single: bool| {
            let params = IterativeParams { single_precision_krylov: single, ..Default::default() };
            let mut solver = IterativeSolver::try_new(&a, 3, Vec::new(), params).unwrap();
            assert!(solver.fine32.is_some());
            let mut x = vec![0.0; a.n];
            let stats = solver.solve(&a, &v, &b, &mut x).unwrap();
            (stats, x)
        };
        let ((single, xs), (double, xd)) = (solve(true), solve(false));
        assert_eq!((single.fallback, double.fallback), (None, None));
        assert_eq!(single.iterations, double.iterations);
        let rtol = IterativeParams::default().pcg.rtol;
        assert!(relative_residual(&a, &v, &b, &xs) <= rtol);
        let (diff, norm) = xs.iter().zip(&xd).fold((0.0, 0.0), |(d, n), (p, q)| (d + (p - q) * (p - q), n + q * q));
        assert!((diff / norm).sqrt() < 1e-5, "solutions differ by {:.2e}", (diff / norm).sqrt());
    }

    /// Below the copy's rounding (a tolerance of 1e-11), its solution fails
    /// the check with the matrix, and PCG goes on with the matrix to meet it.
    #[test]
    fn a_tolerance_below_the_copys_rounding_is_met_by_going_on_with_the_matrix() {
        let (a, v) = grid_laplacian(16, 3);
        let b: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let rtol = 1e-11;
        let pcg = PcgParams { rtol, ..Default::default() };
        let params = IterativeParams { pcg, ..Default::default() };
        let mut solver = IterativeSolver::try_new(&a, 3, Vec::new(), params).unwrap();
        let mut x = vec![0.0; a.n];
        let stats = solver.solve(&a, &v, &b, &mut x).unwrap();
        assert_eq!((stats.solved_by, stats.fallback), (SolvedBy::Pcg, None));
        let reached = relative_residual(&a, &v, &b, &x);
        assert!(reached <= rtol, "relative residual {reached:.2e}");
        // PCG on the copy alone could not have met it: at the solution, the
        // copy's product is off the matrix's by more than the tolerance.
        let mut ax = vec![0.0; a.n];
        solver.fine32.as_ref().expect("a single-precision copy").apply_into(&x, &mut ax);
        let off = ax.iter().zip(a.sym_matvec(&v, &x)).map(|(p, q)| (p - q) * (p - q)).sum::<f64>().sqrt();
        let b_norm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(off > 10.0 * rtol * b_norm, "the copy's products are off by {:.2e} of ‖b‖", off / b_norm);
    }

    #[test]
    fn the_preconditioner_set_up_is_timed_apart_and_only_when_one_is_built() {
        let (a, v) = grid_laplacian(24, 1);
        let b: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let mut solver = IterativeSolver::try_new(&a, 1, Vec::new(), IterativeParams::default()).unwrap();
        assert_eq!(solver.setup_seconds(), 0.0);
        let mut x = vec![0.0; a.n];
        let t = std::time::Instant::now();
        assert!(solver.solve(&a, &v, &b, &mut x).unwrap().iterations > 0);
        let (built, whole) = (solver.setup_seconds(), t.elapsed().as_secs_f64());
        assert!(built > 0.0 && built < whole, "set-up {built} s of a {whole} s solve");
        // From the solution: no iteration, no preconditioner, no set-up.
        assert_eq!(solver.solve(&a, &v, &b, &mut x).unwrap().iterations, 0);
        assert_eq!(solver.setup_seconds(), built);
    }

    #[test]
    fn a_start_that_solves_the_system_takes_no_iteration_and_a_scaled_one_solves_the_scaled_system() {
        let (a, v) = grid_laplacian(12, 1);
        let x_true: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let b = a.sym_matvec(&v, &x_true);
        let mut solver = IterativeSolver::try_new(&a, 1, Vec::new(), IterativeParams::default()).unwrap();
        let mut x = vec![0.0; a.n];
        let cold = solver.solve(&a, &v, &b, &mut x).unwrap();
        assert!(cold.iterations > 0, "{cold:?}");
        // The same system from its solution, then half the right-hand side
        // from half of it: no iteration, and the start is kept.
        let solved = x.clone();
        assert_eq!(solver.solve(&a, &v, &b, &mut x).unwrap().iterations, 0);
        assert_eq!(x, solved);
        let half_b: Vec<f64> = b.iter().map(|v| 0.5 * v).collect();
        let mut half: Vec<f64> = solved.iter().map(|v| 0.5 * v).collect();
        let stats = solver.solve(&a, &v, &half_b, &mut half).unwrap();
        assert_eq!((stats.iterations, stats.solved_by, stats.fallback), (0, SolvedBy::Pcg, None));
        // A start off the solution still iterates to it.
        let mut off: Vec<f64> = solved.iter().map(|v| v + 1e-3).collect();
        assert!(solver.solve(&a, &v, &b, &mut off).unwrap().iterations > 0);
        let ax = a.sym_matvec(&v, &off);
        let (r, bn) = ax.iter().zip(&b).fold((0.0, 0.0), |(r, n), (p, q)| (r + (p - q) * (p - q), n + q * q));
        assert!(r.sqrt() <= IterativeParams::default().pcg.rtol * bn.sqrt(), "{:e}", (r / bn).sqrt());
    }
}
