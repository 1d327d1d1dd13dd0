//! A single-precision copy of a symmetric matrix with nodal blocks, for the
//! products inside the preconditioner.
//!
//! The V-cycle makes six of the seven products with the fine matrix in each
//! PCG iteration ([`super::pmg`]), and those products are memory-bound. Stored
//! by full block rows of `b × b` blocks (BSR), one `u32` block-column index per
//! block and `f32` values, a product reads 4.4 bytes per entry, against
//! 12 or more for the double-precision lower triangle read in place by
//! [`super::pcg::SymmetricOperator`]. Both triangles are stored: reading the
//! lower blocks transposed from the upper ones saves 0.4 KB per unknown at
//! p = 4 in 3D but made the solve 1.55 times slower (scattered reads).
//! Single precision is enough for a preconditioner (its entries are relative
//! perturbations of 6e-8 of the matrix); PCG itself multiplies in double.
//!
//! Measured on the p = 4 sphere-in-box mesh of bench/compare_gmsh.sh (76,542
//! unknowns), in docs/performance.md.

use rayon::prelude::*;

use super::pcg::WithValues;
use super::SymmetricCsc;
use crate::{Error, Result, SolverFailure};

/// y = A x for some fixed symmetric matrix A.
pub trait Operator: Sync {
    fn n(&self) -> usize;
    fn apply_into(&self, x: &[f64], y: &mut [f64]);
}

/// Block rows per parallel task.
const CHUNK_ROWS: usize = 512;

/// A symmetric matrix stored by full block rows in single precision: per
/// block row, its strictly lower blocks and its upper blocks (diagonal
/// included), each part in compressed block rows.
#[derive(Debug, Clone)]
pub struct BlockSym32 {
    /// Block size.
    b: usize,
    n_blocks: usize,
    /// Upper blocks (J, I ≥ J) of row J, in the order of column J·b of the
    /// lower triangle (the diagonal block first).
    up: BlockRows,
    /// Strictly lower blocks (I, J < I) of row I, the transposes of upper
    /// ones (found at each fill through the double-precision operator's
    /// symbolic transpose: an index of its own would cost 44 bytes per
    /// unknown at p = 4 in 3D).
    lo: BlockRows,
}

#[derive(Debug, Clone, Default)]
struct BlockRows {
    ptr: Vec<usize>,
    col: Vec<u32>,
    /// `b²` values per block, row-major.
    val: Vec<f32>,
}

impl BlockRows {
    fn from_lists(lists: &[Vec<u32>], bb: usize) -> BlockRows {
        let mut ptr = Vec::with_capacity(lists.len() + 1);
        ptr.push(0);
        let mut col = Vec::with_capacity(lists.iter().map(Vec::len).sum());
        for l in lists {
            col.extend_from_slice(l);
            ptr.push(col.len());
        }
        BlockRows { val: vec![0.0; col.len() * bb], ptr, col }
    }

    #[inline(always)]
    fn add_row<const B: usize>(&self, i: usize, x: &[f64], acc: &mut [f64; B]) {
        for k in self.ptr[i]..self.ptr[i + 1] {
            let j = self.col[k] as usize;
            let blk = &self.val[k * B * B..(k + 1) * B * B];
            let xj = &x[j * B..(j + 1) * B];
            for r in 0..B {
                for c in 0..B {
                    acc[r] += blk[r * B + c] as f64 * xj[c];
                }
            }
        }
    }
}

