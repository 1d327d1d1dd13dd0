//! Sparse Cholesky LLᵀ through faer: symbolic analysis once, numeric
//! factorisation per matrix.
//!
//! # Fill-reducing ordering
//!
//! Two orderings ([`DirectOrdering`]): faer's AMD, or nested dissection by
//! METIS (`METIS_NodeND`; METIS 5.2.1 vendored in `third_party/metis`,
//! compiled by `build.rs` with `hocurve_`-prefixed symbols so that hosts can
//! link their own METIS; see `super::metis`) on the *node* graph (the
//! pattern's `dim`-blocks: a node's free dofs are consecutive and every
//! coupling is a full block, see [`node_block_size`]), expanded back to dofs
//! with each node's dofs kept together. The node graph has dim² fewer edges
//! than the dof graph.
//!
//! Measured 2026-11-23 (`examples/ordering_table.rs`: K_ff of the straight
//! `hocurve bench` meshes, AMD and ND interleaved, min of 3 runs, one
//! factorisation; 2 shared cores, so ±15 %): nnz(L), symbolic analysis
//! (ordering + elimination tree + supernodes) and numeric factorisation +
//! solve, seconds.
//!
//! ```text
//! case                   n     nnz(A)  nnz(L) AMD   ND  ND/AMD   symb AMD   ND    fact+solve AMD    ND
//! 2D p=2 s=32        8,064     95,168     694,688     558,580 0.80   0.008  0.025   0.022  0.021
//! 2D p=2 s=128      39,424    466,688   3,895,428   3,223,832 0.83   0.064  0.133   0.120  0.134
//! 2D p=2 s=512     190,464  2,259,968  20,528,964  16,727,240 0.81   0.317  0.850   0.661  0.597
//! 2D p=3 s=48       29,088    502,128   2,950,416   2,422,980 0.82   0.036  0.065   0.090  0.057
//! 2D p=3 s=128      89,088  1,540,608  10,243,900   8,106,324 0.79   0.146  0.279   0.314  0.310
//! 2D p=4 s=32       32,512    770,432   3,260,944   2,923,816 0.90   0.059  0.061   0.083  0.098
//! 2D p=4 s=64       73,216  1,737,472   8,807,132   6,942,872 0.79   0.147  0.179   0.317  0.246
//! 2D p=4 s=128     158,720  3,769,856  19,501,820  15,895,444 0.82   0.406  0.411   0.782  0.633
//! 3D p=1 s=6         7,158    144,636   1,416,600   1,074,420 0.76   0.024  0.038   0.114  0.091
//! 3D p=1 s=10       34,254    732,852  17,212,941  10,403,496 0.60   0.253  0.299   2.973  1.406
//! 3D p=2 s=3         7,158    260,808   1,526,157   1,412,550 0.93   0.015  0.024   0.041  0.039
//! 3D p=2 s=4        17,322    664,644   5,946,975   4,592,772 0.77   0.058  0.075   0.252  0.173
//! 3D p=2 s=5        34,254  1,352,556  18,862,443  12,697,047 0.67   0.145  0.166   1.468  0.624
//! 3D p=3 s=3        24,834  1,600,224  15,053,175   9,726,570 0.65   0.120  0.102   0.838  0.376
//! 3D p=4 s=1         2,034    157,860     372,978     490,860 1.32   0.005  0.003   0.007  0.010
//! 3D p=4 s=2        17,322  1,674,732   5,918,166   6,288,354 1.06   0.100  0.058   0.197  0.241
//! 3D p=4 s=3        59,682  6,122,832  40,284,837  34,452,117 0.86   0.814  0.432   4.438  3.022
//! 3D p=5 s=2        34,254  4,979,628  16,105,428  18,158,976 1.13   0.314  0.184   0.730  0.828
//! ```
//!
//! Whole `hocurve bench-one ... --solver direct` runs (median of 3
//! interleaved; `--direct-ordering amd|nd` forces the ordering): 3D p = 4,
//! 59,682 unknowns, one increment: total 4.39 s → 3.24 s with ND, peak 565 →
//! 523 MB; 3D p = 4, 17,322: 0.59 s → 0.56 s (a tie), 119 → 123 MB; 2D p = 4,
//! 158,720, ten increments: 9.00 s → 7.36 s, 340 → 313 MB; 2D p = 2, 190,464,
//! ten increments: 9.00 s → 9.52 s (a tie within the noise), 310 → 289 MB,
//! one increment 1.20 s → 1.54 s (METIS takes 2.7× AMD's time there).
//! Re-measured with the renamed vendored METIS (medians, busier machine):
//! same nnz(L); 3D p = 3 s = 3 factor+solve 0.99 → 0.47 s, p = 4 s = 3
//! 3.46 → 2.37 s, whole run 4.84 → 3.86 s (bench/README.md).
//!
//! Re-measured on the statically condensed systems (the default since; whole
//! `bench-one --solver direct` runs, one increment, medians of 3, AMD → ND):
//! 3D p = 4, 59,682 dofs: 4.04 → 2.12 s (1.9×); 3D p = 3, 24,834: 0.92 → 0.56 s;
//! 3D p = 4, 17,322: 0.44 → 0.40 s; 3D p = 2, 17,322: 0.33 → 0.32 s; 2D p = 6,
//! 357,888: 1.93 → 1.72 s; 2D p = 4, 350,208: 1.72 → 1.80 s (METIS's 0.26 s
//! more set-up against 0.18 s less solve per increment: ND from the second
//! increment on); 2D p = 2, 190,464: 0.92 → 1.30 s. The rule below stands:
//! condensation removes the interior nodes that made AMD win on coarse
//! high-order 3D meshes, which only widens ND's lead there.
//!
//! So ND wins where the mesh is wide in "stencil widths" (n over the mean
//! column length, n² / nnz(A)): in 3D from about 300 (p = 2 at 17k unknowns,
//! p = 3 at 25k, p = 4 at 60k: 1.5–2.4× faster factorisations, a third less
//! fill), and loses on coarse high-order meshes (p = 4 at 17k, p = 5 at 34k:
//! 6–13 % more fill), whose many element-interior nodes AMD eliminates first.
//! In 2D ND always has 10–20 % less fill, but at p = 2 METIS costs more than
//! the factorisation saves; it wins at p = 4 from ~50k unknowns.
//! [`DirectOrdering::Auto`] (the default) follows this: ND in 3D when
//! n² / nnz(A) ≥ 300, in 2D from 50,000 unknowns with a mean column length
//! ≥ 20 (p ≥ 4), AMD otherwise.
//! In the default solver choice (direct in 3D up to 5,000 unknowns at p = 2
//! and 3, 15,000 at p = 4, 25,000 from p = 5) that means AMD for the 3D
//! systems solved directly, ND for large 2D p ≥ 4 meshes and the p-multigrid's order-1 coarsest level from ~7k unknowns (rows
//! p=1 above: 2.1× faster at 34k; its effect inside a PCG run was not
//! measured); with `--solver direct` on large 3D meshes, ND unless the mesh
//! is coarse for its order (p = 5 at 34k stays with AMD).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltParams, LltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side, Spec};

