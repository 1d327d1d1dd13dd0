//! The iterative solver: PCG preconditioned by the two-level p-multigrid of
//! [`super::pmg`], with a direct fallback for indefinite systems.

use super::pcg::{try_pcg, PcgParams, SymmetricOperator};
use super::pmg::{Chebyshev, ChebyshevParams, CoarseLevel, SparseRows, TwoLevel};
use super::{DirectSolver, LinearSolver, SolveStats, SymmetricCsc};
use crate::{Error, Result};

/// Largest system the iterative solver hands to the direct one when PCG breaks
/// down (an indefinite CIL or Newton tangent); above it the error is returned.
/// About 10 s and 2 GB for a 3D p = 4 factorisation (issue 5 measurements).
pub const FALLBACK_DIRECT_MAX_DOFS: usize = 150_000;

/// Settings of [`IterativeSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterativeParams {
    pub pcg: PcgParams,
    pub smoother: ChebyshevParams,
    /// Keep the coarse operator and its factor from the first matrix for all
    /// later ones (the smoother always follows the current matrix).
    pub reuse_coarse: bool,
    pub fallback_max_dofs: usize,
}

impl Default for IterativeParams {
    fn default() -> Self {
        IterativeParams {
            pcg: PcgParams::default(),
            smoother: ChebyshevParams::default(),
            reuse_coarse: true,
            fallback_max_dofs: FALLBACK_DIRECT_MAX_DOFS,
        }
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
    coarse: Option<CoarseLevel>,
    params: IterativeParams,
    direct: Option<DirectSolver>,
}

impl IterativeSolver {
    /// `block`: size of the diagonal blocks of the smoother (the spatial
    /// dimension when the free dofs of a node are consecutive, else 1).
    /// `coarse`: the prolongation P (rows: the unknowns of `pattern`) and the
    /// lower-triangle pattern of Pᵀ A P.
    pub fn try_new(
        pattern: &SymmetricCsc,
        block: usize,
        coarse: Option<(SparseRows, SymmetricCsc)>,
        params: IterativeParams,
    ) -> Result<IterativeSolver> {
        let coarse = match coarse {
            Some((p, cp)) => {
                if p.n_rows != pattern.n {
                    return Err(Error::Solver(format!("P has {} rows for {} unknowns", p.n_rows, pattern.n)));
                }
                Some(CoarseLevel::try_new(p, cp)?)
            }
            None => None,
        };
        Ok(IterativeSolver { op: SymmetricOperator::try_new(pattern)?, block, coarse, params, direct: None })
    }

    fn try_pcg_solve(&mut self, pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], x: &mut [f64]) -> Result<usize> {
        self.op.update(values);
        let smoother = Chebyshev::try_new(&self.op, pattern, values, self.block, self.params.smoother)?;
        if let Some(c) = &mut self.coarse {
            if !(self.params.reuse_coarse && c.is_factored()) {
                c.try_factor(&self.op, values)?;
            }
        }
        let op = &self.op;
        let mut pre = TwoLevel::new(op, values, &smoother, self.coarse.as_ref());
        try_pcg(&mut |v, y| op.matvec_into(values, v, y), &mut |r, z| pre.apply_into(r, z), rhs, x, self.params.pcg)
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

    fn solve(&mut self, pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], x: &mut [f64]) -> Result<SolveStats> {
        let x0 = x.to_vec();
        match self.try_pcg_solve(pattern, values, rhs, x) {
            Ok(iterations) => Ok(SolveStats { iterations }),
            Err(Error::Solver(_)) if pattern.n <= self.params.fallback_max_dofs => {
                // The direct solver handles indefinite matrices (LU); a coarse
                // factor that failed is left unset and rebuilt next time.
                x.copy_from_slice(&x0);
                if self.direct.is_none() {
                    self.direct = Some(DirectSolver::try_new(pattern)?);
                }
                self.direct.as_mut().expect("just set").solve(pattern, values, rhs, x)
            }
            Err(Error::Solver(m)) => Err(Error::Solver(format!(
                "{m}; {} unknowns is too many for the direct fallback (at most {}): try the ILE formulation",
                pattern.n, self.params.fallback_max_dofs
            ))),
            Err(e) => Err(e),
        }
    }
}
