//! A linear solver supplied by the host (PETSc, MUMPS, hypre, ...).
//!
//! The host sees each reduced system K_ff u_f = b_f (free degrees of freedom
//! only) as a full symmetric matrix in CSR form: 0-based, both triangles,
//! column indices sorted within each row. [`ExternalAdapter`] converts the
//! library's lower-triangle CSC pattern to that CSR pattern once (a symbolic
//! map from every CSR entry to its lower-triangle value) and only copies the
//! values for each new system.

use std::fmt;
use std::sync::Arc;

use super::{LinearSolver, SolveStats, SolvedBy, SymmetricCsc};
use crate::{Error, Result, SolverFailure};

/// A full symmetric `n`×`n` matrix in CSR form, borrowed for one solve.
///
/// Row `i` holds columns `col_idx[row_ptr[i]..row_ptr[i + 1]]`, sorted and
/// 0-based, with values at the same positions of `values`; both (i, j) and
/// (j, i) are stored, with equal values.
#[derive(Debug, Clone, Copy)]
pub struct CsrView<'a> {
    pub n: usize,
    /// `n + 1` offsets; `row_ptr[0] = 0`, `row_ptr[n]` = number of entries.
    pub row_ptr: &'a [usize],
    pub col_idx: &'a [usize],
    pub values: &'a [f64],
}

impl CsrView<'_> {
    /// y = A x.
    pub fn matvec(&self, x: &[f64]) -> Vec<f64> {
        (0..self.n)
            .map(|i| (self.row_ptr[i]..self.row_ptr[i + 1]).map(|k| self.values[k] * x[self.col_idx[k]]).sum())
            .collect()
    }
}

/// The lower triangle of a symmetric `n`×`n` matrix by columns, borrowed
/// for one solve: column `j` holds the rows `row_idx[col_ptr[j]..col_ptr[j + 1]]`
/// (sorted, each ≥ j), with values at the same positions of `values`.
#[derive(Debug, Clone, Copy)]
pub struct LowerCscView<'a> {
    pub n: usize,
    pub col_ptr: &'a [usize],
    pub row_idx: &'a [u32],
    pub values: &'a [f64],
}

/// A host's linear solver: solves A x = b for a symmetric matrix A.
///
/// On entry `x` holds an initial guess (the previous increment's solution, or
/// zeros for a Newton correction); on exit, the solution. An `Err` stops the
/// run with [`Error::Solver`] carrying its message, and so does a non-finite
/// entry of `x`. Any `Fn(CsrView, &[f64], &mut [f64]) -> Result<(), String>`
/// closure that is `Send + Sync` is a `SystemSolver`:
///
/// ```
/// use hocurve::solver::{CsrView, ExternalSolver, SolverChoice};
///
/// // Jacobi iterations: fine for a demonstration on a diagonally dominant matrix.
/// let jacobi = |a: CsrView, b: &[f64], x: &mut [f64]| -> Result<(), String> {
///     for _ in 0..100 {
///         let ax = a.matvec(x);
///         for i in 0..a.n {
///             let d = (a.row_ptr[i]..a.row_ptr[i + 1]).find(|&k| a.col_idx[k] == i).ok_or("no diagonal")?;
///             x[i] += (b[i] - ax[i]) / a.values[d];
///         }
///     }
///     Ok(())
/// };
/// let choice = SolverChoice::External(ExternalSolver::new(jacobi));
/// assert_eq!(choice.name(), "external");
/// ```
pub trait SystemSolver: Send + Sync {
    fn solve(&self, a: CsrView<'_>, rhs: &[f64], x: &mut [f64]) -> std::result::Result<(), String>;
    /// [`Self::solve`], and the solver's iterations when it counts them
    /// (the report gives them per solve); by default it does not.
    fn solve_counted(&self, a: CsrView<'_>, rhs: &[f64], x: &mut [f64]) -> std::result::Result<Option<usize>, String> {
        self.solve(a, rhs, x).map(|()| None)
    }
    /// Whether the solver takes the matrix as its lower triangle
    /// ([`Self::solve_lower`]) instead of the full CSR matrix of
    /// [`Self::solve`], which is then never built (it costs 24 bytes per
    /// entry of the matrix); by default it does not.
    fn takes_lower_triangle(&self) -> bool {
        false
    }
    /// [`Self::solve_counted`] with the matrix as its lower triangle, for a
    /// solver whose [`Self::takes_lower_triangle`] is true.
    fn solve_lower(
        &self,
        a: LowerCscView<'_>,
        rhs: &[f64],
        x: &mut [f64],
    ) -> std::result::Result<Option<usize>, String> {
        let _ = (a, rhs, x);
        Err("this solver does not take the lower triangle".into())
    }
    /// The solver's name in the report (default "external").
    fn name(&self) -> &'static str {
        "external"
    }
}

