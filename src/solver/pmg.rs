//! p-multigrid preconditioner: a V-cycle over nested levels with Chebyshev
//! smoothing on block Jacobi, Galerkin coarse operators A_k = P_kᵀ A_{k−1} P_k,
//! and the coarsest level factored by sparse Cholesky.
//!
//! The prolongations P_k and the patterns of the A_k come from outside (the
//! caller knows the mesh: for hocurve, the orders p → p/2 → … → 1 of nested
//! Lagrange spaces, see `assembly::multigrid_levels`). Symbolic work once
//! (transposes, transposed patterns, Cholesky analysis), numeric work per matrix.
//!
//! One application on a level (a symmetric V-cycle, so that PCG may use it):
//! x = S r; x += P B_c Pᵀ (r − A x); x += S (r − A x), B_c the cycle on the
//! next level (A_c⁻¹ on the coarsest), where
//! S is `degree` steps of Chebyshev iteration on D⁻¹A from zero over
//! [λ_max/ratio, λ_max] (Adams, Brezina, Hu, Tuminaro 2003), D the nodal
//! blocks of A, or on the nodes of a line through stretched layers the
//! whole block of the line (`super::lines`, groups from the caller as the
//! prolongations are); S is a polynomial in D⁻¹A times D⁻¹, hence
//! symmetric, and the cycle costs 2·degree products with A.

use rayon::prelude::*;

use super::bsr::Operator;
use super::lines::LineFactors;
use super::pcg::{axpby_in_place, dot, BlockJacobi, SymmetricOperator, WithValues};
use super::{NodeGroups, SparseCholesky, SparseRows, SymmetricCsc};
use crate::{Error, Result, SolverFailure};

/// Fine (node) rows per chunk of W = A P in [`galerkin_product`].
const W_CHUNK: usize = 256;

/// Passes over the fine rows in [`galerkin_product`]: W is held for one
/// pass's rows at a time.
const W_PASSES: usize = 8;

/// The `B`×`B` blocks (S, A(R, S)) of fine node row R, given to the callback.
type BlockRow<'a, const B: usize> = dyn Fn(usize, &mut dyn FnMut(usize, &[[f64; B]; B])) + Sync + 'a;

/// The lower-triangle values of A_c = Pᵀ A P on `coarse` (its pattern):
/// W = A P row by row, then column J of A_c = Σ_r P[r, J] W[r, ·]. Products
/// outside `coarse` (cancellations to round-off, for nested spaces) are dropped.
///
/// W is the largest transient of the preconditioner's set-up (a row of W
/// has about as many entries as a row of A), so it is built for an eighth
/// of the fine rows at a time ([`W_PASSES`]). Each pass adds its part of
/// every coarse column; the sums do not depend on the number of threads.
///
/// When A and A_c are in nodal-block layout and P = p ⊗ I (the same
/// interpolation for every component, as for hocurve's nested Lagrange
/// spaces), the product runs on the nodes' 3×3 (2×2) blocks: the same
/// sums with a ninth (a quarter) of the index work, about twice as fast
/// (p = 4 → 2 on the sphere cavity of bench/compare_gmsh.sh: 0.14–0.19 s
/// against 0.35–0.39 s); else entry by entry.
#[cfg(any(test, feature = "internals"))]
pub fn galerkin_product(a: WithValues, p: &SparseRows, pt: &SparseRows, coarse: &SymmetricCsc) -> Vec<f64> {
    let b = a.block();
    if let Some(pn) = nodal_prolongation(p, b).filter(|_| b > 1) {
        if let Some(values) = galerkin_nodal(a, &pn, &pn.transpose(), coarse) {
            return values;
        }
    }
    galerkin_entrywise(a, p, pt, coarse)
}

/// [`galerkin_product`] for P = `pn` ⊗ I on nodal blocks (`pnt` = pnᵀ);
/// None when the coarse pattern is not in nodal blocks.
fn galerkin_nodal(a: WithValues, pn: &SparseRows, pnt: &SparseRows, coarse: &SymmetricCsc) -> Option<Vec<f64>> {
    let nodes = super::bsr::nodal_blocks(coarse, a.block()).ok()?;
    Some(match a.block() {
        2 => galerkin_blocks::<2>(&|r, f| a.for_each_block::<2>(r, f), pn, pnt, coarse, &nodes),
        _ => galerkin_blocks::<3>(&|r, f| a.for_each_block::<3>(r, f), pn, pnt, coarse, &nodes),
    })
}

/// A coarse level's prolongation P to the level above, and Pᵀ, kept on the
/// nodes when P = p ⊗ I_b (each component interpolated alike, b = 2 or 3):
/// one weight read moves a node's b components, about a third of the bytes
/// of P entry by entry in 3D, and the sums are the same, in the same order.
struct Transfer {
    /// p when `block` > 1, else P itself.
    p: SparseRows,
    pt: SparseRows,
    block: usize,
}

impl Transfer {
    fn new(p: SparseRows, block: usize) -> Transfer {
        match nodal_prolongation(&p, block).filter(|_| matches!(block, 2 | 3)) {
            Some(pn) => Transfer { pt: pn.transpose(), p: pn, block },
            None => Transfer { pt: p.transpose(), p, block: 1 },
        }
    }

    /// y = P x.
    fn prolong_into(&self, x: &[f64], y: &mut [f64]) {
        kron_matvec(&self.p, self.block, x, y);
    }

    /// y = Pᵀ x.
    fn restrict_into(&self, x: &[f64], y: &mut [f64]) {
        kron_matvec(&self.pt, self.block, x, y);
    }

