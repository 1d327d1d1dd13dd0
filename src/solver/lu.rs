//! Sparse LU (faer) for matrices that stopped being positive definite: the
//! fallback of the Newton–Raphson and CIL tangents.

use faer::linalg::solvers::SolveCore;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, MatMut};

use super::SymmetricCsc;
use crate::{Error, Result, SolverFailure};

/// Solve A x = b in place for the symmetric matrix whose lower triangle is
/// (`pattern`, `values`), by a full sparse LU with partial pivoting.
pub fn try_lu_solve_in_place(pattern: &SymmetricCsc, values: &[f64], rhs: &mut [f64]) -> Result<()> {
    let mut triplets = Vec::with_capacity(2 * values.len());
    for c in 0..pattern.n {
        for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
            let r = pattern.row_idx[k] as usize;
            triplets.push(Triplet::new(r, c, values[k]));
            if r != c {
                triplets.push(Triplet::new(c, r, values[k]));
            }
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(pattern.n, pattern.n, &triplets)
        .map_err(|e| Error::solver(SolverFailure::Setup, format!("cannot build the matrix for LU: {e:?}")))?;
    let symbolic = SymbolicLu::try_new(a.symbolic())
        .map_err(|e| Error::solver(SolverFailure::Setup, format!("symbolic LU failed: {e:?}")))?;
    let lu = Lu::try_new_with_symbolic(symbolic, a.as_ref())
        .map_err(|e| Error::solver(SolverFailure::Singular, format!("the matrix is singular ({e:?})")))?;
    let n = rhs.len();
    lu.solve_in_place_with_conj(Conj::No, MatMut::from_column_major_slice_mut(rhs, n, 1));
    if rhs.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::solver(SolverFailure::Singular, "the LU solution is not finite (singular matrix)"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lu_solves_a_symmetric_indefinite_system() {
        // [[2, 1, 0], [1, -3, 1], [0, 1, 1]] (indefinite), lower triangle.
        let a = SymmetricCsc { n: 3, col_ptr: vec![0, 2, 4, 5], row_idx: vec![0, 1, 1, 2, 2] };
        let v = vec![2.0, 1.0, -3.0, 1.0, 1.0];
        let x = [1.0, -2.0, 0.5];
        let mut b = a.sym_matvec(&v, &x);
        try_lu_solve_in_place(&a, &v, &mut b).unwrap();
        for (u, w) in b.iter().zip(&x) {
            assert!((u - w).abs() < 1e-13);
        }
    }
}
