//! Linear solvers. This module sees only matrices and vectors.
//!
//! [`SymmetricCsc`] holds the lower triangle of a symmetric sparse matrix in
//! compressed-column form; [`SparseCholesky`] does the symbolic analysis (fill-
//! reducing ordering, AMD or nested dissection, see [`DirectOrdering`], and
//! elimination tree) once and the numeric
//! factorisation for every new set of values on the same pattern.
//! [`ExternalAdapter`] hands each system to a solver of the host's
//! ([`SystemSolver`]) as a full CSR matrix.

internal! {
    mod bsr;
    mod pcg;
    mod pmg;
}
mod cholesky;
mod direct;
mod external;
mod iterative;
mod lines;
mod lu;
pub(crate) mod metis;
mod simd;
pub use metis::partition;

pub(crate) use crate::sparse::split_by;
pub use crate::sparse::{NodeGroups, SparseRows, SymmetricCsc};
pub use cholesky::{nested_dissection, node_block_size, DirectOrdering, SparseCholesky};
pub use direct::DirectSolver;
pub use external::{CsrView, ExternalAdapter, ExternalSolver, FullCsrPattern, LowerCscView, SystemSolver};
pub use iterative::{IterativeParams, IterativeSolver, FALLBACK_DIRECT_MAX_DOFS, REUSE_SLACK};
pub use lu::try_lu_solve_in_place;
pub use pcg::{PcgFailure, PcgParams};
pub use pmg::ChebyshevParams;

use crate::{Error, Result};

/// What one linear solve reports.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SolveStats {
    /// Krylov iterations run, including those of an attempt that broke down
    /// before a restart or a direct fallback (0 for a direct solve).
    pub iterations: usize,
    /// The solver that produced the solution.
    pub solved_by: SolvedBy,
    /// Why the solver's first choice did not produce it (`None`: it did).
    pub fallback: Option<FallbackReason>,
}

/// What the linear solves of a run did, one entry per solve in order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SolveLog {
    /// The linear solver that was set up ("direct", "pcg-pmg", ...).
    pub solver: &'static str,
    /// Krylov iterations of each solve (zeros for a direct solver; with
    /// those of an attempt that fell back).
    pub iterations: Vec<usize>,
    /// The solver that produced each solve's solution.
    pub solved_by: Vec<SolvedBy>,
    /// Per solve, why the first choice of solver did not produce it.
    pub fallback: Vec<Option<FallbackReason>>,
    /// Solves made from the cells' products alone, without assembling the
    /// matrix ([`LinearSolver::solve_by_products`]).
    pub by_products: usize,
    /// Solves begun that way that then needed the matrix (the kept
    /// preconditioner too slow for it, or a breakdown, in `fallback`).
    pub assembled_after_products: usize,
}

impl SolveLog {
    /// Record what one solve reports.
    pub fn record(&mut self, stats: &SolveStats) {
        self.iterations.push(stats.iterations);
        self.solved_by.push(stats.solved_by);
        self.fallback.push(stats.fallback);
    }

    /// Append the solves of `more`, made after these.
    pub fn append(&mut self, more: SolveLog) {
        self.iterations.extend(more.iterations);
        self.solved_by.extend(more.solved_by);
        self.fallback.extend(more.fallback);
        self.by_products += more.by_products;
        self.assembled_after_products += more.assembled_after_products;
    }

    /// Number of solves.
    pub fn len(&self) -> usize {
        self.solved_by.len()
    }

    pub fn is_empty(&self) -> bool {
        self.solved_by.is_empty()
    }

    /// Solves that fell back (restarted PCG, direct after PCG, LU after Cholesky).
    pub fn fallbacks(&self) -> usize {
        self.fallback.iter().filter(|f| f.is_some()).count()
    }
}

/// Which solver produced a solution ([`SolveStats::solved_by`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum SolvedBy {
    /// Preconditioned conjugate gradients with the default preconditioner.
    Pcg,
    /// PCG restarted, after a breakdown, with the preconditioner rebuilt in
    /// its safe mode (double precision, Gershgorin bound of λ_max).
    PcgRestarted,
    /// Sparse Cholesky.
    #[default]
    Direct,
    /// Sparse LU (the Cholesky factorisation failed: not positive definite).
    DirectLu,
    /// The host's solver.
    External,
}

impl SolvedBy {
    /// "pcg", "pcg-restarted", "direct", "direct-lu" or "external".
    pub fn name(self) -> &'static str {
        match self {
            SolvedBy::Pcg => "pcg",
            SolvedBy::PcgRestarted => "pcg-restarted",
            SolvedBy::Direct => "direct",
            SolvedBy::DirectLu => "direct-lu",
            SolvedBy::External => "external",
        }
    }
}

/// Why a solve fell back from its first choice ([`SolveStats::fallback`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FallbackReason {
    /// PCG found rᵀz ≤ 0: the preconditioner was not positive definite.
    PreconditionerNotPositive,
    /// PCG's residual stagnated ([`pcg::pcg`]).
    Stagnation,
    /// PCG was slow and a fresh estimate of λ_max(D⁻¹A) exceeded the
    /// warm-started one of the smoother: the preconditioner may not be
    /// positive definite.
    EigenvalueUnderestimated,
    /// PCG reached its iteration limit while still converging.
    NotConverged,
    /// PCG's residual became infinite or NaN.
    NonFinite,
    /// PCG found pᵀAp ≤ 0: the matrix is not positive definite.
    MatrixNotPositive,
    /// The preconditioner could not be built (a diagonal block or the coarse
    /// matrix not positive definite, a failed eigenvalue estimate).
    PreconditionerSetup,
    /// Sparse Cholesky failed (the matrix is not positive definite): LU.
    CholeskyFailed,
}

