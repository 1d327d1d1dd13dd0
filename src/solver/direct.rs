//! The direct solver: sparse Cholesky with the symbolic analysis done once
//! per pattern, sparse LU when a matrix is not positive definite.

use super::{
    try_lu_solve_in_place, DirectOrdering, FallbackReason, LinearSolver, SolveStats, SolvedBy, SparseCholesky,
};
use crate::sparse::SymmetricCsc;
use crate::{Error, Result, SolverFailure};

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
            Err(Error::Solver { kind: SolverFailure::NotPositiveDefinite, .. }) => {
                x.copy_from_slice(rhs);
                try_lu_solve_in_place(pattern, values, x)?;
                Ok(SolveStats {
                    iterations: 0,
                    solved_by: SolvedBy::DirectLu,
                    fallback: Some(FallbackReason::CholeskyFailed),
                })
            }
            r => {
                r?;
                Ok(SolveStats { iterations: 0, solved_by: SolvedBy::Direct, fallback: None })
            }
        }
    }
}