use super::SymmetricCsc;
use crate::{Error, Result, SolverFailure};

/// A symbolic Cholesky analysis reusable for every matrix on one pattern.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    par: Par,
    /// The pattern's row indices widened to faer's index type.
    row_idx: Vec<usize>,
    ordering: DirectOrdering,
}

impl SparseCholesky {
    /// Analyse the pattern (fill-reducing ordering chosen by
    /// [`DirectOrdering::Auto`], elimination tree, supernodes).
    pub fn try_analyse(pattern: &SymmetricCsc) -> Result<SparseCholesky> {
        Self::try_analyse_with(pattern, DirectOrdering::Auto)
    }

    /// Analyse the pattern with this fill-reducing ordering.
    pub fn try_analyse_with(pattern: &SymmetricCsc, ordering: DirectOrdering) -> Result<SparseCholesky> {
        let row_idx: Vec<usize> = pattern.row_idx.iter().map(|&r| r as usize).collect();
        let sym = SymbolicSparseColMatRef::new_checked(pattern.n, pattern.n, &pattern.col_ptr, None, &row_idx);
        let ordering = ordering.resolve(pattern);
        let nd = match ordering {
            DirectOrdering::NestedDissection => Some(nested_dissection(pattern)?),
            _ => None,
        };
        let ord = match &nd {
            Some((fwd, inv)) => SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, pattern.n)),
            None => SymmetricOrdering::Amd,
        };
        let symbolic = factorize_symbolic_cholesky(sym, Side::Lower, ord, Default::default())
            .map_err(|e| Error::solver(SolverFailure::Setup, format!("symbolic Cholesky analysis failed: {e:?}")))?;
        drop(nd);
        // faer 0.24's threaded sparse Cholesky is slower than the sequential one on
        // our matrices, so factor sequentially.
        Ok(SparseCholesky { symbolic, par: Par::Seq, row_idx, ordering })
    }

    /// The ordering the analysis used (never `Auto`).
    pub fn ordering(&self) -> DirectOrdering {
        self.ordering
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
            .map_err(|_| Error::solver(SolverFailure::OutOfMemory, "out of memory for the Cholesky factor"))?;
        l_values.resize(self.symbolic.len_val(), 0.0);
        let params: Spec<LltParams, f64> = Default::default();
        let mut mem = MemBuffer::try_new(self.symbolic.factorize_numeric_llt_scratch::<f64>(self.par, params))
            .map_err(|_| Error::solver(SolverFailure::OutOfMemory, "out of memory for the Cholesky workspace"))?;
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
            .map_err(|e| {
                Error::solver(
                    SolverFailure::NotPositiveDefinite,
                    format!("the stiffness matrix is not positive definite ({e:?})"),
                )
            })?;
        Ok(l_values)
    }

    /// Solve L Lᵀ x = b in place with a factor from [`Self::try_factor`].
    pub fn try_solve_in_place(&self, l_values: &[f64], rhs: &mut [f64]) -> Result<()> {
        let llt = LltRef::new(&self.symbolic, l_values);
        let mut solve_mem = MemBuffer::try_new(self.symbolic.solve_in_place_scratch::<f64>(1, self.par))
            .map_err(|_| Error::solver(SolverFailure::OutOfMemory, "out of memory for the solve workspace"))?;
        let n = rhs.len();
        let rhs_mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs_mat, self.par, MemStack::new(&mut solve_mem));
        Ok(())
    }
}