impl FallbackReason {
    /// A short identifier, e.g. "preconditioner-not-positive-definite".
    pub fn name(self) -> &'static str {
        match self {
            FallbackReason::PreconditionerNotPositive => "preconditioner-not-positive-definite",
            FallbackReason::Stagnation => "stagnation",
            FallbackReason::EigenvalueUnderestimated => "eigenvalue-underestimated",
            FallbackReason::NotConverged => "not-converged",
            FallbackReason::NonFinite => "non-finite-residual",
            FallbackReason::MatrixNotPositive => "matrix-not-positive-definite",
            FallbackReason::PreconditionerSetup => "preconditioner-setup-failed",
            FallbackReason::CholeskyFailed => "cholesky-failed",
        }
    }
}

/// A solver for a sequence of symmetric systems on one sparsity pattern (one
/// per load increment or Newton iteration).
pub trait LinearSolver {
    /// Short name for reports ("direct", "pcg-pmg", "external").
    fn name(&self) -> &'static str;
    /// Solve A x = b for the matrix with lower triangle (`pattern`, `values`).
    /// On entry `x` holds the initial guess (iterative solvers start from it,
    /// direct ones ignore it); on exit, the solution.
    fn solve(&mut self, pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], x: &mut [f64]) -> Result<SolveStats>;
    /// Seconds its solves have spent so far building a preconditioner for
    /// their matrix (the smoothers and coarse levels of PCG), which a run
    /// reports as set-up rather than solving. A direct solver's
    /// factorisation is its solve: 0.
    fn setup_seconds(&self) -> f64 {
        0.0
    }
    /// Whether [`Self::solve_by_products`] may solve the next system
    /// without its matrix (with a preconditioner kept from an earlier one).
    fn solves_by_products(&self) -> bool {
        false
    }
    /// Solve A x = b knowing A only by its products (`apply(v, y)`: y = A v),
    /// from the guess in `x`. When it cannot finish that way, `x` holds the
    /// best iterate and the caller assembles A and calls [`Self::solve`].
    fn solve_by_products(
        &mut self,
        _apply: &mut dyn FnMut(&[f64], &mut [f64]),
        _rhs: &[f64],
        _x: &mut [f64],
    ) -> Result<ProductSolve> {
        Ok(ProductSolve::NeedsMatrix { iterations: 0, breakdown: None })
    }
}

/// The outcome of [`LinearSolver::solve_by_products`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProductSolve {
    Solved(SolveStats),
    /// The matrix is needed: the kept preconditioner was too slow for this
    /// system within its iteration budget (`breakdown` None), or PCG broke
    /// down with it. `iterations` were spent.
    NeedsMatrix {
        iterations: usize,
        breakdown: Option<FallbackReason>,
    },
}

/// Which linear solver runs the increments.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum SolverChoice {
    /// The direct solver in 2D and for small 3D systems
    /// ([`auto_direct_max_dofs`]), the iterative one for larger 3D systems.
    #[default]
    Auto,
    /// Sparse Cholesky (LU when not positive definite).
    Direct,
    /// The host's solver (see [`SystemSolver`]).
    External(ExternalSolver),
    /// PCG with a p-multigrid preconditioner ([`IterativeSolver`]).
    Iterative,
}

/// Largest 3D system (unknowns after static condensation) that
/// [`SolverChoice::Auto`] solves directly at order `order`. The direct
/// solver's fill grows with the order's denser rows, the p-multigrid's cost
/// does not, so the crossover moves up with p. Measured (sphere cavity, one
/// ILE increment, `hocurve bench-one`, setup plus solve, 2026-11-26): at
/// p = 2 direct and iterative take 9 and 12 ms at 2k unknowns, 56 and 37 ms
/// at 7k, 202 and 90 ms at 17k; at p = 3 65 and 62 ms at 7k, 393 and 256 ms
/// at 25k; at p = 4 they are even at 16k (220 ms each), at p = 5 at 27k
/// (730 ms each); at p = 6 direct is 1.6× faster at 5k and 1.3× slower at
/// 42k. Above, the direct solver's time and memory grow much faster. 2D
/// stays direct at every size: its factorisations are cheap
/// (nested-dissection fill ~ N log N) and the p-multigrid is weak on
/// stretched boundary-layer cells (63 iterations on the cylinder case at
/// p = 4); a large-2D comparison was not measured.
pub fn auto_direct_max_dofs(order: usize) -> usize {
    match order {
        0..=3 => 5_000,
        4 => 15_000,
        _ => 25_000,
    }
}

impl SolverChoice {
    pub fn name(&self) -> &'static str {
        match self {
            SolverChoice::Auto => "auto",
            SolverChoice::Direct => "direct",
            SolverChoice::External(_) => "external",
            SolverChoice::Iterative => "iterative",
        }
    }

    pub fn parse(s: &str) -> Result<SolverChoice> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(SolverChoice::Auto),
            "direct" => Ok(SolverChoice::Direct),
            "iterative" => Ok(SolverChoice::Iterative),
            _ => Err(Error::InvalidInput(format!("unknown linear solver '{s}' (expected auto, direct or iterative)"))),
        }
    }
}