    /// A_c = Pᵀ A P on `coarse` ([`galerkin_product`]).
    fn galerkin(&self, a: WithValues, coarse: &SymmetricCsc) -> Vec<f64> {
        if self.block > 1 && self.block == a.block() {
            if let Some(values) = galerkin_nodal(a, &self.p, &self.pt, coarse) {
                return values;
            }
        }
        // Not on nodes: P was not p ⊗ I, or the coarse pattern or A is not in nodal blocks.
        if self.block == 1 {
            return galerkin_entrywise(a, &self.p, &self.pt, coarse);
        }
        galerkin_entrywise(a, &kron_identity(&self.p, self.block), &kron_identity(&self.pt, self.block), coarse)
    }
}

/// y = (m ⊗ I_b) x, b = 1, 2 or 3.
fn kron_matvec(m: &SparseRows, b: usize, x: &[f64], y: &mut [f64]) {
    match b {
        1 => m.matvec_into(x, y),
        2 => kron_matvec_b::<2>(m, x, y),
        _ => kron_matvec_b::<3>(m, x, y),
    }
}

fn kron_matvec_b<const B: usize>(m: &SparseRows, x: &[f64], y: &mut [f64]) {
    const ROWS: usize = 1024;
    y.par_chunks_mut(ROWS * B).enumerate().for_each(|(i, yc)| {
        for (j, yr) in yc.chunks_exact_mut(B).enumerate() {
            let r = i * ROWS + j;
            let mut sum = [0.0; B];
            for k in m.row_ptr[r]..m.row_ptr[r + 1] {
                let (w, c) = (m.val[k], m.col[k] as usize * B);
                for (s, xc) in sum.iter_mut().zip(&x[c..c + B]) {
                    *s += w * xc;
                }
            }
            yr.copy_from_slice(&sum);
        }
    });
}

/// m ⊗ I_b entry by entry.
fn kron_identity(m: &SparseRows, b: usize) -> SparseRows {
    let rows: Vec<Vec<(u32, f64)>> = (0..m.n_rows * b)
        .map(|r| {
            let (node, d) = (r / b, r % b);
            (m.row_ptr[node]..m.row_ptr[node + 1]).map(|k| (m.col[k] * b as u32 + d as u32, m.val[k])).collect()
        })
        .collect();
    SparseRows::from_rows(m.n_cols * b, &rows)
}

/// [`galerkin_product`] entry by entry (blocks of one).
fn galerkin_entrywise(a: WithValues, p: &SparseRows, pt: &SparseRows, coarse: &SymmetricCsc) -> Vec<f64> {
    let rows: Vec<Vec<u32>> =
        (0..coarse.n).map(|c| coarse.row_idx[coarse.col_ptr[c]..coarse.col_ptr[c + 1]].to_vec()).collect();
    let row = |r: usize, f: &mut dyn FnMut(usize, &[[f64; 1]; 1])| a.row(r).for_each(|(s, v)| f(s, &[[v]]));
    galerkin_blocks::<1>(&row, p, pt, coarse, &rows)
}

/// p with P = p ⊗ I_b on nodal blocks (rows and columns node·b + component),
/// or None if P is not of that form.
fn nodal_prolongation(p: &SparseRows, b: usize) -> Option<SparseRows> {
    if !(p.n_rows.is_multiple_of(b) && p.n_cols.is_multiple_of(b)) {
        return None;
    }
    let mut out = SparseRows { n_rows: p.n_rows / b, n_cols: p.n_cols / b, row_ptr: vec![0], ..Default::default() };
    for node in 0..out.n_rows {
        let row = |ii: usize| p.row_ptr[node * b + ii]..p.row_ptr[node * b + ii + 1];
        let first = row(0);
        for k in first.clone() {
            let c = p.col[k] as usize;
            if !c.is_multiple_of(b) {
                return None;
            }
            out.col.push((c / b) as u32);
            out.val.push(p.val[k]);
        }
        for ii in 1..b {
            let r = row(ii);
            let same = r.len() == first.len()
                && r.zip(first.clone()).all(|(k, k0)| p.col[k] == p.col[k0] + ii as u32 && p.val[k] == p.val[k0]);
            if !same {
                return None;
            }
        }
        out.row_ptr.push(out.col.len());
    }
    Some(out)
}

/// A_c = Pᵀ A P for P = p ⊗ I_B on nodal blocks, A's node rows given by
/// `row` ([`galerkin_product`]): W(R, J) = Σ_S A(R, S) p(S, J), then node
/// column J of A_c, A_c(I, J) = (Σ_R p(R, J) W(R, I))ᵀ for I ≥ J.
/// `nodes`: the node list of each of the coarse pattern's node columns
/// ([`super::bsr::nodal_blocks`]).
fn galerkin_blocks<const B: usize>(
    row: &BlockRow<B>,
    p: &SparseRows,
    pt: &SparseRows,
    coarse: &SymmetricCsc,
    nodes: &[Vec<u32>],
) -> Vec<f64> {
    let nc = p.n_cols;
    let mut out = vec![0.0f64; coarse.nnz()];
    let zero = [[0.0f64; B]; B];
    let cp = &coarse.col_ptr;
    // The values of node column J (its B columns) are contiguous.
    let node_ptr: Vec<usize> = (0..=nc).map(|j| cp[j * B]).collect();
    let pass_rows = p.n_rows.div_ceil(W_PASSES).div_ceil(W_CHUNK) * W_CHUNK;
    for first in (0..p.n_rows).step_by(pass_rows.max(1)) {
        let rows = first..(first + pass_rows).min(p.n_rows);
        let w = w_chunks::<B>(row, p, rows.clone());
        let w_row = |r: usize| {
            let (ptr, cols, vals) = &w[(r - rows.start) / W_CHUNK];
            let range = ptr[(r - rows.start) % W_CHUNK] as usize..ptr[(r - rows.start) % W_CHUNK + 1] as usize;
            cols[range.clone()].iter().zip(&vals[range])
        };
        let columns = super::split_by(&mut out, &node_ptr, 1);
        columns.into_par_iter().enumerate().for_each_init(
            || vec![zero; nc],
            |acc, (j, column)| {
                let pt_row = &pt.col[pt.row_ptr[j]..pt.row_ptr[j + 1]];
                let ks = pt.row_ptr[j] + pt_row.partition_point(|&r| (r as usize) < rows.start)
                    ..pt.row_ptr[j] + pt_row.partition_point(|&r| (r as usize) < rows.end);
                for k in ks.clone() {
                    let (r, pr) = (pt.col[k] as usize, pt.val[k]);
                    for (&i, wb) in w_row(r) {
                        if i as usize >= j {
                            for (arow, wrow) in acc[i as usize].iter_mut().zip(wb) {
                                for (x, &y) in arow.iter_mut().zip(wrow) {
                                    *x += pr * y;
                                }
                            }
                        }
                    }
                }
                // Entry (I·B + ii, J·B + jj) = acc[I][jj][ii], at position m·B + ii − jj of column J·B + jj.
                for jj in 0..B {
                    let base = cp[j * B + jj] - node_ptr[j];
                    for (m, &i) in nodes[j].iter().enumerate() {
                        let ab = &acc[i as usize];
                        for ii in if m == 0 { jj } else { 0 }..B {
                            column[base + m * B + ii - jj] += ab[jj][ii];
                        }
                    }
                }
                // Reset every touched slot (including those outside the pattern).
                for k in ks {
                    for (&i, _) in w_row(pt.col[k] as usize) {
                        acc[i as usize] = zero;
                    }
                }
            },
        );
    }
    out
}

