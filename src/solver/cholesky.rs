//! Sparse Cholesky LLᵀ through faer: symbolic analysis once, numeric
//! factorisation per matrix.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltParams, LltRegularization};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side, Spec};

use super::SymmetricCsc;
use crate::{Error, Result};

/// A symbolic Cholesky analysis reusable for every matrix on one pattern.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    par: Par,
    /// The pattern's row indices widened to faer's index type.
    row_idx: Vec<usize>,
}

impl SparseCholesky {
    /// Analyse the pattern (AMD ordering, elimination tree, supernodes).
    pub fn try_analyse(pattern: &SymmetricCsc) -> Result<SparseCholesky> {
        let row_idx: Vec<usize> = pattern.row_idx.iter().map(|&r| r as usize).collect();
        let sym = SymbolicSparseColMatRef::new_checked(pattern.n, pattern.n, &pattern.col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(sym, Side::Lower, Default::default(), Default::default())
            .map_err(|e| Error::Solver(format!("symbolic Cholesky analysis failed: {e:?}")))?;
        // faer 0.24's threaded sparse Cholesky is slower than the sequential one on
        // our matrices (issue 5 measurements), so factor sequentially.
        Ok(SparseCholesky { symbolic, par: Par::Seq, row_idx })
    }

    /// Number of nonzeros of the factor L.
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Factor the matrix with these `values` on the analysed pattern and solve
    /// A x = b in place (`rhs` becomes x). Fails if A is not positive definite.
    pub fn try_factor_solve_in_place(&self, pattern: &SymmetricCsc, values: &[f64], rhs: &mut [f64]) -> Result<()> {
        let l_values = self.try_factor(pattern, values)?;
        self.try_solve_in_place(&l_values, rhs)
    }

    /// The numeric factor L (values on the analysed pattern of L) of the matrix
    /// with these `values`, for repeated solves with [`Self::try_solve_in_place`].
    /// Fails if A is not positive definite.
    pub fn try_factor(&self, pattern: &SymmetricCsc, values: &[f64]) -> Result<Vec<f64>> {
        let sym = SymbolicSparseColMatRef::new_checked(pattern.n, pattern.n, &pattern.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(sym, values);
        let mut l_values = Vec::new();
        l_values
            .try_reserve_exact(self.symbolic.len_val())
            .map_err(|_| Error::Solver("out of memory for the Cholesky factor".into()))?;
        l_values.resize(self.symbolic.len_val(), 0.0);
        let params: Spec<LltParams, f64> = Default::default();
        let mut mem = MemBuffer::try_new(self.symbolic.factorize_numeric_llt_scratch::<f64>(self.par, params))
            .map_err(|_| Error::Solver("out of memory for the Cholesky workspace".into()))?;
        self.symbolic
            .factorize_numeric_llt(
                &mut l_values,
                a,
                Side::Lower,
                LltRegularization::default(),
                self.par,
                MemStack::new(&mut mem),
                params,
            )
            .map_err(|e| Error::Solver(format!("the stiffness matrix is not positive definite ({e:?})")))?;
        Ok(l_values)
    }

    /// Solve L Lᵀ x = b in place with a factor from [`Self::try_factor`].
    pub fn try_solve_in_place(&self, l_values: &[f64], rhs: &mut [f64]) -> Result<()> {
        let llt = LltRef::new(&self.symbolic, l_values);
        let mut solve_mem = MemBuffer::try_new(self.symbolic.solve_in_place_scratch::<f64>(1, self.par))
            .map_err(|_| Error::Solver("out of memory for the solve workspace".into()))?;
        let n = rhs.len();
        let rhs_mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs_mat, self.par, MemStack::new(&mut solve_mem));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1D Laplacian (tridiagonal 2, −1) lower triangle.
    fn laplacian(n: usize) -> (SymmetricCsc, Vec<f64>) {
        let mut col_ptr = vec![0];
        let mut row_idx = vec![];
        let mut vals = vec![];
        for c in 0..n {
            row_idx.push(c);
            vals.push(2.0);
            if c + 1 < n {
                row_idx.push(c + 1);
                vals.push(-1.0);
            }
            col_ptr.push(row_idx.len());
        }
        (SymmetricCsc { n, col_ptr, row_idx: row_idx.into_iter().map(|r| r as u32).collect() }, vals)
    }

    #[test]
    fn cholesky_solves_the_laplacian_to_round_off() {
        let (a, v) = laplacian(50);
        let x_true: Vec<f64> = (0..50).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = a.sym_matvec(&v, &x_true);
        let chol = SparseCholesky::try_analyse(&a).unwrap();
        chol.try_factor_solve_in_place(&a, &v, &mut b).unwrap();
        for (x, t) in b.iter().zip(&x_true) {
            assert!((x - t).abs() < 1e-12);
        }
        // Same symbolic analysis, new values.
        let v2: Vec<f64> = v.iter().map(|x| 3.0 * x).collect();
        let mut b2 = a.sym_matvec(&v2, &x_true);
        chol.try_factor_solve_in_place(&a, &v2, &mut b2).unwrap();
        assert!((b2[7] - x_true[7]).abs() < 1e-12);
    }

    #[test]
    fn indefinite_matrix_is_reported() {
        let (a, mut v) = laplacian(5);
        v[0] = -2.0;
        let chol = SparseCholesky::try_analyse(&a).unwrap();
        let mut b = vec![1.0; 5];
        assert!(matches!(chol.try_factor_solve_in_place(&a, &v, &mut b), Err(Error::Solver(_))));
    }
}
