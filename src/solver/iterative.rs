//! The iterative solver: PCG preconditioned by the p-multigrid V-cycle of
//! [`super::pmg`], with a direct fallback for indefinite systems.
//!
//! Decisions (issue 5, sphere_in_box_3d, ILE, ν = 0.45, 2 cores):
//! - Tolerance ‖r‖ ≤ 1e-5 ‖b‖ ([`PcgParams`]): the nodes then agree with the
//!   direct solver's to ~1e-6 of the mesh size (tests/solvers.rs checks 2e-5),
//!   far below the geometric error of the curved boundary; 1e-8 took 27
//!   iterations at p = 4 against 16.
//! - The coarse levels (Galerkin products, coarsest factor) are built on the
//!   first matrix and reused: rebuilding them gave the same iteration counts
//!   for ~1 s more per increment at 106k unknowns. The fine smoother follows
//!   every matrix (its λ_max power iteration restarts from the previous
//!   dominant vector: 2 steps, not 12).
//! - Chebyshev degree 3 on [λ_max/30, λ_max]: at p = 4 degrees 2/3/4 took
//!   34/26/21 iterations (tolerance 1e-8), i.e. 170/182/189 products: flat, so 3.
//! - The V-cycle's fine-level products use a single-precision nodal-block copy
//!   of the matrix ([`BlockSym32`]: 4.4 bytes per entry against 12); PCG's own
//!   products stay in double precision, so the converged solution is not
//!   limited by single precision. Same iteration counts.
//! - Indefinite tangents (CIL, NONLINEAR): PCG reports pᵀAp ≤ 0 (or the
//!   smoother's blocks or the coarse factor fail); systems of at most
//!   [`FALLBACK_DIRECT_MAX_DOFS`] unknowns are then solved directly (reported
//!   as 0 iterations), larger ones return [`Error::Solver`].
//!
//! Measured 2026-11-23, other jobs paused (`hocurve bench`, bench/README.md),
//! one increment from a zero start: iterations 10, 9, 13–14, 12, 16 at
//! p = 2..6, the same at every mesh size; solve time ∝ N^0.94 at p = 4 from
//! 2,000 to 1,161,402 unknowns, which five increments curve in 62–66 s and 6.8 GB.
//! With static condensation (session 5): iterations 10, 9, 13, 9–10, 13;
//! solve ∝ N^0.97; the 1,161,402 unknowns in 40.6 s and 6.3 GB.
//! The solve is dominated by products with the fine matrix (memory-bound); at
//! p = 5–6 the numeric set-up of the coarse levels in the first increment
//! (Galerkin products, coarsest factorisation) is about half of it.

use super::bsr::{BlockSym32, Operator};
use super::pcg::{try_pcg, PcgParams, SymmetricOperator, WithValues};
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
    /// Fine-level smoothing and residuals of the V-cycle with a single-precision
    /// copy of the matrix ([`BlockSym32`]); PCG's own products stay in double.
    pub single_precision_smoother: bool,
}

impl Default for IterativeParams {
    fn default() -> Self {
        IterativeParams {
            pcg: PcgParams::default(),
            smoother: ChebyshevParams::default(),
            reuse_coarse: true,
            fallback_max_dofs: FALLBACK_DIRECT_MAX_DOFS,
            single_precision_smoother: true,
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
    /// Single-precision copy of the fine matrix for the preconditioner's
    /// products (when `params.single_precision_smoother` and the pattern is in
    /// nodal blocks).
    fine32: Option<BlockSym32>,
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
        // A pattern not in nodal blocks (an external caller's) keeps double precision.
        let fine32 = if params.single_precision_smoother { BlockSym32::try_new(pattern, block).ok() } else { None };
        Ok(IterativeSolver {
            fine32,
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
        if let Some(f) = &mut self.fine32 {
            f.update(pattern, values);
        }
        let exact = WithValues(&self.op, values);
        let fine: &dyn Operator = match &self.fine32 {
            Some(f) => f,
            None => &exact,
        };
        let smoother = Chebyshev::try_new_from(fine, pattern, values, self.block, self.params.smoother, start)?;
        if let Some(c) = &mut self.coarse {
            if !(self.params.reuse_coarse && c.is_ready()) {
                c.try_update(&self.op, values)?;
            }
        }
        let op = &self.op;
        let mut pre = VCycle::new(fine, &smoother, self.coarse.as_mut());
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
        assert_eq!(stats.iterations, 0, "solved by the direct fallback");
        assert!(x.iter().zip(&x_true).all(|(p, q)| (p - q).abs() < 1e-9));
        let params = IterativeParams { fallback_max_dofs: 10, ..Default::default() };
        let mut solver = IterativeSolver::try_new(&a, 1, Vec::new(), params).unwrap();
        let r = solver.solve(&a, &v, &b, &mut vec![0.0; a.n]);
        assert!(matches!(r, Err(Error::Solver(ref m)) if m.contains("direct fallback")), "{r:?}");
    }
}