/// W = A P by node rows on the fine `rows`, per chunk of [`W_CHUNK`]
/// rows: row starts (relative to the chunk), coarse nodes, blocks.
#[allow(clippy::type_complexity)]
fn w_chunks<const B: usize>(
    row: &BlockRow<B>,
    p: &SparseRows,
    rows: std::ops::Range<usize>,
) -> Vec<(Vec<u32>, Vec<u32>, Vec<[[f64; B]; B]>)> {
    let nc = p.n_cols;
    let zero = [[0.0f64; B]; B];
    let scratch = || (vec![zero; nc], vec![false; nc], Vec::<u32>::new());
    (0..rows.len().div_ceil(W_CHUNK))
        .into_par_iter()
        .map_init(scratch, |(acc, seen, list), t| {
            let chunk = rows.start + t * W_CHUNK..(rows.start + (t + 1) * W_CHUNK).min(rows.end);
            let mut ptr = Vec::with_capacity(chunk.len() + 1);
            ptr.push(0u32);
            let (mut cols, mut vals) = (Vec::new(), Vec::new());
            for r in chunk {
                row(r, &mut |s, blk| {
                    for k in p.row_ptr[s]..p.row_ptr[s + 1] {
                        let (j, pv) = (p.col[k] as usize, p.val[k]);
                        if !seen[j] {
                            seen[j] = true;
                            list.push(j as u32);
                        }
                        for (arow, brow) in acc[j].iter_mut().zip(blk) {
                            for (x, &y) in arow.iter_mut().zip(brow) {
                                *x += y * pv;
                            }
                        }
                    }
                });
                for &j in list.iter() {
                    cols.push(j);
                    vals.push(acc[j as usize]);
                    acc[j as usize] = zero;
                    seen[j as usize] = false;
                }
                list.clear();
                ptr.push(cols.len() as u32);
            }
            cols.shrink_to_fit();
            vals.shrink_to_fit();
            (ptr, cols, vals)
        })
        .collect()
}

/// Chebyshev smoothing parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChebyshevParams {
    /// Products with A per smoothing step (polynomial degree).
    pub degree: usize,
    /// The smoother targets [λ_max/ratio, λ_max] of D⁻¹A.
    pub ratio: f64,
    /// Lanczos steps for λ_max (the largest Ritz value, then times 1.1;
    /// one product with A each, plus one for the start).
    pub power_iterations: usize,
}

impl Default for ChebyshevParams {
    fn default() -> Self {
        ChebyshevParams { degree: 3, ratio: 30.0, power_iterations: 12 }
    }
}

/// Chebyshev smoother on D⁻¹A for one matrix.
///
/// The V-cycle built on it is symmetric positive definite (for a symmetric
/// positive definite A, and an exact or SPD coarse solve) exactly when the
/// Chebyshev error polynomial r, r(0) = 1, satisfies |r(λ)| < 1 on the
/// spectrum of D⁻¹A: the cycle's inverse is then the sum of the SPD
/// symmetrised smoother (1 − r(D⁻¹A)²)(D⁻¹A)⁻¹D⁻¹ and an SPD coarse term. On
/// [lo, hi] the polynomial is small, on (0, lo) it falls from 1, and above hi
/// it grows: |r(λ)| < 1 holds up to λ = hi + lo and fails beyond. Hence the
/// need for hi + lo > λ_max(D⁻¹A): a Lanczos estimate from below
/// (times 1.1) can miss a mode localised on a few nodes (a sliver cell) and
/// give an indefinite preconditioner; [`Self::try_new_safe`] takes hi from a
/// Gershgorin bound instead.
pub struct Chebyshev {
    jacobi: BlockJacobi,
    lambda_max: f64,
    /// The Lanczos estimate of λ_max(D⁻¹A) (not enlarged).
    estimate: f64,
    /// Lower end of the smoothed interval.
    lo: f64,
    params: ChebyshevParams,
    power: Vec<f64>,
}

impl Chebyshev {
    /// Invert the diagonal blocks and estimate λ_max(D⁻¹A) by Lanczos
    /// (times 1.1: the estimate approaches λ_max from below).
    #[cfg(test)]
    pub fn try_new(a: WithValues, block: usize, params: ChebyshevParams) -> Result<Chebyshev> {
        Self::try_with_jacobi(&a, BlockJacobi::try_new(a.pattern(), a.values(), block)?, params, None)
    }

