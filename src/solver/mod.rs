//! Linear solvers. This module sees only matrices and vectors.
//!
//! [`SymmetricCsc`] holds the lower triangle of a symmetric sparse matrix in
//! compressed-column form; [`SparseCholesky`] does the symbolic analysis (fill-
//! reducing AMD ordering and elimination tree) once and the numeric
//! factorisation for every new set of values on the same pattern.

mod cholesky;
mod lu;

pub use cholesky::SparseCholesky;
pub use lu::try_lu_solve_in_place;

/// Lower triangle (row ≥ column) of a symmetric `n`×`n` sparse matrix, CSC.
#[derive(Debug, Clone, Default)]
pub struct SymmetricCsc {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column.
    pub row_idx: Vec<usize>,
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
        self.row_idx[s..e].binary_search(&row).ok().map(|k| s + k)
    }

    /// y = A x for the symmetric matrix whose lower triangle is stored.
    pub fn sym_matvec(&self, values: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.n];
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[k];
                y[r] += values[k] * x[c];
                if r != c {
                    y[c] += values[k] * x[r];
                }
            }
        }
        y
    }
}
