//! Linear solvers. This module sees only matrices and vectors.
//!
//! [`SymmetricCsc`] holds the lower triangle of a symmetric sparse matrix in
//! compressed-column form; [`SparseCholesky`] does the symbolic analysis (fill-
//! reducing ordering, AMD or nested dissection, see [`DirectOrdering`], and
//! elimination tree) once and the numeric
//! factorisation for every new set of values on the same pattern.
//! [`ExternalAdapter`] hands each system to a solver of the host's
//! ([`SystemSolver`]) as a full CSR matrix.

pub mod bsr;
mod cholesky;
mod external;
mod iterative;
mod lu;
mod metis;
pub mod pcg;
pub mod pmg;

pub use cholesky::{nested_dissection, node_block_size, DirectOrdering, SparseCholesky};
pub use external::{CsrView, ExternalAdapter, ExternalSolver, FullCsrPattern, SystemSolver};
pub use iterative::{IterativeParams, IterativeSolver, FALLBACK_DIRECT_MAX_DOFS};
pub use lu::try_lu_solve_in_place;
pub use pmg::SparseRows;

use crate::{Error, Result};

/// What one linear solve reports.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SolveStats {
    /// Krylov iterations (0 for a direct solve).
    pub iterations: usize,
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
}

/// Sparse Cholesky with the symbolic analysis done once; if a matrix is not
/// positive definite (a CIL or Newton tangent can lose definiteness), sparse LU.
pub struct DirectSolver {
    chol: SparseCholesky,
}

impl DirectSolver {
    /// Analyse `pattern` with the ordering [`DirectOrdering::Auto`] picks.
    pub fn try_new(pattern: &SymmetricCsc) -> Result<DirectSolver> {
        Self::try_new_with(pattern, DirectOrdering::Auto)
    }

    /// Analyse `pattern` with this fill-reducing ordering.
    pub fn try_new_with(pattern: &SymmetricCsc, ordering: DirectOrdering) -> Result<DirectSolver> {
        Ok(DirectSolver { chol: SparseCholesky::try_analyse_with(pattern, ordering)? })
    }

    /// The symbolic analysis (ordering used, factor size).
    pub fn cholesky(&self) -> &SparseCholesky {
        &self.chol
    }
}

impl LinearSolver for DirectSolver {
    fn name(&self) -> &'static str {
        "direct"
    }
    fn solve(&mut self, pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], x: &mut [f64]) -> Result<SolveStats> {
        x.copy_from_slice(rhs);
        match self.chol.try_factor_solve_in_place(pattern, values, x) {
            Err(Error::Solver(_)) => {
                x.copy_from_slice(rhs);
                try_lu_solve_in_place(pattern, values, x)?
            }
            r => r?,
        }
        Ok(SolveStats::default())
    }
}

/// Which linear solver runs the increments.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum SolverChoice {
    /// The direct solver in 2D and in 3D up to [`AUTO_DIRECT_MAX_DOFS`]
    /// unknowns, the iterative one for larger 3D systems.
    #[default]
    Auto,
    /// Sparse Cholesky (LU when not positive definite).
    Direct,
    /// The host's solver (see [`SystemSolver`]).
    External(ExternalSolver),
    /// PCG with a p-multigrid preconditioner ([`IterativeSolver`]).
    Iterative,
}

/// Largest 3D system that [`SolverChoice::Auto`] solves directly. Measured
/// (sphere cavity, one ILE increment, 2026-11-23, other jobs paused): at p = 2
/// the iterative solve is 2× faster at 17k unknowns and 4.7× at 34k; at p = 4
/// the direct one is 2.6× faster at 17k and 2× slower at 60k. Above, the
/// direct solver's time and memory grow much faster. 2D stays direct at every
/// size: its factorisations are cheap (nested-dissection fill ~ N log N) and
/// the p-multigrid is weak on stretched boundary-layer cells (63 iterations on
/// the cylinder case at p = 4); a large-2D comparison was not measured.
pub const AUTO_DIRECT_MAX_DOFS: usize = 25_000;

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

/// Lower triangle (row ≥ column) of a symmetric `n`×`n` sparse matrix, CSC.
#[derive(Debug, Clone, Default)]
pub struct SymmetricCsc {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column; 32-bit (half the memory of
    /// usize: 0.7 GB at a million unknowns, p = 4), so n < 2^32.
    pub row_idx: Vec<u32>,
}

impl SymmetricCsc {
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Position of entry (`row`, `col`) (row ≥ col) in the value array.
    #[inline]
    pub fn position(&self, row: usize, col: usize) -> Option<usize> {
        let (s, e) = (self.col_ptr[col], self.col_ptr[col + 1]);
        let row = u32::try_from(row).ok()?;
        self.row_idx[s..e].binary_search(&row).ok().map(|k| s + k)
    }

    /// y = A x for the symmetric matrix whose lower triangle is stored.
    pub fn sym_matvec(&self, values: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.n];
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[k] as usize;
                y[r] += values[k] * x[c];
                if r != c {
                    y[c] += values[k] * x[r];
                }
            }
        }
        y
    }
}