    /// The smoother for the inverted diagonal blocks `jacobi` (nodal or
    /// line blocks) of the matrix that `op` applies (or an approximation of
    /// it, single precision), with λ_max(D⁻¹A) estimated by Lanczos, times
    /// 1.1. With `start`, the dominant vector of a previous, similar matrix
    /// ([`Self::power_vector`]), `power_iterations / 6` steps (at least 2)
    /// suffice.
    ///
    /// The warm start is what the sequence of load increments relies on, and
    /// its weak point: if the new matrix has a larger eigenvalue on a mode the
    /// previous dominant vector barely contains (a cell that became nearly
    /// degenerate), two steps do not find it (tests/solvers.rs, one sliver of
    /// quality 1e-5: hi = 3.14 against λ_max = 3.85 at p = 2, 4.89 against
    /// 5.37 at p = 4). PCG then sees rᵀz ≤ 0 or crawls, and
    /// [`super::IterativeSolver`] rebuilds with [`Self::try_new_safe`].
    pub fn try_with_jacobi(
        op: &dyn Operator,
        jacobi: BlockJacobi,
        params: ChebyshevParams,
        start: Option<Vec<f64>>,
    ) -> Result<Chebyshev> {
        let steps = if start.is_some() { (params.power_iterations / 6).max(2) } else { params.power_iterations.max(1) };
        let (lambda, v) = lambda_max_estimate(op, &jacobi, steps, start)?;
        let lambda_max = 1.1 * lambda;
        Ok(Chebyshev { jacobi, lambda_max, estimate: lambda, lo: lambda_max / params.ratio, params, power: v })
    }

    /// The smoother with a guaranteed interval: hi = ‖D⁻¹A‖_∞ (Gershgorin,
    /// [`BlockJacobi::row_sum_bound`], ≥ λ_max(D⁻¹A)) and lo = min(1.1·λ, hi)
    /// / ratio for a cold Lanczos estimate λ; the products in double precision
    /// with the matrix `a` itself. hi ≥ λ_max makes
    /// |r| < 1 on the whole spectrum, so the V-cycle is SPD. The bound is
    /// loose (4–6× λ_max at p = 2–4 on the sliver cube of tests/solvers.rs),
    /// so the smoothing is weaker (1.5–2× the PCG iterations): this is the
    /// fallback, not the default.
    pub fn try_new_safe(a: WithValues, block: usize, params: ChebyshevParams) -> Result<Chebyshev> {
        Self::try_safe_with_jacobi(a, BlockJacobi::try_new(a.pattern(), a.values(), block)?, params)
    }

    /// [`Self::try_new_safe`] with the diagonal blocks already inverted.
    pub fn try_safe_with_jacobi(a: WithValues, jacobi: BlockJacobi, params: ChebyshevParams) -> Result<Chebyshev> {
        let bound = jacobi.row_sum_bound(a);
        if !(bound > 0.0 && bound.is_finite()) {
            return Err(Error::solver(
                SolverFailure::Setup,
                format!("Chebyshev: the bound {bound:.3e} of λ_max is not positive"),
            ));
        }
        let steps = params.power_iterations.max(SAFE_POWER_ITERATIONS);
        let (lambda, v) = lambda_max_estimate(&a, &jacobi, steps, None)?;
        let lo = (1.1 * lambda).min(bound) / params.ratio;
        Ok(Chebyshev { jacobi, lambda_max: bound, estimate: lambda, lo, params, power: v })
    }

    /// Upper end of the smoothed interval.
    #[cfg(test)]
    pub fn lambda_max(&self) -> f64 {
        self.lambda_max
    }

    /// The Lanczos estimate of λ_max(D⁻¹A) it was built with.
    pub fn estimate(&self) -> f64 {
        self.estimate
    }

    /// A fresh Lanczos estimate of λ_max(D⁻¹A) from the fixed start vector
    /// (`steps` products with `op`), without the factor 1.1: to check a
    /// warm-started estimate ([`Self::try_with_jacobi`]).
    pub fn cold_estimate(&self, op: &dyn Operator, steps: usize) -> Result<f64> {
        lambda_max_estimate(op, &self.jacobi, steps.max(1), None).map(|(lambda, _)| lambda)
    }

    /// The approximate dominant vector of D⁻¹A (a start for the next, similar matrix).
    pub fn power_vector(self) -> Vec<f64> {
        self.power
    }

    /// x = S r (Chebyshev from zero).
    fn smooth_into(&self, op: &dyn Operator, r: &[f64], x: &mut [f64], w: &mut SmootherWork) {
        let hi = self.lambda_max;
        let lo = self.lo;
        let (theta, delta) = ((hi + lo) / 2.0, (hi - lo) / 2.0);
        let sigma = theta / delta;
        let mut rho = 1.0 / sigma;
        w.res.copy_from_slice(r);
        self.jacobi.apply_into(&w.res, &mut w.d);
        w.d.iter_mut().for_each(|v| *v /= theta);
        x.copy_from_slice(&w.d);
        for _ in 1..self.params.degree {
            op.apply_into(&w.d, &mut w.t);
            axpby_in_place(-1.0, &w.t, 1.0, &mut w.res);
            self.jacobi.apply_into(&w.res, &mut w.z);
            let rho_new = 1.0 / (2.0 * sigma - rho);
            axpby_in_place(2.0 * rho_new / delta, &w.z, rho_new * rho, &mut w.d);
            axpby_in_place(1.0, &w.d, 1.0, x);
            rho = rho_new;
        }
    }
}

/// Power-iteration steps of [`Chebyshev::try_new_safe`] (for the lower end
/// of the interval only).
const SAFE_POWER_ITERATIONS: usize = 20;

