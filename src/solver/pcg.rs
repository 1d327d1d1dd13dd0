//! Preconditioned conjugate gradients on a symmetric sparse matrix, and the
//! parallel symmetric matrix-vector product it runs on.
//!
//! [`SymmetricOperator`] is built once per pattern from the lower triangle
//! ([`SymmetricCsc`]): row r of the full matrix is column r of the lower
//! triangle plus the strictly lower part of row r, the transpose of entries
//! stored in earlier columns, read in place from the caller's values. With
//! nodes of b unknowns in consecutive rows (the layout of the assembled
//! systems), one (column, offset) pair of `u32` per b × b block locates
//! them: 8 bytes per block of 9 entries in 3D, against 16 per entry for a
//! compressed-row copy of the transpose with its position map.
//!
//! Vector reductions run over fixed chunks and are summed in chunk order, so
//! results do not depend on the number of threads.

use rayon::prelude::*;

use super::lines::LineFactors;
use super::SymmetricCsc;
use crate::{Error, Result, SolverFailure};

/// Rows per parallel task of the vector updates, the dot products, and the
/// products and solves with the diagonal blocks.
const CHUNK: usize = 2048;

/// Rows per parallel task of the product with the stored lower triangle.
/// In nodal-block layout each task sums into its own buffer, from its first
/// row to the last its columns reach ([`super::bsr::add_parts`]); entry by
/// entry, the blocks left of the diagonal whose column lies in an earlier
/// chunk are read through the symbolic transpose (the larger the chunk, the
/// fewer).
const PRODUCT_CHUNK: usize = 12288;

/// The transpose structure of a lower-triangle pattern, for the rows of the
/// full symmetric matrix: y = A x in parallel, and row-wise set-up.
///
/// Row r = (I, ii) of node I is, in ascending columns: the strictly lower
/// blocks (I, J < I), each the transpose of block (J, I), stored in columns
/// J·b..J·b + b; the strictly lower part of the diagonal block; and column r
/// of the triangle. Only the positions of the first are kept here, one
/// (J, offset) pair per block.
#[derive(Debug, Clone)]
pub struct SymmetricOperator {
    n: usize,
    nnz: usize,
    /// Unknowns per node: the block size asked for when the pattern is in
    /// nodal-block layout ([`super::bsr::nodal_blocks`]), else 1.
    b: usize,
    /// Per node I, its strictly lower blocks, J ascending (compressed rows).
    lower_ptr: Vec<usize>,
    /// J of each block.
    lower_col: Vec<u32>,
    /// Position of row I·b in column J·b, from the column's start: entry
    /// (I·b + ii, J·b + jj) is at col_ptr[J·b + jj] + offset − jj + ii.
    lower_off: Vec<u32>,
    /// Per chunk of [`PRODUCT_CHUNK`] rows in nodal-block layout, one past
    /// the last node row its columns reach ([`super::bsr::chunk_reach`]).
    reach: Vec<usize>,
    /// x padded for the products by blocks.
    padded: super::bsr::Padded,
}

impl SymmetricOperator {
    /// The symbolic transpose of `pattern` (once per pattern), by nodes of
    /// `block` unknowns when the pattern is in that layout.
    pub fn try_new(pattern: &SymmetricCsc, block: usize) -> Result<SymmetricOperator> {
        let nodal = if block > 1 { super::bsr::nodal_blocks(pattern, block).ok() } else { None };
        SymmetricOperator::from_nodal_blocks(pattern, block, nodal)
    }

    /// [`SymmetricOperator::try_new`] with the pattern's nodal-block layout
    /// already read ([`super::bsr::nodal_blocks`] of `pattern` and `block`),
    /// or None to take the pattern entry by entry.
    pub fn from_nodal_blocks(
        pattern: &SymmetricCsc,
        block: usize,
        nodal: Option<Vec<Vec<u32>>>,
    ) -> Result<SymmetricOperator> {
        let n = pattern.n;
        if n >= u32::MAX as usize || pattern.nnz() >= u32::MAX as usize {
            return Err(Error::solver(
                SolverFailure::Setup,
                format!("matrix too large for 32-bit indices ({n} rows, {} entries)", pattern.nnz()),
            ));
        }
        let (b, columns) = match nodal {
            Some(upper) => (block, upper),
            None => (1, (0..n).map(|c| pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]].to_vec()).collect()),
        };
        let mut lower_ptr = vec![0usize; columns.len() + 1];
        for (j, nodes) in columns.iter().enumerate() {
            for &i in nodes.iter().filter(|&&i| i as usize > j) {
                lower_ptr[i as usize + 1] += 1;
            }
        }
        for i in 0..columns.len() {
            lower_ptr[i + 1] += lower_ptr[i];
        }
        let m = lower_ptr[columns.len()];
        let mut fill = lower_ptr.clone();
        let (mut lower_col, mut lower_off) = (vec![0u32; m], vec![0u32; m]);
        for (j, nodes) in columns.iter().enumerate() {
            for (t, &i) in nodes.iter().enumerate().filter(|&(_, &i)| i as usize > j) {
                let k = &mut fill[i as usize];
                lower_col[*k] = j as u32;
                lower_off[*k] = (t * b) as u32;
                *k += 1;
            }
        }
        let reach = if b > 1 { super::bsr::chunk_reach(&columns, PRODUCT_CHUNK / b) } else { Vec::new() };
        Ok(SymmetricOperator {
            n,
            nnz: pattern.nnz(),
            b,
            lower_ptr,
            lower_col,
            lower_off,
            reach,
            padded: Default::default(),
        })
    }

    /// The matrix of this pattern with lower-triangle `values`.
    pub fn with<'a>(&'a self, pattern: &'a SymmetricCsc, values: &'a [f64]) -> WithValues<'a> {
        assert!(pattern.n == self.n && pattern.nnz() == self.nnz && values.len() == self.nnz, "pattern mismatch");
        WithValues { op: self, pattern, values }
    }
}

/// A symmetric matrix: a [`SymmetricOperator`] with its pattern and
/// lower-triangle values.
#[derive(Clone, Copy)]
pub struct WithValues<'a> {
    op: &'a SymmetricOperator,
    pattern: &'a SymmetricCsc,
    values: &'a [f64],
}

impl<'a> WithValues<'a> {
    pub fn n(&self) -> usize {
        self.op.n
    }

