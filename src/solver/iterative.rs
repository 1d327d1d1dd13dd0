//! The iterative solver: PCG preconditioned by the two-level p-multigrid of
//! [`super::pmg`], with a direct fallback for indefinite systems.

use super::pcg::{try_pcg, PcgParams, SymmetricOperator};
use super::pmg::{Chebyshev, ChebyshevParams, Hierarchy, SparseRows, VCycle};
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
    coarse: Option<Hierarchy>,
    params: IterativeParams,
    direct: Option<DirectSolver>,
    /// Dominant vector of D⁻¹A of the previous matrix.
    power: Option<Vec<f64>>,
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
        if let Some((p, _)) = levels.first() {
            if p.n_rows != pattern.n {
                return Err(Error::Solver(format!("P has {} rows for {} unknowns", p.n_rows, pattern.n)));
            }
        }
        let coarse = if levels.is_empty() { None } else { Some(Hierarchy::try_new(levels, block, params.smoother)?) };
        Ok(IterativeSolver {
            op: SymmetricOperator::try_new(pattern)?,
            block,
            coarse,
            params,
            direct: None,
            power: None,
        })
    }

    fn try_pcg_solve(&mut self, pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], x: &mut [f64]) -> Result<usize> {
        self.op.update(values);
        let start = self.power.take();
        let smoother = Chebyshev::try_new_from(&self.op, pattern, values, self.block, self.params.smoother, start)?;
        if let Some(c) = &mut self.coarse {
            if !(self.params.reuse_coarse && c.is_ready()) {
                c.try_update(&self.op, values)?;
            }
        }
        let op = &self.op;
        let mut pre = VCycle::new(op, values, &smoother, self.coarse.as_mut());
        let it = try_pcg(
            &mut |v, y| op.matvec_into(values, v, y),
            &mut |r, z| pre.apply_into(r, z),
            rhs,
            x,
            self.params.pcg,
        );
        drop(pre);
        self.power = Some(smoother.power_vector());
        it
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
                // hierarchy that failed is left unset and rebuilt next time.
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