/// Estimate λ_max(D⁻¹A) by `steps` steps of Lanczos on the symmetric
/// S = Rᵀ A R (R Rᵀ = D⁻¹, [`BlockJacobi::inverse_factor`]), which has the
/// eigenvalues of D⁻¹A, started from Rᵀ A x = S R⁻¹x, a power step from
/// `start` (a dominant vector of D⁻¹A for a similar matrix) or a fixed
/// vector. Returns the largest Ritz value, a lower bound of λ_max and much
/// closer than power iteration's after as many products (its error falls
/// like a Chebyshev polynomial over the spectrum, not like a power of
/// λ₂/λ₁: cells near degenerate put several eigenvalues near the top), and
/// R times its Ritz vector, an approximate dominant vector of D⁻¹A, the
/// next start.
fn lambda_max_estimate(
    op: &dyn Operator,
    jacobi: &BlockJacobi,
    steps: usize,
    start: Option<Vec<f64>>,
) -> Result<(f64, Vec<f64>)> {
    let n = op.n();
    let x = start
        .filter(|v| v.len() == n)
        .unwrap_or_else(|| (0..n).map(|i| 1.0 + 0.5 * ((i as f64) * 1.618).sin()).collect());
    let not_positive = |what: &str, value: f64| {
        Error::solver(SolverFailure::Setup, format!("Chebyshev: {what} {value:.3e} is not positive"))
    };
    let factor = jacobi.inverse_factor();
    let (mut y, mut z) = (vec![0.0; n], vec![0.0; n]);
    let mut q = vec![0.0; n];
    op.apply_into(&x, &mut z);
    factor.apply_into(&z, &mut q, true);
    let norm = dot(&q, &q).sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return Err(not_positive("the norm of the start", norm));
    }
    q.iter_mut().for_each(|x| *x /= norm);
    let mut q_prev = vec![0.0; n];
    let mut w = vec![0.0; n];
    let (mut alpha, mut beta): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for _ in 0..steps.max(1) {
        // w = S q − α q − β q_prev.
        factor.apply_into(&q, &mut y, false);
        op.apply_into(&y, &mut z);
        factor.apply_into(&z, &mut w, true);
        let al = dot(&q, &w);
        let b_prev = beta.last().copied().unwrap_or(0.0);
        w.iter_mut().zip(q.iter().zip(&q_prev)).for_each(|(w, (&q, &p))| *w -= al * q + b_prev * p);
        let b = dot(&w, &w).sqrt();
        alpha.push(al);
        basis.push(q.clone());
        if !(b > 1e-12 * al.abs() && b.is_finite()) {
            break;
        }
        beta.push(b);
        std::mem::swap(&mut q_prev, &mut q);
        q.iter_mut().zip(&w).for_each(|(q, &w)| *q = w / b);
    }
    let m = alpha.len();
    let t = faer::Mat::<f64>::from_fn(m, m, |i, j| match i.abs_diff(j) {
        0 => alpha[i],
        1 => beta[i.min(j)],
        _ => 0.0,
    });
    let eig = t
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|e| Error::solver(SolverFailure::Setup, format!("Chebyshev: Lanczos eigenproblem: {e:?}")))?;
    let lambda = eig.S().column_vector()[m - 1];
    if !(lambda > 0.0 && lambda.is_finite()) {
        return Err(not_positive("λ_max estimate", lambda));
    }
    let coef = eig.U().col(m - 1);
    let mut ritz = vec![0.0; n];
    for (j, qj) in basis.iter().enumerate() {
        let c = coef[j];
        ritz.iter_mut().zip(qj).for_each(|(r, &x)| *r += c * x);
    }
    factor.apply_into(&ritz, &mut y, false);
    Ok((lambda, y))
}

/// Work vectors of the smoother.
struct SmootherWork {
    res: Vec<f64>,
    d: Vec<f64>,
    t: Vec<f64>,
    z: Vec<f64>,
}

/// One coarse level: the prolongation to the level above, its transpose, the
/// Galerkin operator on its pattern and either a smoother (intermediate
/// levels) or a Cholesky factor (the coarsest).
struct Level {
    transfer: Transfer,
    pattern: SymmetricCsc,
    op: SymmetricOperator,
    values: Vec<f64>,
    smoother: Option<Chebyshev>,
    /// Line blocks of its smoother (not on the coarsest level).
    lines: Option<NodeGroups>,
    chol: Option<(SparseCholesky, Vec<f64>)>,
    work: SmootherWork,
    s: Vec<f64>,
    e: Vec<f64>,
    rhs: Vec<f64>,
    x: Vec<f64>,
}

/// The coarse levels of the p-multigrid V-cycle, finest first; the last one is
/// solved by sparse Cholesky.
pub struct Hierarchy {
    levels: Vec<Level>,
    block: usize,
    params: ChebyshevParams,
    ready: bool,
    /// The first coarse level's operator for the next fast set-up, instead
    /// of the Galerkin product ([`Self::set_first_values`]).
    given: Option<Vec<f64>>,
}

impl Hierarchy {
    /// Symbolic set-up from (P_k, pattern_k) per coarse level, finest first:
    /// P_k maps level k to level k − 1 (level 0 is the fine matrix).
    pub fn try_new(
        levels: Vec<(SparseRows, SymmetricCsc)>,
        block: usize,
        params: ChebyshevParams,
    ) -> Result<Hierarchy> {
        let n_levels = levels.len();
        let mut out = Vec::with_capacity(n_levels);
        for (k, (p, pattern)) in levels.into_iter().enumerate() {
            if pattern.n != p.n_cols {
                return Err(Error::solver(
                    SolverFailure::Setup,
                    format!("coarse pattern has {} rows, P has {} columns", pattern.n, p.n_cols),
                ));
            }
            let chol =
                if k + 1 == n_levels { Some((SparseCholesky::try_analyse(&pattern)?, Vec::new())) } else { None };
            let n = pattern.n;
            let v = || vec![0.0; n];
            out.push(Level {
                transfer: Transfer::new(p, block),
                op: SymmetricOperator::try_new(&pattern, block)?,
                values: vec![0.0; pattern.nnz()],
                pattern,
                smoother: None,
                lines: None,
                chol,
                work: SmootherWork { res: v(), d: v(), t: v(), z: v() },
                s: v(),
                e: v(),
                rhs: v(),
                x: v(),
            });
        }
        Ok(Hierarchy { levels: out, block, params, ready: false, given: None })
    }