    pub fn pattern(&self) -> &'a SymmetricCsc {
        self.pattern
    }

    /// The lower-triangle values.
    pub fn values(&self) -> &'a [f64] {
        self.values
    }

    /// Entries (column, value) of row `r`, in ascending columns.
    #[inline]
    pub fn row(&self, r: usize) -> impl Iterator<Item = (usize, f64)> + 'a {
        let (op, pattern, values) = (self.op, self.pattern, self.values);
        let (b, cp) = (op.b, &pattern.col_ptr);
        let (node, ii) = (r / b, r % b);
        let blocks = (op.lower_ptr[node]..op.lower_ptr[node + 1]).flat_map(move |k| {
            let (j, off) = (op.lower_col[k] as usize, op.lower_off[k] as usize);
            (0..b).map(move |jj| (j * b + jj, values[cp[j * b + jj] + off - jj + ii]))
        });
        let diagonal = (0..ii).map(move |jj| (node * b + jj, values[cp[node * b + jj] + ii - jj]));
        let column = (cp[r]..cp[r + 1]).map(move |k| (pattern.row_idx[k] as usize, values[k]));
        blocks.chain(diagonal).chain(column)
    }

    /// Unknowns per node of its nodal-block layout (1: not in that layout).
    pub fn block(&self) -> usize {
        self.op.b
    }

    /// Each `B`×`B` block (S, A(R, S)) of node row `node`, S ascending
    /// (`B` = [`Self::block`]).
    #[inline]
    pub fn for_each_block<const B: usize>(&self, node: usize, mut f: impl FnMut(usize, &[[f64; B]; B])) {
        debug_assert_eq!(self.op.b, B);
        let (op, cp, ri, values) = (self.op, &self.pattern.col_ptr, &self.pattern.row_idx, self.values);
        let mut blk = [[0.0f64; B]; B];
        // Strictly lower: (node·B + ii, S·B + jj) in column S·B + jj.
        for k in op.lower_ptr[node]..op.lower_ptr[node + 1] {
            let (s, off) = (op.lower_col[k] as usize, op.lower_off[k] as usize);
            for (jj, &start) in cp[s * B..s * B + B].iter().enumerate() {
                for (ii, row) in blk.iter_mut().enumerate() {
                    row[jj] = values[start + off - jj + ii];
                }
            }
            f(s, &blk);
        }
        // Diagonal and upper: (S_m·B + c, node·B + r) in column node·B + r,
        // the m-th node of its list; the diagonal block's upper half from its lower.
        let first = cp[node * B];
        let nodes = (cp[node * B + 1] - first) / B;
        for m in 0..nodes {
            for (r, row) in blk.iter_mut().enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = if m == 0 && c < r {
                        values[cp[node * B + c] + r - c]
                    } else {
                        values[cp[node * B + r] + m * B + c - r]
                    };
                }
            }
            f(ri[first + m * B] as usize / B, &blk);
        }
    }

    /// y = A x; each row summed in the same order whatever the threads.
    pub fn matvec_into(&self, x: &[f64], y: &mut [f64]) {
        match self.op.b {
            1 => self.matvec_nodes::<1>(x, y),
            2 => self.matvec_lanes::<2, 2>(x, y),
            _ => self.matvec_lanes::<3, 4>(x, y),
        }
    }

    /// [`Self::matvec_nodes`] for a pattern in nodal-block layout, by
    /// blocks in vectors of `L` ≥ `B` lanes: the loops of
    /// [`Self::chunk_lanes`] on `x` padded to `L` entries per node, each
    /// chunk's sums then added up by rows ([`super::bsr::add_parts`]).
    fn matvec_lanes<const B: usize, const L: usize>(&self, x: &[f64], y: &mut [f64]) {
        let padded = self.op.padded.fill::<B, L>(x);
        let padded = &padded[..];
        let per = PRODUCT_CHUNK / B;
        super::bsr::product_by_chunks::<B, L>(&self.op.reach, per, y, |first, part| {
            #[cfg(target_arch = "x86_64")]
            if B == 3 && L == 4 && std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor supports AVX2 (checked just above).
                return unsafe { avx2::chunk_3(self, first, per, padded, part) };
            }
            self.chunk_lanes::<B, L>(first, per, padded, part)
        });
    }

    /// The sums of the columns of the chunk of `per` node rows from `first`
    /// on (fewer at the end), for a pattern in nodal-block layout and `x`
    /// padded to `L` entries per node (zeros past `B`), into `part`: `L`
    /// lanes per node row from `first` to the chunk's reach.
    ///
    /// Column jj of a block (I, J), I > J, is `B` consecutive values of
    /// column J·B + jj, read as the `L` from its start (reaching into the
    /// column's next block or the next column, which exists since a later
    /// node's columns follow). To row J it adds, lane by lane, t_jj +=
    /// col_jj ⊙ x_I, summed over lanes 0..B once per node; to row I
    /// Σ_jj x_J[jj] col_jj, whose lanes past `B` are dropped. Each stored
    /// value is read once, in order. The diagonal block goes entry by entry.
    pub(super) fn chunk_lanes<const B: usize, const L: usize>(
        &self,
        first: usize,
        per: usize,
        x: &[f64],
        part: &mut [f64],
    ) {
        let (cp, ri, values) = (&self.pattern.col_ptr, &self.pattern.row_idx, self.values);
        let end = (first + per).min(self.op.n / B);
        let xv = |i: usize| -> [f64; L] { x[i * L..][..L].try_into().expect("L lanes") };
        let col = |at: usize| -> [f64; L] { values[at..][..L].try_into().expect("L lanes") };
        for j in first..end {
            let xj = xv(j);
            let yj = &mut part[(j - first) * L..][..L];
            // The diagonal block: (J·B + ii, J·B + jj), ii ≥ jj, at cp[J·B + jj] + ii − jj.
            for jj in 0..B {
                for ii in jj..B {
                    let v = values[cp[j * B + jj] + ii - jj];
                    yj[ii] += v * xj[jj];
                    if ii != jj {
                        yj[jj] += v * xj[ii];
                    }
                }
            }
            let mut t = [[0.0f64; L]; B];
            let nodes = (cp[j * B + 1] - cp[j * B]) / B;
            for m in 1..nodes {
                let i = ri[cp[j * B] + m * B] as usize / B;
                let a: [[f64; L]; B] = std::array::from_fn(|jj| col(cp[j * B + jj] + m * B - jj));
                let xi = xv(i);
                for jj in 0..B {
                    for l in 0..L {
                        t[jj][l] += a[jj][l] * xi[l];
                    }
                }
                let yi = &mut part[(i - first) * L..][..L];
                for jj in 0..B {
                    for l in 0..L {
                        yi[l] += a[jj][l] * xj[jj];
                    }
                }
            }
            let yj = &mut part[(j - first) * L..][..L];
            for jj in 0..B {
                yj[jj] += super::bsr::sum_lanes(&t[jj], B);
            }
        }
    }

    /// Node rows in fixed chunks of [`PRODUCT_CHUNK`] (whatever the
    /// threads). Each stored value is read once: a chunk reads its own
    /// columns in order, each entry added to its column's row (the upper
    /// triangle) and, when its row is in the chunk, to that row too; the
    /// blocks left of the diagonal whose column lies in an earlier chunk
    /// are gathered through the symbolic transpose first.
    fn matvec_nodes<const B: usize>(&self, x: &[f64], y: &mut [f64]) {
        let (op, cp, ri, values) = (self.op, &self.pattern.col_ptr, &self.pattern.row_idx, self.values);
        let per = PRODUCT_CHUNK / B;
        y.par_chunks_mut(per * B).enumerate().for_each(|(t, yc)| {
            let (first, end) = (t * per, t * per + yc.len() / B);
            let (lo, hi) = (first * B, end * B);
            for (di, yn) in yc.chunks_exact_mut(B).enumerate() {
                let node = first + di;
                let mut acc = [0.0f64; B];
                for k in op.lower_ptr[node]..op.lower_ptr[node + 1] {
                    let (j, off) = (op.lower_col[k] as usize, op.lower_off[k] as usize);
                    if j >= first {
                        break;
                    }
                    for jj in 0..B {
                        let c = j * B + jj;
                        let (at, xc) = (cp[c] + off - jj, x[c]);
                        for (ii, a) in acc.iter_mut().enumerate() {
                            *a += values[at + ii] * xc;
                        }
                    }
                }
                yn.copy_from_slice(&acc);
            }
            for c in lo..hi {
                let (start, stop) = (cp[c], cp[c + 1]);
                // The rows of column c in this chunk come first (sorted).
                let inside = start + ri[start..stop].partition_point(|&r| (r as usize) < hi);
                let xc = x[c];
                // The diagonal entry, first when stored, goes to row c once.
                let diagonal = start < stop && ri[start] as usize == c;
                let mut acc = if diagonal { values[start] * xc } else { 0.0 };
                for k in start + diagonal as usize..inside {
                    let (r, v) = (ri[k] as usize, values[k]);
                    acc += v * x[r];
                    yc[r - lo] += v * xc;
                }
                for k in inside..stop {
                    acc += values[k] * x[ri[k] as usize];
                }
                yc[c - lo] += acc;
            }
        });
    }
}