/// The node lists of the block columns of `pattern`, a lower triangle whose
/// unknowns come in consecutive groups of `b` (one group per node) and whose
/// column (J, j) lists, in order, rows (J, j..b) and then the `b` rows of
/// every later coupled node (the layout of `assembly::DofMap::pattern`): per
/// node J, the nodes I ≥ J coupled to it, ascending, J first. An error if
/// the pattern is not in that layout.
pub fn nodal_blocks(pattern: &SymmetricCsc, b: usize) -> Result<Vec<Vec<u32>>> {
    let n = pattern.n;
    if !(1..=3).contains(&b) || !n.is_multiple_of(b) {
        return Err(Error::solver(SolverFailure::Setup, format!("block matrix: block size {b} does not divide {n}")));
    }
    let upper: Vec<Vec<u32>> = (0..n / b)
        .into_par_iter()
        .map(|j| {
            let c = j * b;
            let rows = &pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]];
            rows.iter().step_by(b).map(|&r| r / b as u32).collect()
        })
        .collect();
    for (j, nodes) in upper.iter().enumerate() {
        let ok = nodes.first() == Some(&(j as u32))
            && nodes.windows(2).all(|w| w[0] < w[1])
            && (0..b).all(|jj| {
                let c = j * b + jj;
                let rows = &pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]];
                rows.len() == nodes.len() * b - jj
                    && rows.iter().enumerate().all(|(t, &r)| {
                        let t = t + jj;
                        r as usize == nodes[t / b] as usize * b + t % b
                    })
            });
        if !ok {
            return Err(Error::solver(
                SolverFailure::Setup,
                format!("block matrix: column {} is not in nodal-block layout", j * b),
            ));
        }
    }
    Ok(upper)
}

impl BlockSym32 {
    /// Symbolic set-up from the lower triangle `pattern` in nodal-block
    /// layout ([`nodal_blocks`]).
    #[cfg(test)]
    pub fn try_new(pattern: &SymmetricCsc, b: usize) -> Result<BlockSym32> {
        BlockSym32::from_nodal_blocks(&nodal_blocks(pattern, b)?, b)
    }

    /// Symbolic set-up from the nodal-block layout `upper` of a lower
    /// triangle pattern ([`nodal_blocks`] of the pattern and `b`), read
    /// once for this and the double-precision operator.
    pub fn from_nodal_blocks(upper: &[Vec<u32>], b: usize) -> Result<BlockSym32> {
        let n_blocks = upper.len();
        // Lower block rows: transpose of the strictly upper part.
        let mut lower: Vec<Vec<u32>> = vec![Vec::new(); n_blocks];
        for (j, nodes) in upper.iter().enumerate() {
            for &i in &nodes[1..] {
                lower[i as usize].push(j as u32);
            }
        }
        let bb = b * b;
        let up = BlockRows::from_lists(upper, bb);
        let lo = BlockRows::from_lists(&lower, bb);
        if up.col.len() >= u32::MAX as usize {
            return Err(Error::solver(
                SolverFailure::Setup,
                format!("block matrix: {} blocks do not fit 32-bit indices", up.col.len()),
            ));
        }
        Ok(BlockSym32 { b, n_blocks, up, lo })
    }

    /// Numeric fill from the matrix `a` on the pattern given to
    /// [`Self::try_new`], whose operator is in the same nodal-block layout.
    pub fn update(&mut self, a: WithValues) {
        assert_eq!(a.block(), self.b, "the operator's nodal blocks are the copy's");
        let (pattern, values) = (a.pattern(), a.values());
        let (b, bb) = (self.b, self.b * self.b);
        super::split_by(&mut self.up.val, &self.up.ptr, bb).into_par_iter().enumerate().for_each(|(j, row)| {
            for jj in 0..b {
                let c = j * b + jj;
                let (s, e) = (pattern.col_ptr[c], pattern.col_ptr[c + 1]);
                // Rows (J, jj..b): the diagonal block, both triangles.
                for (t, &v) in values[s..s + b - jj].iter().enumerate() {
                    let ii = jj + t;
                    row[ii * b + jj] = v as f32;
                    row[jj * b + ii] = v as f32;
                }
                // Row (I, ii) of a later node: (ii, jj) of block (I, J) = (jj, ii) of block (J, I).
                for (t, &v) in values[s + b - jj..e].iter().enumerate() {
                    let (blk, ii) = (1 + t / b, t % b);
                    row[blk * bb + jj * b + ii] = v as f32;
                }
            }
        });
        let (up, lo_col, ptr) = (&self.up, &self.lo.col, &self.lo.ptr);
        super::split_by(&mut self.lo.val, ptr, bb).into_par_iter().enumerate().for_each(|(i, row)| {
            for ((t, blk), (j, pos)) in row.chunks_exact_mut(bb).enumerate().zip(a.lower_blocks(i)) {
                // Block (I, J) is the transpose of (J, I), block `pos` of row J of the upper part.
                debug_assert_eq!(lo_col[ptr[i] + t] as usize, j);
                let from = &up.val[(up.ptr[j] + pos) * bb..][..bb];
                for r in 0..b {
                    for c in 0..b {
                        blk[r * b + c] = from[c * b + r];
                    }
                }
            }
        });
    }