/// [`DirectOrdering::Auto`] in 3D: nested dissection when n² / nnz(A) (n
/// over the mean column length of the stored lower triangle) reaches this.
const ND_MIN_WIDTHS_3D: f64 = 300.0;
/// [`DirectOrdering::Auto`] in 2D: nested dissection from this many unknowns...
const ND_MIN_DOFS_2D: usize = 50_000;
/// ... and this mean column length of the stored lower triangle (p = 2: 12,
/// p = 3: 17, p = 4: 24).
const ND_MIN_DENSITY_2D: f64 = 20.0;

/// Fill-reducing ordering of the symbolic analysis.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum DirectOrdering {
    /// Approximate minimum degree (faer's own).
    Amd,
    /// Nested dissection (METIS_NodeND) of the node graph, each node's dofs
    /// kept together.
    NestedDissection,
    /// The measured choice (see the module doc).
    #[default]
    Auto,
}

impl DirectOrdering {
    pub fn name(self) -> &'static str {
        match self {
            DirectOrdering::Amd => "amd",
            DirectOrdering::NestedDissection => "nd",
            DirectOrdering::Auto => "auto",
        }
    }

    /// `Auto` replaced by the ordering it stands for on this pattern.
    pub fn resolve(self, pattern: &SymmetricCsc) -> DirectOrdering {
        match self {
            DirectOrdering::Auto => {
                let (n, nnz) = (pattern.n as f64, pattern.nnz().max(1) as f64);
                let nd = match node_block_size(pattern) {
                    // n / (entries per column) = n² / nnz: the mesh's extent in
                    // "stencil widths"; ND wins from ~300 (module doc).
                    3 => n * n / nnz >= ND_MIN_WIDTHS_3D,
                    2 => pattern.n >= ND_MIN_DOFS_2D && nnz / n >= ND_MIN_DENSITY_2D,
                    _ => false,
                };
                if nd {
                    DirectOrdering::NestedDissection
                } else {
                    DirectOrdering::Amd
                }
            }
            o => o,
        }
    }

    pub fn parse(s: &str) -> Result<DirectOrdering> {
        match s.to_ascii_lowercase().as_str() {
            "amd" => Ok(DirectOrdering::Amd),
            "nd" | "metis" | "nested-dissection" => Ok(DirectOrdering::NestedDissection),
            "auto" => Ok(DirectOrdering::Auto),
            _ => Err(Error::InvalidInput(format!("unknown direct ordering '{s}' (expected amd, nd or auto)"))),
        }
    }
}