/// [`WithValues::chunk_lanes`] for blocks of 3 in lanes of 4, in AVX2 vectors.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::super::simd::{add_sums, block, load};
    use super::WithValues;

    /// Values ahead (6 KB) that each column's stream is prefetched: on a
    /// 516,186-unknown matrix the product took 63–80 ms against 84–93 ms
    /// without (three interleaved runs, medians of 31 products each).
    const PF: usize = 768;

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chunk_3(a: &WithValues, first: usize, per: usize, x: &[f64], part: &mut [f64]) {
        let (cp, ri, values) = (&a.pattern.col_ptr, &a.pattern.row_idx, a.values);
        let end = (first + per).min(a.op.n / 3);
        for j in first..end {
            let xb = [_mm256_set1_pd(x[j * 4]), _mm256_set1_pd(x[j * 4 + 1]), _mm256_set1_pd(x[j * 4 + 2])];
            {
                let yj = &mut part[(j - first) * 4..][..3];
                for jj in 0..3 {
                    for ii in jj..3 {
                        let v = values[cp[j * 3 + jj] + ii - jj];
                        yj[ii] += v * x[j * 4 + jj];
                        if ii != jj {
                            yj[jj] += v * x[j * 4 + ii];
                        }
                    }
                }
            }
            let mut t = [_mm256_setzero_pd(); 3];
            let nodes = (cp[j * 3 + 1] - cp[j * 3]) / 3;
            for m in 1..nodes {
                let i = ri[cp[j * 3] + m * 3] as usize / 3;
                // A prefetch past the end of the arrays is harmless (it never faults).
                for jj in 0..3 {
                    _mm_prefetch(values.as_ptr().wrapping_add(cp[j * 3 + jj] + m * 3 + PF) as *const i8, _MM_HINT_T0);
                }
                _mm_prefetch(ri.as_ptr().wrapping_add(cp[j * 3] + m * 3 + 2 * PF) as *const i8, _MM_HINT_T0);
                let c = [
                    load(&values[cp[j * 3] + m * 3..]),
                    load(&values[cp[j * 3 + 1] + m * 3 - 1..]),
                    load(&values[cp[j * 3 + 2] + m * 3 - 2..]),
                ];
                block(&mut t, &c, load(&x[i * 4..]), Some((&mut part[(i - first) * 4..], &xb)));
            }
            add_sums(&mut part[(j - first) * 4..], &t);
        }
    }
}

impl super::bsr::Operator for WithValues<'_> {
    fn n(&self) -> usize {
        self.op.n
    }
    fn apply_into(&self, x: &[f64], y: &mut [f64]) {
        self.matvec_into(x, y)
    }
}

/// xᵀy, summed per fixed chunk then in chunk order (thread-count independent).
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    let partial: Vec<f64> =
        x.par_chunks(CHUNK).zip(y.par_chunks(CHUNK)).map(|(a, b)| a.iter().zip(b).map(|(p, q)| p * q).sum()).collect();
    partial.iter().sum()
}

/// y ← a x + b y.
pub fn axpby_in_place(a: f64, x: &[f64], b: f64, y: &mut [f64]) {
    y.par_chunks_mut(CHUNK).zip(x.par_chunks(CHUNK)).for_each(|(yc, xc)| {
        for (yi, xi) in yc.iter_mut().zip(xc) {
            *yi = a * xi + b * *yi;
        }
    });
}

/// Stopping rule of [`try_pcg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgParams {
    /// Converged when ‖b − A x‖₂ ≤ `rtol` ‖b‖₂.
    pub rtol: f64,
    pub max_iterations: usize,
}

impl Default for PcgParams {
    /// rtol = 1e-5. The error in the displacement is at most κ(A)·rtol relative
    /// to it in the worst case but, with a multigrid preconditioner, of the
    /// order of rtol times a small constant; the increments move nodes by a
    /// fraction of the mesh size h, so the nodes end within a few 1e-6·h of
    /// the exact solution's (tests/solvers.rs checks 2e-5·h against the direct
    /// solver) — far below anything visible in the quality or the geometry,
    /// and the boundary nodes, which carry the geometry, are prescribed exactly.
    /// 1e-8 took twice the iterations (27 against 13 at p = 4).
    fn default() -> Self {
        PcgParams { rtol: 1e-5, max_iterations: 1000 }
    }
}

/// z = M⁻¹ r, for [`try_pcg`].
pub type Preconditioner<'a> = dyn FnMut(&[f64], &mut [f64]) -> Result<()> + 'a;