impl<F> SystemSolver for F
where
    F: Fn(CsrView<'_>, &[f64], &mut [f64]) -> std::result::Result<(), String> + Send + Sync,
{
    fn solve(&self, a: CsrView<'_>, rhs: &[f64], x: &mut [f64]) -> std::result::Result<(), String> {
        self(a, rhs, x)
    }
}

/// A shared handle to a host's [`SystemSolver`], for
/// [`SolverChoice::External`](super::SolverChoice::External). Two handles
/// are equal when they share the same solver.
#[derive(Clone)]
pub struct ExternalSolver(pub Arc<dyn SystemSolver>);

impl ExternalSolver {
    pub fn new(solver: impl SystemSolver + 'static) -> ExternalSolver {
        ExternalSolver(Arc::new(solver))
    }
}

impl fmt::Debug for ExternalSolver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("ExternalSolver(..)")
    }
}

impl PartialEq for ExternalSolver {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Eq for ExternalSolver {}

/// The full CSR pattern of a lower-triangle CSC pattern, and for every CSR
/// entry the position of its value in the lower triangle's value array.
#[derive(Debug, Clone, Default)]
pub struct FullCsrPattern {
    pub n: usize,
    pub row_ptr: Vec<usize>,
    pub col_idx: Vec<usize>,
    /// `values_csr[k] = values_lower[source[k]]`.
    pub source: Vec<usize>,
}

impl FullCsrPattern {
    /// Mirror the strict lower triangle. Lower entry (r, c), r ≥ c, of column
    /// c goes to row r at column c and, off the diagonal, to row c at column
    /// r. Visiting the columns in increasing order fills every row in
    /// increasing column order: row i receives its columns j < i from columns
    /// j < i, then j = i and j > i from column i (whose rows are sorted).
    pub fn from_lower_csc(p: &SymmetricCsc) -> FullCsrPattern {
        let n = p.n;
        let mut count = vec![0usize; n + 1];
        for c in 0..n {
            for &r in &p.row_idx[p.col_ptr[c]..p.col_ptr[c + 1]] {
                let r = r as usize;
                count[r + 1] += 1;
                if r != c {
                    count[c + 1] += 1;
                }
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let row_ptr = count.clone();
        let nnz = row_ptr[n];
        let mut next = count;
        let (mut col_idx, mut source) = (vec![0; nnz], vec![0; nnz]);
        for c in 0..n {
            for k in p.col_ptr[c]..p.col_ptr[c + 1] {
                let r = p.row_idx[k] as usize;
                col_idx[next[r]] = c;
                source[next[r]] = k;
                next[r] += 1;
                if r != c {
                    col_idx[next[c]] = r;
                    source[next[c]] = k;
                    next[c] += 1;
                }
            }
        }
        FullCsrPattern { n, row_ptr, col_idx, source }
    }

    /// The CSR values of the lower-triangle `values`, into `out`.
    pub fn values_into(&self, lower: &[f64], out: &mut [f64]) {
        for (o, &k) in out.iter_mut().zip(&self.source) {
            *o = lower[k];
        }
    }
}

/// [`LinearSolver`] over a host's [`SystemSolver`]: the CSR pattern is built
/// once, the values are copied for each system; for a host that takes the
/// lower triangle, neither.
pub struct ExternalAdapter {
    host: ExternalSolver,
    csr: FullCsrPattern,
    values: Vec<f64>,
}

impl ExternalAdapter {
    pub fn new(host: ExternalSolver, pattern: &SymmetricCsc) -> ExternalAdapter {
        if host.0.takes_lower_triangle() {
            let csr = FullCsrPattern { n: pattern.n, ..Default::default() };
            return ExternalAdapter { host, csr, values: Vec::new() };
        }
        let csr = FullCsrPattern::from_lower_csc(pattern);
        let values = vec![0.0; csr.col_idx.len()];
        ExternalAdapter { host, csr, values }
    }
}

impl LinearSolver for ExternalAdapter {
    fn name(&self) -> &'static str {
        self.host.0.name()
    }

    fn solve(&mut self, pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], x: &mut [f64]) -> Result<SolveStats> {
        if pattern.n != self.csr.n || values.len() != pattern.nnz() {
            return Err(Error::solver(
                SolverFailure::External,
                format!(
                    "the external linear solver was set up for {} unknowns, got a system of {} with {} entries",
                    self.csr.n,
                    pattern.n,
                    values.len()
                ),
            ));
        }
        let iterations = if self.host.0.takes_lower_triangle() {
            let a = LowerCscView { n: pattern.n, col_ptr: &pattern.col_ptr, row_idx: &pattern.row_idx, values };
            self.host.0.solve_lower(a, rhs, x)
        } else {
            self.csr.values_into(values, &mut self.values);
            let a =
                CsrView { n: self.csr.n, row_ptr: &self.csr.row_ptr, col_idx: &self.csr.col_idx, values: &self.values };
            self.host.0.solve_counted(a, rhs, x)
        };
        let iterations = iterations.map_err(|m| {
            Error::solver(SolverFailure::External, format!("the external linear solver returned an error: {m}"))
        })?;
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::solver(
                SolverFailure::External,
                format!(
                    "the external linear solver returned a non-finite solution (unknown {i} of {} is {})",
                    x.len(),
                    x[i]
                ),
            ));
        }
        Ok(SolveStats { iterations: iterations.unwrap_or(0), solved_by: SolvedBy::External, fallback: None })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 5×5 lower pattern with a missing diagonal entry and a dense last row.
    fn pattern() -> (SymmetricCsc, Vec<f64>) {
        let cols: [&[u32]; 5] = [&[0, 2, 4], &[1, 4], &[2, 3, 4], &[4], &[4]];
        let mut p = SymmetricCsc { n: 5, col_ptr: vec![0], row_idx: vec![] };
        for c in cols {
            p.row_idx.extend_from_slice(c);
            p.col_ptr.push(p.row_idx.len());
        }
        let values = (0..p.nnz()).map(|k| 1.0 + k as f64 * 0.37).collect();
        (p, values)
    }