    /// Bytes held (indices and values).
    #[cfg(test)]
    pub fn memory_bytes(&self) -> usize {
        let part = |p: &BlockRows| p.ptr.len() * 8 + p.col.len() * 4 + p.val.len() * 4;
        part(&self.up) + part(&self.lo)
    }

    fn apply_block<const B: usize>(&self, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(CHUNK_ROWS * B).enumerate().for_each(|(t, yc)| {
            crate::linalg::with_avx2(
                #[inline(always)]
                || self.rows::<B>(t * CHUNK_ROWS, x, yc),
            )
        });
    }

    /// y of the block rows from `first` on (as many as `y` holds).
    #[inline(always)]
    fn rows<const B: usize>(&self, first: usize, x: &[f64], y: &mut [f64]) {
        for (di, yb) in y.chunks_exact_mut(B).enumerate() {
            let mut acc = [0.0f64; B];
            self.lo.add_row::<B>(first + di, x, &mut acc);
            self.up.add_row::<B>(first + di, x, &mut acc);
            yb.copy_from_slice(&acc);
        }
    }
}

impl Operator for BlockSym32 {
    fn n(&self) -> usize {
        self.n_blocks * self.b
    }
    fn apply_into(&self, x: &[f64], y: &mut [f64]) {
        match self.b {
            1 => self.apply_block::<1>(x, y),
            2 => self.apply_block::<2>(x, y),
            _ => self.apply_block::<3>(x, y),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lower-triangle pattern in nodal-block layout: a ring of `nodes` nodes,
    /// each coupled to the next two, block size `b`, with random values.
    fn ring(nodes: usize, b: usize) -> (SymmetricCsc, Vec<f64>) {
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::new();
        for j in 0..nodes {
            let mut nb: Vec<usize> = vec![j, (j + 1) % nodes, (j + 2) % nodes, (j + 7) % nodes];
            nb.retain(|&m| m >= j);
            nb.sort_unstable();
            nb.dedup();
            for jj in 0..b {
                for &m in &nb {
                    let from = if m == j { jj } else { 0 };
                    row_idx.extend((from..b).map(|ii| m * b + ii));
                }
                col_ptr.push(row_idx.len());
            }
        }
        let values = (0..row_idx.len()).map(|k| ((k * 7919) % 1000) as f64 / 250.0 - 2.0).collect();
        (SymmetricCsc { n: nodes * b, col_ptr, row_idx: row_idx.into_iter().map(|r| r as u32).collect() }, values)
    }

    #[test]
    fn product_matches_the_double_precision_lower_triangle() {
        for b in 1..=3 {
            let (pattern, values) = ring(23, b);
            let mut m = BlockSym32::try_new(&pattern, b).unwrap();
            let op = super::super::pcg::SymmetricOperator::try_new(&pattern, b).unwrap();
            m.update(op.with(&pattern, &values));
            let x: Vec<f64> = (0..pattern.n).map(|i| (i as f64 * 0.37).sin()).collect();
            let mut y = vec![0.0; pattern.n];
            m.apply_into(&x, &mut y);
            let want = pattern.sym_matvec(&values, &x);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (p, q) in y.iter().zip(&want) {
                assert!((p - q).abs() < 1e-6 * scale, "b = {b}: {p} vs {q}");
            }
            assert!(m.memory_bytes() > 0);
            // Bitwise the same with and without the AVX2 copy of the loop.
            let mut portable = vec![0.0; pattern.n];
            match b {
                1 => m.rows::<1>(0, &x, &mut portable),
                2 => m.rows::<2>(0, &x, &mut portable),
                _ => m.rows::<3>(0, &x, &mut portable),
            }
            assert!(y.iter().zip(&portable).all(|(p, q)| p.to_bits() == q.to_bits()), "b = {b}");
        }
    }

    #[test]
    fn a_pattern_not_in_nodal_blocks_is_refused() {
        let (mut pattern, _) = ring(5, 3);
        pattern.row_idx.swap(1, 2);
        assert!(BlockSym32::try_new(&pattern, 3).is_err());
        assert!(BlockSym32::try_new(&pattern, 2).is_err());
    }
}