/// Why [`pcg`] stopped without converging.
#[derive(Debug, Clone, PartialEq)]
pub enum PcgFailure {
    /// rᵀz ≤ 0 (or NaN): the preconditioner is not positive definite.
    PreconditionerNotPositive { iteration: usize, rz: f64 },
    /// pᵀAp ≤ 0 (or NaN): the matrix is not positive definite.
    MatrixNotPositive { iteration: usize, pap: f64 },
    /// The residual became infinite or NaN.
    NonFinite { iteration: usize },
    /// The smallest residual of the last `window` iterations is not below
    /// [`STAGNATION_FACTOR`] times the smallest one before them.
    Stagnated { iteration: usize, window: usize, relative_residual: f64 },
    /// `max_iterations` reached.
    NotConverged { iterations: usize, relative_residual: f64, rtol: f64 },
    /// The caller's check stopped the iteration ([`pcg`]'s `check`).
    Stopped { iteration: usize },
    /// The preconditioner returned an error.
    Preconditioner(Error),
}

impl std::fmt::Display for PcgFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PcgFailure::PreconditionerNotPositive { iteration, rz } => {
                write!(f, "PCG: the preconditioner is not positive definite (rᵀz = {rz:.3e} in iteration {iteration})")
            }
            PcgFailure::MatrixNotPositive { iteration, pap } => {
                write!(
                    f,
                    "PCG breakdown in iteration {iteration}: pᵀAp = {pap:.3e}, the matrix is not positive definite"
                )
            }
            PcgFailure::NonFinite { iteration } => {
                write!(f, "PCG: the residual is not finite in iteration {iteration}")
            }
            PcgFailure::Stagnated { iteration, window, relative_residual } => write!(
                f,
                "PCG stagnated: the residual did not fall by {:.0} % in the last {window} iterations \
                 (relative residual {relative_residual:.2e} after {iteration})",
                100.0 * (1.0 - STAGNATION_FACTOR)
            ),
            PcgFailure::NotConverged { iterations, relative_residual, rtol } => write!(
                f,
                "PCG did not converge in {iterations} iterations (relative residual {relative_residual:.2e}, \
                 tolerance {rtol:.1e})"
            ),
            PcgFailure::Stopped { iteration } => write!(f, "PCG stopped by its caller in iteration {iteration}"),
            PcgFailure::Preconditioner(e) => write!(f, "{e}"),
        }
    }
}

impl PcgFailure {
    /// The same failure in a PCG that had run `spent` iterations before this one's start.
    pub fn after(self, spent: usize) -> PcgFailure {
        match self {
            PcgFailure::PreconditionerNotPositive { iteration, rz } => {
                PcgFailure::PreconditionerNotPositive { iteration: iteration + spent, rz }
            }
            PcgFailure::MatrixNotPositive { iteration, pap } => {
                PcgFailure::MatrixNotPositive { iteration: iteration + spent, pap }
            }
            PcgFailure::NonFinite { iteration } => PcgFailure::NonFinite { iteration: iteration + spent },
            PcgFailure::Stagnated { iteration, window, relative_residual } => {
                PcgFailure::Stagnated { iteration: iteration + spent, window, relative_residual }
            }
            PcgFailure::NotConverged { iterations, relative_residual, rtol } => {
                PcgFailure::NotConverged { iterations: iterations + spent, relative_residual, rtol }
            }
            PcgFailure::Stopped { iteration } => PcgFailure::Stopped { iteration: iteration + spent },
            f @ PcgFailure::Preconditioner(_) => f,
        }
    }

    /// The kind of solver failure this is.
    fn kind(&self) -> SolverFailure {
        match self {
            PcgFailure::PreconditionerNotPositive { .. } | PcgFailure::MatrixNotPositive { .. } => {
                SolverFailure::NotPositiveDefinite
            }
            PcgFailure::NonFinite { .. } => SolverFailure::NonFinite,
            PcgFailure::Stagnated { .. } | PcgFailure::NotConverged { .. } | PcgFailure::Stopped { .. } => {
                SolverFailure::NotConverged
            }
            PcgFailure::Preconditioner(_) => SolverFailure::Setup,
        }
    }
}

impl From<PcgFailure> for Error {
    fn from(f: PcgFailure) -> Error {
        match f {
            PcgFailure::Preconditioner(e) => e,
            f => Error::solver(f.kind(), f.to_string()),
        }
    }
}

/// [`pcg`] declares stagnation when the smallest residual of the last
/// `stagnation_window` iterations is above this fraction of the smallest one
/// before them.
pub const STAGNATION_FACTOR: f64 = 0.9;

/// Solve A x = b by preconditioned conjugate gradients from the initial guess
/// in `x` (Saad, Iterative Methods, Alg. 9.1); returns the iterations.
///
/// `apply_a(x, y)` sets y = A x, `apply_m(r, z)` sets z = M⁻¹ r for a
/// symmetric positive definite M. Fails with [`Error::Solver`] when pᵀAp ≤ 0
/// (A is not positive definite: a CIL or Newton tangent can be indefinite),
/// when rᵀz ≤ 0 (the preconditioner is not), on a non-finite residual, or
/// without convergence in `max_iterations`.
#[cfg(any(test, feature = "internals"))]
pub fn try_pcg(
    apply_a: &mut dyn FnMut(&[f64], &mut [f64]),
    apply_m: &mut Preconditioner<'_>,
    b: &[f64],
    x: &mut [f64],
    params: PcgParams,
) -> Result<usize> {
    pcg(apply_a, apply_m, b, x, None, params, 0, &mut |_| true).map_err(Error::from)
}