    /// Smooth coarse level k (0 the finest coarse level) in the line
    /// blocks `lines[k]` (in its fast mode; the safe mode keeps nodal blocks).
    pub fn set_lines(&mut self, lines: Vec<NodeGroups>) {
        for (l, g) in self.levels.iter_mut().zip(lines) {
            l.lines = Some(g).filter(|g| !g.is_empty());
        }
        self.ready = false;
    }

    /// The first coarse level's operator (values of its pattern) for the
    /// next set-up in the fast mode, instead of PᵀAP: one assembled on that
    /// level's own mesh. The safe mode, and later set-ups, take the product.
    /// Ignored unless it fits the level's pattern.
    pub fn set_first_values(&mut self, values: Vec<f64>) {
        self.given = self.levels.first().filter(|l| l.pattern.nnz() == values.len()).map(|_| values);
        self.ready = false;
    }

    /// True once [`Self::try_update_with`] has succeeded.
    pub fn is_ready(&self) -> bool {
        self.ready
    }

    /// Numeric set-up for the fine matrix `a`: Galerkin operators
    /// level by level, smoothers, and the factor of the coarsest; with
    /// `safe`, the smoothers of [`Chebyshev::try_new_safe`].
    pub fn try_update_with(&mut self, a: WithValues, safe: bool) -> Result<()> {
        self.ready = false;
        let mut given = self.given.take().filter(|_| !safe);
        for k in 0..self.levels.len() {
            let (above, rest) = self.levels.split_at_mut(k);
            let l = &mut rest[0];
            l.values = match above.last() {
                None => match given.take() {
                    Some(values) => values,
                    None => l.transfer.galerkin(a, &l.pattern),
                },
                Some(up) => l.transfer.galerkin(up.op.with(&up.pattern, &up.values), &l.pattern),
            };
            if let Some((chol, factor)) = &mut l.chol {
                *factor = chol.try_factor(&l.pattern, &l.values)?;
            } else if safe {
                l.smoother = Some(Chebyshev::try_new_safe(l.op.with(&l.pattern, &l.values), self.block, self.params)?);
            } else {
                let a = l.op.with(&l.pattern, &l.values);
                let lines = l.lines.as_ref().map(|g| LineFactors::try_new(&l.pattern, &l.values, self.block, g)).transpose()?;
                let jacobi = BlockJacobi::try_new_with_lines(&l.pattern, &l.values, self.block, lines)?;
                l.smoother = Some(Chebyshev::try_with_jacobi(&a, jacobi, self.params, None)?);
            }
        }
        self.ready = true;
        Ok(())
    }

    /// x = B_k r on coarse level k (V-cycle from there down).
    fn cycle_on(&mut self, k: usize) -> Result<()> {
        let (now, below) = self.levels.split_at_mut(k + 1);
        let l = &mut now[k];
        if let Some((chol, factor)) = &l.chol {
            l.x.copy_from_slice(&l.rhs);
            return chol.try_solve_in_place(factor, &mut l.x);
        }
        let smoother =
            l.smoother.as_ref().ok_or_else(|| Error::solver(SolverFailure::Setup, "p-multigrid level not set up"))?;
        let a = l.op.with(&l.pattern, &l.values);
        smoother.smooth_into(&a, &l.rhs, &mut l.x, &mut l.work);
        a.matvec_into(&l.x, &mut l.s);
        axpby_in_place(1.0, &l.rhs, -1.0, &mut l.s);
        let next = &mut below[0];
        next.transfer.restrict_into(&l.s, &mut next.rhs);
        self.cycle_on(k + 1)?;
        let (now, below) = self.levels.split_at_mut(k + 1);
        let (l, next) = (&mut now[k], &below[0]);
        next.transfer.prolong_into(&next.x, &mut l.e);
        axpby_in_place(1.0, &l.e, 1.0, &mut l.x);
        let a = l.op.with(&l.pattern, &l.values);
        a.matvec_into(&l.x, &mut l.s);
        axpby_in_place(1.0, &l.rhs, -1.0, &mut l.s);
        let smoother = l.smoother.as_ref().expect("checked above");
        smoother.smooth_into(&a, &l.s, &mut l.e, &mut l.work);
        axpby_in_place(1.0, &l.e, 1.0, &mut l.x);
        Ok(())
    }
}

/// The p-multigrid V-cycle z = B r for the fine matrix applied by `op` (the
/// matrix itself or a single-precision copy): smoothing with `smoother` on the
/// fine level, the coarse levels of `coarse`.
pub struct VCycle<'a> {
    op: &'a dyn Operator,
    smoother: &'a Chebyshev,
    coarse: Option<&'a mut Hierarchy>,
    work: SmootherWork,
    s: Vec<f64>,
    e: Vec<f64>,
}