    #[test]
    fn full_csr_is_sorted_symmetric_and_multiplies_like_the_lower_triangle() {
        let (p, lower) = pattern();
        let csr = FullCsrPattern::from_lower_csc(&p);
        assert_eq!(csr.row_ptr.len(), 6);
        assert_eq!(csr.col_idx.len(), 2 * p.nnz() - 4, "4 stored diagonal entries");
        let mut values = vec![0.0; csr.col_idx.len()];
        csr.values_into(&lower, &mut values);
        let a = CsrView { n: 5, row_ptr: &csr.row_ptr, col_idx: &csr.col_idx, values: &values };
        let entry = |i: usize, j: usize| {
            let row = &a.col_idx[a.row_ptr[i]..a.row_ptr[i + 1]];
            row.binary_search(&j).ok().map(|k| a.values[a.row_ptr[i] + k])
        };
        for i in 0..5 {
            let row = &a.col_idx[a.row_ptr[i]..a.row_ptr[i + 1]];
            assert!(row.windows(2).all(|w| w[0] < w[1]), "row {i} not sorted: {row:?}");
            for &j in row {
                assert_eq!(entry(i, j), entry(j, i), "({i}, {j})");
            }
        }
        let x = [0.3, -1.0, 2.5, 0.7, -0.2];
        let (y, z) = (a.matvec(&x), p.sym_matvec(&lower, &x));
        for (u, v) in y.iter().zip(&z) {
            assert!((u - v).abs() < 1e-14, "{y:?} != {z:?}");
        }
    }
}