/// [`try_pcg`] with the reason of a failure, and, unless `stagnation_window`
/// is 0, a stop on stagnation: once 2·`stagnation_window` iterations have run,
/// it stops when the smallest residual norm of the last `stagnation_window`
/// iterations is not below [`STAGNATION_FACTOR`] times the smallest one before
/// them. After every iteration that has not converged, `check(iteration)`
/// may stop it by returning false (it does not change the iterates
/// otherwise). On failure `x` holds the last iterate (not finite after
/// [`PcgFailure::NonFinite`]).
///
/// `residual` is b − A x for the start `x` when the caller has it already
/// (None: computed here), which saves a product with A.
#[allow(clippy::too_many_arguments)]
pub fn pcg(
    apply_a: &mut dyn FnMut(&[f64], &mut [f64]),
    apply_m: &mut Preconditioner<'_>,
    b: &[f64],
    x: &mut [f64],
    residual: Option<Vec<f64>>,
    params: PcgParams,
    stagnation_window: usize,
    check: &mut dyn FnMut(usize) -> bool,
) -> std::result::Result<usize, PcgFailure> {
    let n = b.len();
    let b_norm = dot(b, b).sqrt();
    if b_norm == 0.0 {
        x.fill(0.0);
        return Ok(0);
    }
    let target = params.rtol * b_norm;
    let mut r = residual.unwrap_or_else(|| {
        let mut r = vec![0.0; n];
        apply_a(x, &mut r);
        axpby_in_place(1.0, b, -1.0, &mut r);
        r
    });
    assert_eq!(r.len(), n, "the start's residual has the wrong length");
    let mut r_norm = dot(&r, &r).sqrt();
    if r_norm <= target {
        return Ok(0);
    }
    let mut z = vec![0.0; n];
    apply_m(&r, &mut z).map_err(PcgFailure::Preconditioner)?;
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut q = vec![0.0; n];
    // Smallest residual norm up to each iteration (index = iteration), for
    // the stagnation test.
    let mut best = if stagnation_window > 0 { vec![r_norm] } else { Vec::new() };
    for it in 1..=params.max_iterations {
        if rz.is_nan() || rz <= 0.0 {
            return Err(PcgFailure::PreconditionerNotPositive { iteration: it, rz });
        }
        apply_a(&p, &mut q);
        let pq = dot(&p, &q);
        if pq.is_nan() || pq <= 0.0 {
            return Err(PcgFailure::MatrixNotPositive { iteration: it, pap: pq });
        }
        let alpha = rz / pq;
        axpby_in_place(alpha, &p, 1.0, x);
        axpby_in_place(-alpha, &q, 1.0, &mut r);
        r_norm = dot(&r, &r).sqrt();
        if !r_norm.is_finite() {
            return Err(PcgFailure::NonFinite { iteration: it });
        }
        if r_norm <= target {
            return Ok(it);
        }
        if stagnation_window > 0 {
            let w = stagnation_window;
            best.push(r_norm.min(best[it - 1]));
            if it >= 2 * w && best[it] > STAGNATION_FACTOR * best[it - w] {
                return Err(PcgFailure::Stagnated { iteration: it, window: w, relative_residual: r_norm / b_norm });
            }
        }
        if !check(it) {
            return Err(PcgFailure::Stopped { iteration: it });
        }
        apply_m(&r, &mut z).map_err(PcgFailure::Preconditioner)?;
        let rz_new = dot(&r, &z);
        axpby_in_place(1.0, &z, rz_new / rz, &mut p);
        rz = rz_new;
    }
    Err(PcgFailure::NotConverged {
        iterations: params.max_iterations,
        relative_residual: r_norm / b_norm,
        rtol: params.rtol,
    })
}

/// Inverse diagonal blocks of size `block` (1: point Jacobi; the spatial
/// dimension: one block per node, whose free dofs are consecutive).
#[derive(Debug, Clone)]
pub struct BlockJacobi {
    block: usize,
    /// Row-major inverse of each block.
    inv: Vec<f64>,
    /// Blocks shifted by [`BLOCK_SHIFT`] because they were nearly singular.
    #[cfg_attr(not(test), allow(dead_code))] // read by the tests
    regularised: usize,
    /// Groups of nodes whose whole block is inverted instead (line smoothing).
    lines: Option<LineFactors>,
}

/// R, block-diagonal, with R Rᵀ = D⁻¹ ([`BlockJacobi::inverse_factor`]).
pub struct BlockFactor<'a> {
    block: usize,
    /// Row-major lower factor of each nodal block.
    r: Vec<f64>,
    /// The line blocks' factors, which replace the nodal ones on their rows.
    lines: Option<&'a LineFactors>,
}

impl BlockFactor<'_> {
    /// y = R x, or y = Rᵀ x with `transposed`.
    pub fn apply_into(&self, x: &[f64], y: &mut [f64], transposed: bool) {
        self.apply_nodal(x, y, transposed);
        if let Some(lines) = self.lines {
            lines.factor_into(x, y, transposed);
        }
    }

    fn apply_nodal(&self, x: &[f64], y: &mut [f64], transposed: bool) {
        let (b, bb) = (self.block, self.block * self.block);
        y.par_chunks_mut(CHUNK * b).zip(x.par_chunks(CHUNK * b)).enumerate().for_each(|(i, (yc, xc))| {
            let r = &self.r[i * CHUNK * bb..];
            for (k, (yb, xb)) in yc.chunks_exact_mut(b).zip(xc.chunks_exact(b)).enumerate() {
                let m = &r[k * bb..(k + 1) * bb];
                for (ii, yi) in yb.iter_mut().enumerate() {
                    *yi = (0..b).map(|j| if transposed { m[j * b + ii] } else { m[ii * b + j] } * xb[j]).sum();
                }
            }
        });
    }
}

/// A diagonal block whose Cholesky pivot falls below this fraction of its
/// diagonal entry is nearly singular (its inverse would be mostly round-off).
pub const NEAR_SINGULAR_PIVOT: f64 = 1e-10;
/// Such a block is inverted as B + δ I with δ = `BLOCK_SHIFT` · max diag(B).
/// B + δI ≥ B keeps D⁻¹A's eigenvalues positive and no larger than with D.
pub const BLOCK_SHIFT: f64 = 1e-8;

impl BlockJacobi {
    /// Invert the diagonal blocks of the matrix (`pattern`, `values`), in
    /// double precision; a nearly singular block (a pivot below
    /// [`NEAR_SINGULAR_PIVOT`] of its diagonal entry) is shifted by
    /// [`BLOCK_SHIFT`] first. Fails if a block is not positive definite.
    pub fn try_new(pattern: &SymmetricCsc, values: &[f64], block: usize) -> Result<BlockJacobi> {
        Self::try_new_with_lines(pattern, values, block, None)
    }