impl<'a> VCycle<'a> {
    pub fn new(op: &'a dyn Operator, smoother: &'a Chebyshev, coarse: Option<&'a mut Hierarchy>) -> VCycle<'a> {
        let n = op.n();
        let coarse = coarse.filter(|c| !c.levels.is_empty() && c.levels.iter().all(|l| l.pattern.n > 0));
        let v = || vec![0.0; n];
        let work = SmootherWork { res: v(), d: v(), t: v(), z: v() };
        VCycle { op, smoother, coarse, work, s: v(), e: v() }
    }

    /// z = B r.
    pub fn apply_into(&mut self, r: &[f64], z: &mut [f64]) -> Result<()> {
        let op = self.op;
        self.smoother.smooth_into(op, r, z, &mut self.work);
        let Some(coarse) = self.coarse.as_deref_mut() else {
            return Ok(());
        };
        if !coarse.ready {
            return Err(Error::solver(SolverFailure::Setup, "p-multigrid hierarchy not set up"));
        }
        // s = r − A z; z += P B_1 Pᵀ s
        op.apply_into(z, &mut self.s);
        axpby_in_place(1.0, r, -1.0, &mut self.s);
        {
            let l = &mut coarse.levels[0];
            l.transfer.restrict_into(&self.s, &mut l.rhs);
        }
        coarse.cycle_on(0)?;
        let l = &coarse.levels[0];
        l.transfer.prolong_into(&l.x, &mut self.e);
        axpby_in_place(1.0, &self.e, 1.0, z);
        // z += S (r − A z)
        op.apply_into(z, &mut self.s);
        axpby_in_place(1.0, r, -1.0, &mut self.s);
        self.smoother.smooth_into(op, &self.s, &mut self.e, &mut self.work);
        axpby_in_place(1.0, &self.e, 1.0, z);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::pcg::tests::grid_laplacian;

    /// λ_max(D⁻¹A), D the `block` × `block` diagonal blocks of A (given by
    /// its lower triangle), from the dense symmetric D^(-1/2) A D^(-1/2).
    fn dense_lambda_max(a: &SymmetricCsc, v: &[f64], block: usize) -> f64 {
        let n = a.n;
        let mut m = faer::Mat::<f64>::zeros(n, n);
        for c in 0..n {
            for k in a.col_ptr[c]..a.col_ptr[c + 1] {
                let r = a.row_idx[k] as usize;
                m[(r, c)] = v[k];
                m[(c, r)] = v[k];
            }
        }
        let d = faer::Mat::<f64>::from_fn(n, n, |i, j| if i / block == j / block { m[(i, j)] } else { 0.0 });
        // D^(-1/2) A D^(-1/2), D^(-1/2) = U Λ^(-1/2) Uᵀ from D = U Λ Uᵀ.
        let e = d.self_adjoint_eigen(faer::Side::Lower).unwrap();
        let (u, lam) = (e.U(), e.S().column_vector());
        let h = faer::Mat::<f64>::from_fn(n, n, |i, j| (0..n).map(|k| u[(i, k)] * u[(j, k)] / lam[k].sqrt()).sum());
        let s = &h * &m * &h;
        *s.self_adjoint_eigenvalues(faer::Side::Lower).unwrap().last().unwrap()
    }

    /// The power iteration the estimate used to be: ‖D⁻¹A v‖ for unit v, `steps` times.
    fn power_iteration(op: &dyn Operator, jacobi: &BlockJacobi, steps: usize) -> f64 {
        let n = op.n();
        let mut v: Vec<f64> = (0..n).map(|i| 1.0 + 0.5 * ((i as f64) * 1.618).sin()).collect();
        let norm = dot(&v, &v).sqrt();
        v.iter_mut().for_each(|x| *x /= norm);
        let (mut av, mut u, mut lambda) = (vec![0.0; n], vec![0.0; n], 0.0);
        for _ in 0..steps {
            op.apply_into(&v, &mut av);
            jacobi.apply_into(&av, &mut u);
            lambda = dot(&u, &u).sqrt();
            v.iter_mut().zip(&u).for_each(|(x, &y)| *x = y / lambda);
        }
        lambda
    }

    /// A 7×7 grid with `b` coupled components per node and pseudo-random
    /// symmetric values; p the bilinear interpolation from every other node.
    fn block_problem(b: usize) -> (SymmetricCsc, Vec<f64>, SparseRows, SymmetricCsc) {
        let (m, mc) = (7, 4);
        let (a, mut v) = grid_laplacian(m, b);
        v.iter_mut().enumerate().for_each(|(k, x)| *x += ((k * 7919) % 1000) as f64 / 1000.0 - 0.5);
        let rows: Vec<Vec<(u32, f64)>> = (0..m * m)
            .flat_map(|node| {
                let (i, j) = (node % m, node / m);
                let weights = |t: usize| if t.is_multiple_of(2) { vec![(t / 2, 1.0)] } else { vec![(t / 2, 0.5), (t / 2 + 1, 0.5)] };
                let row: Vec<(usize, f64)> = weights(j)
                    .into_iter()
                    .flat_map(|(cj, wj)| weights(i).into_iter().map(move |(ci, wi)| (cj * mc + ci, wi * wj)))
                    .collect();
                (0..b).map(move |c| row.iter().map(|&(cn, w)| ((cn * b + c) as u32, w)).collect())
            })
            .collect();
        let p = SparseRows::from_rows(mc * mc * b, &rows);
        // Every coarse node coupled with every other (a dense lower triangle).
        let nc = mc * mc * b;
        let mut coarse = SymmetricCsc { n: nc, col_ptr: vec![0], row_idx: vec![] };
        for c in 0..nc {
            coarse.row_idx.extend((c..nc).map(|r| r as u32));
            coarse.col_ptr.push(coarse.row_idx.len());
        }
        (a, v, p, coarse)
    }

    #[test]
    fn the_block_galerkin_product_is_the_entrywise_one_and_the_dense_triple_product() {
        for b in [2, 3] {
            let (a, v, p, coarse) = block_problem(b);
            let op = SymmetricOperator::try_new(&a, b).unwrap();
            let mat = op.with(&a, &v);
            let pt = p.transpose();
            assert!(nodal_prolongation(&p, b).is_some(), "P = p ⊗ I");
            let blocks = galerkin_product(mat, &p, &pt, &coarse);
            let scalar = galerkin_entrywise(mat, &p, &pt, &coarse);
            // Dense Pᵀ A P.
            let (nf, nc) = (p.n_rows, p.n_cols);
            let (mut e, mut pe, mut ape, mut col) = (vec![0.0; nc], vec![0.0; nf], vec![0.0; nf], vec![0.0; nc]);
            for j in 0..nc {
                e.fill(0.0);
                e[j] = 1.0;
                p.matvec_into(&e, &mut pe);
                mat.matvec_into(&pe, &mut ape);
                pt.matvec_into(&ape, &mut col);
                for k in coarse.col_ptr[j]..coarse.col_ptr[j + 1] {
                    let want = col[coarse.row_idx[k] as usize];
                    let (i, tol) = (coarse.row_idx[k], 1e-12 * want.abs().max(1.0));
                    assert!((blocks[k] - want).abs() < tol, "b = {b}: ({i}, {j})");
                    assert!((scalar[k] - want).abs() < tol, "b = {b}: ({i}, {j})");
                }
            }
            // Not p ⊗ I: one component's weight differs.
            let mut q = p.clone();
            q.val[q.row_ptr[b * 10 + 1]] += 0.25;
            assert!(nodal_prolongation(&q, b).is_none());
        }
    }

    /// A level's transfers on the nodes give the entry-by-entry products of
    /// P and Pᵀ bit for bit, and its Galerkin product is PᵀAP's; a P that is
    /// not p ⊗ I stays entry by entry.
    #[test]
    fn nodal_transfers_are_the_entrywise_ones_bit_for_bit() {
        for b in [2, 3] {
            let (a, v, p, coarse) = block_problem(b);
            let pt = p.transpose();
            let mat = SymmetricOperator::try_new(&a, b).unwrap();
            let mat = mat.with(&a, &v);
            let mut q = p.clone();
            q.val[q.row_ptr[b * 10 + 1]] += 0.25;
            for (m, nodal) in [(&p, true), (&q, false)] {
                let t = Transfer::new(m.clone(), b);
                assert_eq!(t.block, if nodal { b } else { 1 });
                let mt = m.transpose();
                let xc: Vec<f64> = (0..m.n_cols).map(|i| (i as f64 * 0.37).sin() + 0.1).collect();
                let xf: Vec<f64> = (0..m.n_rows).map(|i| (i as f64 * 0.61).cos() - 0.2).collect();
                let (mut want, mut got) = (vec![0.0; m.n_rows], vec![1.0; m.n_rows]);
                m.matvec_into(&xc, &mut want);
                t.prolong_into(&xc, &mut got);
                assert!(want.iter().zip(&got).all(|(w, g)| w.to_bits() == g.to_bits()), "P x, b = {b}");
                let (mut want, mut got) = (vec![0.0; m.n_cols], vec![1.0; m.n_cols]);
                mt.matvec_into(&xf, &mut want);
                t.restrict_into(&xf, &mut got);
                assert!(want.iter().zip(&got).all(|(w, g)| w.to_bits() == g.to_bits()), "Pᵀ x, b = {b}");
            }
            let t = Transfer::new(p.clone(), b);
            assert_eq!(t.galerkin(mat, &coarse), galerkin_product(mat, &p, &pt, &coarse));
            // The entry-by-entry product from the nodal transfer (the block
            // of A differs from the transfer's).
            let scalar = SymmetricOperator::try_new(&a, 1).unwrap();
            let scalar = scalar.with(&a, &v);
            assert_eq!(t.galerkin(scalar, &coarse), galerkin_entrywise(scalar, &p, &pt, &coarse));
        }
    }

    /// Given first-level values serve the next fast set-up only; the safe
    /// mode, later set-ups, and values that do not fit take PᵀAP.
    #[test]
    fn given_first_level_values_serve_one_fast_set_up() {
        let (a, v, p, coarse) = block_problem(3);
        let op = SymmetricOperator::try_new(&a, 3).unwrap();
        let mat = op.with(&a, &v);
        let galerkin = galerkin_product(mat, &p, &p.transpose(), &coarse);
        let given: Vec<f64> = galerkin.iter().map(|x| 2.0 * x).collect();
        let mut h = Hierarchy::try_new(vec![(p, coarse)], 3, ChebyshevParams::default()).unwrap();
        h.set_first_values(given.clone());
        h.try_update_with(mat, false).unwrap();
        assert_eq!(h.levels[0].values, given);
        h.try_update_with(mat, false).unwrap();
        assert_eq!(h.levels[0].values, galerkin, "taken once");
        h.set_first_values(given.clone());
        h.try_update_with(mat, true).unwrap();
        assert_eq!(h.levels[0].values, galerkin, "the safe mode's product");
        h.set_first_values(given[1..].to_vec());
        h.try_update_with(mat, false).unwrap();
        assert_eq!(h.levels[0].values, galerkin, "values that do not fit the pattern");
    }

    #[test]
    fn lanczos_estimates_the_largest_eigenvalue_from_below_closer_than_power_iteration() {
        // 2D Laplacians: the top eigenvalues cluster (gaps O(h²)), where
        // power iteration converges slowly.
        for (m, block) in [(24, 1), (12, 3)] {
            let (a, v) = grid_laplacian(m, block);
            let truth = dense_lambda_max(&a, &v, block);
            let op = SymmetricOperator::try_new(&a, block).unwrap();
            let mat = op.with(&a, &v);
            let jacobi = BlockJacobi::try_new(&a, &v, block).unwrap();
            let cold = Chebyshev::try_new(mat, block, ChebyshevParams::default()).unwrap();
            let est = cold.estimate();
            let power = power_iteration(&mat, &jacobi, ChebyshevParams::default().power_iterations);
            println!("m {m} block {block}: λ_max {truth:.4}, Lanczos {est:.4}, power {power:.4}");
            assert!(est <= truth * (1.0 + 1e-12) && truth - est < 0.5 * (truth - power), "{est} {power} {truth}");
            // With the safety factor, the smoothed interval covers the spectrum.
            assert!(1.1 * est > truth);
            // Warm-started from its own Ritz vector, two steps find it again.
            let params = ChebyshevParams::default();
            let warm = Chebyshev::try_with_jacobi(&mat, jacobi, params, Some(cold.power_vector())).unwrap();
            assert!(warm.estimate() <= truth * (1.0 + 1e-12) && warm.estimate() >= est, "warm {}", warm.estimate());
        }
    }
}