/// The size of the node blocks of `pattern`: the largest b in {3, 2} such that
/// the dofs come in groups of b consecutive indices with identical couplings
/// (the layout of `DofMap::pattern`: a node's `dim` free dofs are consecutive
/// and every coupling of two nodes is a full dim × dim block); 1 otherwise.
pub fn node_block_size(pattern: &SymmetricCsc) -> usize {
    [3usize, 2].into_iter().find(|&b| is_blocked(pattern, b)).unwrap_or(1)
}

fn is_blocked(p: &SymmetricCsc, b: usize) -> bool {
    if p.n == 0 || !p.n.is_multiple_of(b) || p.col_ptr.len() != p.n + 1 {
        return false;
    }
    for k in 0..p.n / b {
        let c0 = b * k;
        let first = &p.row_idx[p.col_ptr[c0]..p.col_ptr[c0 + 1]];
        // Diagonal block: rows c0..c0+b.
        if first.len() < b || first[..b].iter().enumerate().any(|(i, &r)| r as usize != c0 + i) {
            return false;
        }
        let tail = &first[b..];
        // Off-diagonal rows in aligned, complete groups of b.
        if !tail.len().is_multiple_of(b) {
            return false;
        }
        for g in tail.chunks_exact(b) {
            let r0 = g[0] as usize;
            if !r0.is_multiple_of(b) || g.iter().enumerate().any(|(i, &r)| r as usize != r0 + i) {
                return false;
            }
        }
        // The other columns of the node: the rest of the diagonal block, same tail.
        for j in 1..b {
            let col = &p.row_idx[p.col_ptr[c0 + j]..p.col_ptr[c0 + j + 1]];
            if col.len() != first.len() - j
                || col[..b - j].iter().enumerate().any(|(i, &r)| r as usize != c0 + j + i)
                || col[b - j..] != *tail
            {
                return false;
            }
        }
    }
    true
}

/// A nested-dissection ordering of `pattern` (METIS_NodeND on the graph of
/// its `b`-blocks, b = [`node_block_size`]), expanded so that each block's
/// dofs stay consecutive. Returns (forward, inverse): `forward[new] = old`.
pub fn nested_dissection(pattern: &SymmetricCsc) -> Result<(Vec<usize>, Vec<usize>)> {
    let b = node_block_size(pattern);
    let nn = pattern.n / b;
    if nn == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    if nn > i32::MAX as usize {
        return Err(Error::solver(SolverFailure::Setup, "graph too large for METIS (32-bit indices)"));
    }
    // Node graph, both triangles, no self loops: node k's column is dof b·k;
    // its off-diagonal rows come in groups of b (one per neighbour node).
    let neighbours = |k: usize| {
        let c0 = b * k;
        pattern.row_idx[pattern.col_ptr[c0]..pattern.col_ptr[c0 + 1]]
            .iter()
            .map(move |&r| r as usize)
            .filter(move |&r| r.is_multiple_of(b) && r / b != k)
            .map(move |r| r / b)
    };
    let mut xadj = vec![0i32; nn + 1];
    for k in 0..nn {
        for m in neighbours(k) {
            xadj[k + 1] += 1;
            xadj[m + 1] += 1;
        }
    }
    let n_adj: usize = xadj.iter().map(|&d| d as usize).sum();
    if n_adj > i32::MAX as usize {
        return Err(Error::solver(SolverFailure::Setup, "graph too large for METIS (32-bit indices)"));
    }
    for k in 0..nn {
        xadj[k + 1] += xadj[k];
    }
    let mut fill: Vec<i32> = xadj[..nn].to_vec();
    let mut adjncy = vec![0i32; n_adj];
    for k in 0..nn {
        for m in neighbours(k) {
            adjncy[fill[k] as usize] = m as i32;
            fill[k] += 1;
            adjncy[fill[m] as usize] = k as i32;
            fill[m] += 1;
        }
    }
    drop(fill);
    let perm = super::metis::try_node_nd(&mut xadj, &mut adjncy)?;
    drop((xadj, adjncy));
    // METIS: perm[new] = old node. Expand to dofs.
    let mut fwd = vec![0usize; pattern.n];
    let mut inv = vec![0usize; pattern.n];
    for (new, &old) in perm.iter().enumerate() {
        let old = old as usize;
        for j in 0..b {
            fwd[b * new + j] = b * old + j;
            inv[b * old + j] = b * new + j;
        }
    }
    Ok((fwd, inv))
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
        assert!(matches!(
            chol.try_factor_solve_in_place(&a, &v, &mut b),
            Err(Error::Solver { kind: SolverFailure::NotPositiveDefinite, .. })
        ));
    }
}