    /// [`Self::try_new`], with the line blocks `lines` (each group's whole
    /// block, factored from this matrix) inverted instead of their nodes'
    /// own blocks.
    pub fn try_new_with_lines(
        pattern: &SymmetricCsc,
        values: &[f64],
        block: usize,
        lines: Option<LineFactors>,
    ) -> Result<BlockJacobi> {
        let n = pattern.n;
        if !(1..=3).contains(&block) || !n.is_multiple_of(block) {
            return Err(Error::solver(
                SolverFailure::Setup,
                format!("block Jacobi: block size {block} does not divide {n}"),
            ));
        }
        let bb = block * block;
        let mut inv = vec![0.0; n * block];
        let regularised = inv
            .par_chunks_mut(bb)
            .enumerate()
            .map(|(i, out)| -> Result<usize> {
                let mut a = [0.0; 9];
                for jc in 0..block {
                    let c = i * block + jc;
                    for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                        let r = pattern.row_idx[k] as usize;
                        if r >= (i + 1) * block {
                            break;
                        }
                        let ir = r - i * block;
                        a[ir * block + jc] = values[k];
                        a[jc * block + ir] = values[k];
                    }
                }
                let not_spd = || {
                    Error::solver(
                        SolverFailure::NotPositiveDefinite,
                        format!("block Jacobi: diagonal block {i} is not positive definite"),
                    )
                };
                match invert_spd_block(&a[..bb], block, out) {
                    Some(min_ratio) if min_ratio >= NEAR_SINGULAR_PIVOT => Ok(0),
                    _ => {
                        let diag_max = (0..block).map(|j| a[j * block + j]).fold(f64::NEG_INFINITY, f64::max);
                        if !(0..block).all(|j| a[j * block + j] > 0.0) || !diag_max.is_finite() {
                            return Err(not_spd());
                        }
                        for j in 0..block {
                            a[j * block + j] += BLOCK_SHIFT * diag_max;
                        }
                        invert_spd_block(&a[..bb], block, out).ok_or_else(not_spd)?;
                        Ok(1)
                    }
                }
            })
            .try_reduce(|| 0, |x, y| Ok(x + y))?;
        Ok(BlockJacobi { block, inv, regularised, lines })
    }

    /// Blocks that were shifted because nearly singular.
    #[cfg(test)]
    pub fn regularised(&self) -> usize {
        self.regularised
    }

    /// z = D⁻¹ r.
    pub fn apply_into(&self, r: &[f64], z: &mut [f64]) {
        self.apply_nodal(r, z);
        if let Some(lines) = &self.lines {
            lines.solve_into(r, z);
        }
    }

    fn apply_nodal(&self, r: &[f64], z: &mut [f64]) {
        let b = self.block;
        let bb = b * b;
        z.par_chunks_mut(CHUNK * b).zip(r.par_chunks(CHUNK * b)).enumerate().for_each(|(i, (zc, rc))| {
            let inv = &self.inv[i * CHUNK * bb..];
            for (k, (zb, rb)) in zc.chunks_exact_mut(b).zip(rc.chunks_exact(b)).enumerate() {
                let m = &inv[k * bb..(k + 1) * bb];
                for (ii, zi) in zb.iter_mut().enumerate() {
                    *zi = (0..b).map(|j| m[ii * b + j] * rb[j]).sum();
                }
            }
        });
    }

    /// R with R Rᵀ = D⁻¹, block by block (the Cholesky factors of the
    /// inverted blocks): D⁻¹A is similar to the symmetric Rᵀ A R.
    pub fn inverse_factor(&self) -> BlockFactor<'_> {
        let (b, bb) = (self.block, self.block * self.block);
        let mut r = vec![0.0; self.inv.len()];
        r.par_chunks_mut(bb).zip(self.inv.par_chunks(bb)).for_each(|(out, inv)| {
            // The inverse of an SPD block is SPD; round-off cannot make a 3 × 3 one indefinite.
            let (l, _) = cholesky_block(inv, b).expect("the inverse of an SPD block is SPD");
            out.copy_from_slice(&l[..bb]);
        });
        BlockFactor { block: b, r, lines: self.lines.as_ref() }
    }

    /// ‖D⁻¹A‖_∞, the largest absolute row sum of D⁻¹A for the matrix `a`
    /// (D its blocks inverted here): an
    /// upper bound of every eigenvalue of D⁻¹A (Gershgorin), computed in
    /// double precision from the entries, so it cannot miss a mode the way a
    /// power iteration can. For nodal blocks only (D without lines).
    pub fn row_sum_bound(&self, a: WithValues) -> f64 {
        debug_assert!(self.lines.is_none(), "the row-sum bound is of nodal blocks");
        let b = self.block;
        let bb = b * b;
        let n = a.n();
        (0..n / b)
            .into_par_iter()
            .map_init(
                || (vec![[0.0f64; 3]; n], vec![false; n], Vec::<usize>::new()),
                |(acc, seen, list), i| {
                    for k in 0..b {
                        for (c, v) in a.row(i * b + k) {
                            if !seen[c] {
                                seen[c] = true;
                                list.push(c);
                            }
                            acc[c][k] += v;
                        }
                    }
                    let m = &self.inv[i * bb..(i + 1) * bb];
                    let mut sums = [0.0f64; 3];
                    for &c in list.iter() {
                        let w = acc[c];
                        for (ii, s) in sums.iter_mut().enumerate().take(b) {
                            *s += (0..b).map(|j| m[ii * b + j] * w[j]).sum::<f64>().abs();
                        }
                        acc[c] = [0.0; 3];
                        seen[c] = false;
                    }
                    list.clear();
                    sums.iter().take(b).fold(0.0f64, |x, &y| x.max(y))
                },
            )
            .reduce(|| 0.0, f64::max)
    }
}

/// Inverse of a symmetric block of size 1..=3 by Cholesky; `None` unless
/// positive definite, else the smallest ratio of a pivot (before its square
/// root) to its diagonal entry (1 for a diagonal block; near 0 when a column
/// is nearly a combination of the previous ones).
/// The lower Cholesky factor L (row-major) of the SPD block `a` (b × b),
/// and the smallest ratio of a pivot² to its diagonal entry; None if a pivot
/// is not positive.
fn cholesky_block(a: &[f64], b: usize) -> Option<([f64; 9], f64)> {
    let mut l = [0.0; 9];
    let mut min_ratio = f64::INFINITY;
    for j in 0..b {
        let mut d = a[j * b + j];
        for k in 0..j {
            d -= l[j * b + k] * l[j * b + k];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        min_ratio = min_ratio.min(d / a[j * b + j]);
        let d = d.sqrt();
        l[j * b + j] = d;
        for i in j + 1..b {
            let mut s = a[i * b + j];
            for k in 0..j {
                s -= l[i * b + k] * l[j * b + k];
            }
            l[i * b + j] = s / d;
        }
    }
    Some((l, min_ratio))
}

fn invert_spd_block(a: &[f64], b: usize, out: &mut [f64]) -> Option<f64> {
    // L Lᵀ = A, then A⁻¹ column by column.
    let (l, min_ratio) = cholesky_block(a, b)?;
    for c in 0..b {
        let mut y = [0.0; 3];
        for i in 0..b {
            let mut s = if i == c { 1.0 } else { 0.0 };
            for k in 0..i {
                s -= l[i * b + k] * y[k];
            }
            y[i] = s / l[i * b + i];
        }
        for i in (0..b).rev() {
            let mut s = y[i];
            for k in i + 1..b {
                s -= l[k * b + i] * y[k];
            }
            y[i] = s / l[i * b + i];
        }
        for i in 0..b {
            out[i * b + c] = y[i];
        }
    }
    Some(min_ratio)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Lower triangle of the 2D 5-point Laplacian on an m×m grid, with each
    /// unknown replicated into `block` coupled components (an SPD block matrix).
    pub(crate) fn grid_laplacian(m: usize, block: usize) -> (SymmetricCsc, Vec<f64>) {
        let n = m * m * block;
        let mut col_ptr = vec![0];
        let mut row_idx = vec![];
        let mut vals = vec![];
        for c in 0..n {
            let (node, comp) = (c / block, c % block);
            let (i, j) = (node % m, node / m);
            for d in comp..block {
                row_idx.push(node * block + d);
                vals.push(if d == comp { 4.0 + 0.5 } else { 0.3 });
            }
            let mut nb = vec![];
            if i + 1 < m {
                nb.push(node + 1);
            }
            if j + 1 < m {
                nb.push(node + m);
            }
            for q in nb {
                for d in 0..block {
                    row_idx.push(q * block + d);
                    vals.push(if d == comp { -1.0 } else { 0.0 });
                }
            }
            col_ptr.push(row_idx.len());
        }
        (SymmetricCsc { n, col_ptr, row_idx: row_idx.into_iter().map(|r| r as u32).collect() }, vals)
    }

    #[test]
    fn symmetric_operator_matches_the_serial_product() {
        let (a, v) = grid_laplacian(30, 3);
        // By nodes of 3 and, with block 1, by single unknowns.
        for block in [3, 1] {
            let op = SymmetricOperator::try_new(&a, block).unwrap();
            assert_eq!(op.b, block);
            let m = op.with(&a, &v);
            let x: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.77).cos()).collect();
            let mut y = vec![0.0; a.n];
            m.matvec_into(&x, &mut y);
            let y_ref = a.sym_matvec(&v, &x);
            for (p, q) in y.iter().zip(&y_ref) {
                assert!((p - q).abs() < 1e-12);
            }
            for r in [0, 1, 2, 100, 101, 102, a.n - 1] {
                let row: Vec<(usize, f64)> = m.row(r).collect();
                assert!(row.windows(2).all(|w| w[0].0 < w[1].0), "row {r}: columns not ascending");
                let dot: f64 = row.iter().map(|&(c, a)| a * x[c]).sum();
                assert!((dot - y_ref[r]).abs() < 1e-12, "row {r}");
            }
        }
    }

    /// Matrices of more than one chunk of the product: by nodal blocks, a
    /// chunk's columns add to later chunks' rows through its own buffer;
    /// entry by entry, the entries whose column lies in an earlier chunk are
    /// read through the symbolic transpose. The sums do not depend on the
    /// threads. With single unknowns, some columns lack their
    /// diagonal entry.
    #[test]
    fn the_product_by_chunks_matches_the_serial_product_for_any_thread_count() {
        let (a3, v3) = grid_laplacian(100, 3);
        let (mut a1, mut v1) = grid_laplacian(170, 1);
        // Drop the diagonal entry of every fifth column.
        let (mut col_ptr, mut row_idx, mut vals) = (vec![0], vec![], vec![]);
        for c in 0..a1.n {
            for k in a1.col_ptr[c]..a1.col_ptr[c + 1] {
                if !(c % 5 == 0 && a1.row_idx[k] as usize == c) {
                    row_idx.push(a1.row_idx[k]);
                    vals.push(v1[k]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        (a1, v1) = (SymmetricCsc { n: a1.n, col_ptr, row_idx }, vals);
        let (a2, v2) = grid_laplacian(120, 2);
        for (a, v, block) in [(&a3, &v3, 3), (&a2, &v2, 2), (&a1, &v1, 1)] {
            assert!(a.n > 2 * PRODUCT_CHUNK, "{} unknowns: fewer than three chunks", a.n);
            let op = SymmetricOperator::try_new(a, block).unwrap();
            let m = op.with(a, v);
            let x: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.77).cos()).collect();
            let y_ref = a.sym_matvec(v, &x);
            let product = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut y = vec![0.0; a.n];
                pool.install(|| m.matvec_into(&x, &mut y));
                y
            };
            let y = product(1);
            for (p, q) in y.iter().zip(&y_ref) {
                assert!((p - q).abs() < 1e-12, "{p} against {q}");
            }
            assert_eq!(y, product(3), "block {block}: the sums depend on the threads");
            if block > 1 {
                // The portable loops, bitwise as the AVX2 ones.
                let lanes = if block == 3 { 4 } else { block };
                let mut padded = vec![0.0; a.n / block * lanes];
                for (p, v) in padded.chunks_exact_mut(lanes).zip(x.chunks_exact(block)) {
                    p[..block].copy_from_slice(v);
                }
                let per = PRODUCT_CHUNK / block;
                let mut portable = vec![0.0; a.n];
                match block {
                    2 => crate::solver::bsr::product_by_chunks::<2, 2>(&op.reach, per, &mut portable, |f, p| {
                        m.chunk_lanes::<2, 2>(f, per, &padded, p)
                    }),
                    _ => crate::solver::bsr::product_by_chunks::<3, 4>(&op.reach, per, &mut portable, |f, p| {
                        m.chunk_lanes::<3, 4>(f, per, &padded, p)
                    }),
                }
                assert!(y.iter().zip(&portable).all(|(p, q)| p.to_bits() == q.to_bits()), "block {block}");
            }
        }
    }

    #[test]
    fn pcg_matches_the_direct_solver_on_an_spd_matrix() {
        let (a, v) = grid_laplacian(25, 2);
        let op = SymmetricOperator::try_new(&a, 2).unwrap();
        let m = op.with(&a, &v);
        let x_true: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.37).sin()).collect();
        let b = a.sym_matvec(&v, &x_true);
        let mut x_direct = b.clone();
        super::super::SparseCholesky::try_analyse(&a)
            .unwrap()
            .try_factor_solve_in_place(&a, &v, &mut x_direct)
            .unwrap();
        let jac = BlockJacobi::try_new(&a, &v, 2).unwrap();
        let mut x = vec![0.0; a.n];
        let params = PcgParams { rtol: 1e-12, max_iterations: 500 };
        let solve = |x: &mut [f64]| {
            let mut precondition = |r: &[f64], z: &mut [f64]| {
                jac.apply_into(r, z);
                Ok(())
            };
            try_pcg(&mut |x, y| m.matvec_into(x, y), &mut precondition, &b, x, params).unwrap()
        };
        let it = solve(&mut x);
        assert!(it > 5 && it < 500, "{it} iterations");
        for (p, q) in x.iter().zip(&x_direct) {
            assert!((p - q).abs() < 1e-9, "{p} vs {q}");
        }
        // Warm start from the solution: no iteration.
        assert_eq!(solve(&mut x), 0);
    }

    #[test]
    fn pcg_reports_an_indefinite_matrix() {
        let (a, mut v) = grid_laplacian(10, 1);
        for k in 0..a.n {
            v[a.col_ptr[k]] -= 6.0; // diagonal 4.5 → −1.5: indefinite
        }
        let op = SymmetricOperator::try_new(&a, 1).unwrap();
        let b = vec![1.0; a.n];
        let mut x = vec![0.0; a.n];
        let r = try_pcg(
            &mut |x, y| op.with(&a, &v).matvec_into(x, y),
            &mut |r, z| {
                z.copy_from_slice(r);
                Ok(())
            },
            &b,
            &mut x,
            PcgParams::default(),
        );
        assert!(matches!(r, Err(Error::Solver { .. })), "{r:?}");
        assert!(BlockJacobi::try_new(&a, &v, 1).is_err());
    }

    #[test]
    fn row_sum_bound_is_above_every_eigenvalue_of_the_jacobi_scaled_matrix() {
        use super::super::pmg::{Chebyshev, ChebyshevParams};
        for block in [1, 3] {
            let (a, v) = grid_laplacian(12, block);
            let op = SymmetricOperator::try_new(&a, block).unwrap();
            let m = op.with(&a, &v);
            let bound = BlockJacobi::try_new(&a, &v, block).unwrap().row_sum_bound(m);
            let params = ChebyshevParams { power_iterations: 60, ..Default::default() };
            let lambda = Chebyshev::try_new(m, block, params).unwrap().estimate();
            let safe = Chebyshev::try_new_safe(m, block, ChebyshevParams::default()).unwrap();
            println!("block {block}: lambda_max {lambda:.4}, bound {bound:.4}");
            assert!(bound >= lambda && bound < 3.0 * lambda, "block {block}: {bound} vs {lambda}");
            assert_eq!(safe.lambda_max(), bound);
        }
    }

    #[test]
    fn nearly_singular_blocks_are_shifted_and_indefinite_ones_refused() {
        // One 3×3 block: rows 0 and 1 equal to 1e-13.
        let a = SymmetricCsc { n: 3, col_ptr: vec![0, 3, 5, 6], row_idx: vec![0, 1, 2, 1, 2, 2] };
        let v = [1.0, 1.0, 0.0, 1.0 + 1e-13, 0.0, 2.0];
        let jac = BlockJacobi::try_new(&a, &v, 3).unwrap();
        assert_eq!(jac.regularised(), 1);
        let mut z = [0.0; 3];
        jac.apply_into(&[1.0, -1.0, 0.0], &mut z);
        // (B + δI)⁻¹ on the near null vector (1, −1, 0): about 1/δ, δ = 2e-8.
        assert!(z.iter().all(|x| x.is_finite()) && (z[0] * 2e-8 - 1.0).abs() < 1e-3, "{z:?}");
        let well = [4.0, 1.0, 0.0, 3.0, 0.0, 2.0];
        assert_eq!(BlockJacobi::try_new(&a, &well, 3).unwrap().regularised(), 0);
        let indefinite = [1.0, 2.0, 0.0, 1.0, 0.0, 2.0];
        assert!(BlockJacobi::try_new(&a, &indefinite, 3).is_err());
    }

    #[test]
    fn pcg_reports_stagnation_and_stops_when_asked() {
        // Diagonal, condition number 1e8, with a preconditioner that changes
        // at every call: conjugacy is lost and the residual crawls.
        let n = 200;
        let d: Vec<f64> = (0..n).map(|i| 10f64.powf(8.0 * i as f64 / (n - 1) as f64)).collect();
        let b = vec![1.0; n];
        let mut calls = 0usize;
        let mut apply_a =
            |x: &[f64], y: &mut [f64]| y.iter_mut().zip(x.iter().zip(&d)).for_each(|(y, (x, d))| *y = d * x);
        let mut varying = |r: &[f64], z: &mut [f64]| {
            calls += 1;
            for (i, (z, r)) in z.iter_mut().zip(r).enumerate() {
                *z = r * (1.5 + ((i * 7 + calls * 13) as f64).sin());
            }
            Ok(())
        };
        let params = PcgParams { rtol: 1e-10, max_iterations: 5000 };
        let mut x = vec![0.0; n];
        let r = pcg(&mut apply_a, &mut varying, &b, &mut x, None, params, 20, &mut |_| true);
        assert!(matches!(r, Err(PcgFailure::Stagnated { window: 20, .. })), "{r:?}");
        assert!(x.iter().all(|v| v.is_finite()));
        let mut x = vec![0.0; n];
        let mut identity = |r: &[f64], z: &mut [f64]| {
            z.copy_from_slice(r);
            Ok(())
        };
        let r = pcg(&mut apply_a, &mut identity, &b, &mut x, None, params, 0, &mut |it| it < 3);
        assert_eq!(r, Err(PcgFailure::Stopped { iteration: 3 }));
    }

    #[test]
    fn a_given_start_residual_saves_one_product_and_changes_no_iterate() {
        let (a, v) = grid_laplacian(9, 1);
        let b: Vec<f64> = (0..a.n).map(|i| 1.0 + (i as f64 * 0.7).sin()).collect();
        let start: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.3).cos()).collect();
        let params = PcgParams { rtol: 1e-8, max_iterations: 500 };
        let run = |residual: Option<Vec<f64>>| {
            let mut products = 0;
            let mut apply_a = |x: &[f64], y: &mut [f64]| {
                products += 1;
                y.copy_from_slice(&a.sym_matvec(&v, x));
            };
            let mut identity = |r: &[f64], z: &mut [f64]| {
                z.copy_from_slice(r);
                Ok(())
            };
            let mut x = start.clone();
            let it = pcg(&mut apply_a, &mut identity, &b, &mut x, residual, params, 0, &mut |_| true).unwrap();
            (it, products, x)
        };
        let (it, products, x) = run(None);
        let r: Vec<f64> = a.sym_matvec(&v, &start).iter().zip(&b).map(|(ax, b)| b - ax).collect();
        let (it_given, products_given, x_given) = run(Some(r));
        assert!(it > 1);
        assert_eq!((it_given, products_given), (it, products - 1));
        assert!(x.iter().zip(&x_given).all(|(p, q)| p.to_bits() == q.to_bits()));
        // The given residual is the one used: a wrong one leads elsewhere.
        let (_, _, x_wrong) = run(Some(b.clone()));
        assert!(x.iter().zip(&x_wrong).any(|(p, q)| (p - q).abs() > 1e-3));
    }

    #[test]
    fn block_inverse_is_the_inverse() {
        let a = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let mut inv = [0.0; 9];
        invert_spd_block(&a, 3, &mut inv).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let s: f64 = (0..3).map(|k| a[i * 3 + k] * inv[k * 3 + j]).sum();
                assert!((s - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
    }
}
