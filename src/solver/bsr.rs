//! A single-precision copy of a symmetric matrix with nodal blocks, for the
//! products inside the preconditioner.
//!
//! The V-cycle makes six of the seven products with the fine matrix in each
//! PCG iteration ([`super::pmg`]), and those products are memory-bound. Stored
//! by block rows of `b × b` blocks (BSR), one `u32` block-column index per
//! block and `f32` values, a product reads 4.4 bytes per entry, against 8.4
//! for the double-precision lower triangle read in place by
//! [`super::pcg::SymmetricOperator`]. The rows go in fixed chunks of nodes,
//! one task each, and only the upper blocks (J, I ≥ J) are stored, each read
//! once: it adds to row J and, transposed, to row I. A chunk sums into its
//! own buffer, from its first row to the last its blocks reach, and the
//! buffers are added up by rows afterwards ([`add_parts`]). Before, the
//! blocks whose row I lay in a later chunk were stored a second time,
//! transposed, by row I, for that chunk to stream (at p = 4, 25 % of the
//! off-diagonal blocks on the sphere cavity of bench/compare_gmsh.sh, 36 %
//! on the built-in million-unknown mesh): read twice, and held twice.
//! Single precision is enough for a preconditioner (its entries are relative
//! perturbations of 6e-8 of the matrix); PCG itself multiplies in double.
//!
//! Measured on the p = 4 sphere-in-box mesh of bench/compare_gmsh.sh (76,542
//! unknowns), in docs/performance.md.

use std::sync::Mutex;

use rayon::prelude::*;

use super::SymmetricCsc;
use crate::{Error, Result, SolverFailure};

/// y = A x for some fixed symmetric matrix A.
pub trait Operator: Sync {
    fn n(&self) -> usize;
    fn apply_into(&self, x: &[f64], y: &mut [f64]);
}

/// Node rows per chunk of a product (one parallel task; the chunks depend
/// on the matrix, not on the number of threads, so neither do the sums):
/// a sixteenth of the nodes, from [`CHUNK_NODES`] to [`CHUNK_NODES_MAX`].
/// Each chunk sums into a buffer that runs from its first row to the last
/// its blocks reach, about the chunk plus the bandwidth of the numbering:
/// at a million unknowns (350,270 nodes, bandwidth about 33,000 nodes),
/// chunks of 4,096 nodes made buffers 9.1 times the vector, and the product
/// took 40–43 ms; chunks of 16,384, 3.0 times and 32–33 ms.
fn chunk_nodes(n_nodes: usize) -> usize {
    (n_nodes / 16).clamp(CHUNK_NODES, CHUNK_NODES_MAX)
}

/// The smallest chunk of a product, in node rows.
const CHUNK_NODES: usize = 4096;

/// The largest chunk of a product, in node rows.
const CHUNK_NODES_MAX: usize = 16384;

/// A symmetric matrix stored by its upper block rows in single precision.
#[derive(Debug, Clone)]
pub struct BlockSym32 {
    /// Block size.
    b: usize,
    n_blocks: usize,
    /// Node rows per chunk of a product.
    chunk: usize,
    /// Upper blocks (J, I ≥ J) of row J, in the order of column J·b of the
    /// lower triangle (the diagonal block first).
    up: BlockRows,
    /// Per chunk, one past the last node row its blocks reach ([`chunk_reach`]).
    reach: Vec<usize>,
    /// x padded to the lanes of a product, kept from one to the next.
    padded: Padded,
}

/// Lanes 0..`b` of `t` summed from the first on.
#[inline(always)]
pub(super) fn sum_lanes<const L: usize>(t: &[f64; L], b: usize) -> f64 {
    t[1..b].iter().fold(t[0], |a, v| a + v)
}

/// A vector copied with its `B` entries per node padded by zeros to `L`,
/// the lanes of a product's loops, held from one product to the next.
#[derive(Debug, Default)]
pub(super) struct Padded(Mutex<Vec<f64>>);

impl Clone for Padded {
    /// A new, empty one (it holds nothing between products).
    fn clone(&self) -> Padded {
        Padded::default()
    }
}

impl Padded {
    /// `x` padded: in the kept vector, or, when that is in use (a product
    /// on the same operator running at the same time, perhaps on this very
    /// thread through rayon's work stealing), in a new one.
    pub(super) fn fill<const B: usize, const L: usize>(&self, x: &[f64]) -> PaddedX<'_> {
        let mut padded = match self.0.try_lock() {
            Ok(kept) => PaddedX::Kept(kept),
            Err(std::sync::TryLockError::Poisoned(e)) => PaddedX::Kept(e.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => PaddedX::New(Vec::new()),
        };
        let v: &mut Vec<f64> = match &mut padded {
            PaddedX::Kept(g) => g,
            PaddedX::New(v) => v,
        };
        v.resize(x.len() / B * L, 0.0);
        v.par_chunks_mut(L * PAD_NODES).zip(x.par_chunks(B * PAD_NODES)).for_each(|(p, x)| {
            for (p, x) in p.chunks_exact_mut(L).zip(x.chunks_exact(B)) {
                p[..B].copy_from_slice(x);
                p[B..].fill(0.0);
            }
        });
        padded
    }
}

/// A padded copy of x ([`Padded::fill`]).
pub(super) enum PaddedX<'a> {
    Kept(std::sync::MutexGuard<'a, Vec<f64>>),
    New(Vec<f64>),
}

impl std::ops::Deref for PaddedX<'_> {
    type Target = [f64];
    fn deref(&self) -> &[f64] {
        match self {
            PaddedX::Kept(g) => g,
            PaddedX::New(v) => v,
        }
    }
}

/// Values stored past the last block, which the product reads as the
/// lanes past the last row (below).
const OVERREAD: usize = 1;

/// Nodes per task when x is padded for a product.
const PAD_NODES: usize = 16384;

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
        BlockRows { val: vec![0.0; col.len() * bb + OVERREAD], ptr, col }
    }
}

/// Per chunk of `per` node rows, one past the last node row that its
/// columns reach (at least the chunk's end): `columns` as from
/// [`nodal_blocks`], each list ascending.
pub(super) fn chunk_reach(columns: &[Vec<u32>], per: usize) -> Vec<usize> {
    (0..columns.len().div_ceil(per))
        .map(|t| {
            let (first, end) = (t * per, ((t + 1) * per).min(columns.len()));
            columns[first..end].iter().filter_map(|c| c.last()).map(|&i| i as usize + 1).fold(end, usize::max)
        })
        .collect()
}

/// y = A x by chunks of `per` node rows: `chunk(first, part)` sums the
/// columns of the chunk from node `first` into `part`, `L` lanes per node
/// row from `first` to the chunk's reach (`reach`, [`chunk_reach`]); the
/// parts are then added up by rows ([`add_parts`]).
pub(super) fn product_by_chunks<const B: usize, const L: usize>(
    reach: &[usize],
    per: usize,
    y: &mut [f64],
    chunk: impl Fn(usize, &mut [f64]) + Sync,
) {
    let parts: Vec<Vec<f64>> = reach
        .par_iter()
        .enumerate()
        .map(|(t, &r)| {
            let mut part = vec![0.0; (r - t * per) * L];
            chunk(t * per, &mut part);
            part
        })
        .collect();
    add_parts::<B, L>(&parts, per, y);
}

/// y from the partial sums of a product by chunks of `per` node rows:
/// `parts[t]` holds, `L` lanes per node, the sums of chunk t's columns for
/// the rows from its first on (its own rows, then those of later chunks
/// that its columns reach). Each row adds its own chunk's sum, then the
/// earlier chunks' in order: the same sums whatever the threads.
pub(super) fn add_parts<const B: usize, const L: usize>(parts: &[Vec<f64>], per: usize, y: &mut [f64]) {
    y.par_chunks_mut(per * B).enumerate().for_each(|(u, yc)| {
        let first = u * per;
        for (yn, p) in yc.chunks_exact_mut(B).zip(parts[u].chunks_exact(L)) {
            yn.copy_from_slice(&p[..B]);
        }
        for (t, part) in parts[..u].iter().enumerate() {
            let from = (first - t * per) * L;
            if part.len() > from {
                for (yn, p) in yc.chunks_exact_mut(B).zip(part[from..].chunks_exact(L)) {
                    for (y, v) in yn.iter_mut().zip(p) {
                        *y += v;
                    }
                }
            }
        }
    });
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
    let bad = upper.par_iter().enumerate().find_first(|(j, nodes)| {
        let j = *j;
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
        !ok
    });
    match bad {
        Some((j, _)) => Err(Error::solver(
            SolverFailure::Setup,
            format!("block matrix: column {} is not in nodal-block layout", j * b),
        )),
        None => Ok(upper),
    }
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
        BlockSym32::with_chunks(upper, b, chunk_nodes(upper.len()))
    }

    /// [`Self::from_nodal_blocks`] with products in chunks of `chunk` node rows.
    fn with_chunks(upper: &[Vec<u32>], b: usize, chunk: usize) -> Result<BlockSym32> {
        let n_blocks = upper.len();
        let up = BlockRows::from_lists(upper, b * b);
        if up.col.len() >= u32::MAX as usize {
            return Err(Error::solver(
                SolverFailure::Setup,
                format!("block matrix: {} blocks do not fit 32-bit indices", up.col.len()),
            ));
        }
        let reach = chunk_reach(upper, chunk);
        Ok(BlockSym32 { b, n_blocks, chunk, up, reach, padded: Padded::default() })
    }

    /// Numeric fill from the lower-triangle `values` of a matrix on the pattern
    /// given to [`Self::from_nodal_blocks`].
    pub fn update(&mut self, pattern: &SymmetricCsc, values: &[f64]) {
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
    }

    /// Bytes held (indices and values).
    #[cfg(test)]
    pub fn memory_bytes(&self) -> usize {
        self.up.ptr.len() * 8 + self.up.col.len() * 4 + self.up.val.len() * 4
    }

    /// y = A x with blocks of `B` and rows of `L` lanes (`L` ≥ `B`, the
    /// vector width the loop works in, below): each chunk's sums, then
    /// added up by rows ([`add_parts`]).
    fn apply_block<const B: usize, const L: usize>(&self, x: &[f64], y: &mut [f64]) {
        let padded = self.padded.fill::<B, L>(x);
        let padded = &padded[..];
        product_by_chunks::<B, L>(&self.reach, self.chunk, y, |first, part| {
            #[cfg(target_arch = "x86_64")]
            if B == 3 && L == 4 && std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor supports AVX2 (checked just above).
                return unsafe { avx2::chunk_rows_3(self, first, padded, part) };
            }
            crate::linalg::with_avx2(
                #[inline(always)]
                || self.chunk_rows::<B, L>(first, padded, part),
            )
        });
    }

    /// The sums of the block rows of the chunk from node `first` on, `x`
    /// padded to `L` entries per node (the last `L − B` zero), into `part`:
    /// `L` lanes per node row from `first` to the chunk's reach.
    ///
    /// A block's row r is read as the `L` values from its start (reaching
    /// into the next row, or the padding after the last block): for the
    /// row of the block's own row node, lane by lane, t_r += a_r ⊙ x_I,
    /// summed over lanes 0..B once per row node; for the transposed block,
    /// y_I += x_J[r] a_r, whose lanes past `B` are dropped. Both are vector
    /// operations of `L` lanes with no shuffle. The compiler does not find
    /// the vectors at `B` = 3, `L` = 4 (it shuffles scalars), so on AVX2
    /// [`avx2::chunk_rows_3`] writes them out, with the same operations in
    /// the same order: on the sphere cavity at p = 4 (72,666 unknowns,
    /// 866,038 upper blocks), 5.1 ms against 7.4 ms for the 3 × 3 loops
    /// before; the product is bound by memory traffic from there.
    #[inline(always)]
    fn chunk_rows<const B: usize, const L: usize>(&self, first: usize, x: &[f64], part: &mut [f64]) {
        let end = (first + self.chunk).min(self.n_blocks);
        let bb = B * B;
        let xv = |i: usize| -> [f64; L] { x[i * L..][..L].try_into().expect("L lanes") };
        // Each block to its row and, transposed, to the row of its column.
        let up = &self.up;
        for j in first..end {
            let xj = xv(j);
            let mut t = [[0.0f64; L]; B];
            for k in up.ptr[j]..up.ptr[j + 1] {
                let i = up.col[k] as usize;
                let (a, xi) = (&up.val[k * bb..][..bb + L - B], xv(i));
                for r in 0..B {
                    for l in 0..L {
                        t[r][l] += f64::from(a[r * B + l]) * xi[l];
                    }
                }
                if i != j {
                    let yi = &mut part[(i - first) * L..][..L];
                    for r in 0..B {
                        for l in 0..L {
                            yi[l] += f64::from(a[r * B + l]) * xj[r];
                        }
                    }
                }
            }
            for (o, tr) in part[(j - first) * L..][..B].iter_mut().zip(&t) {
                *o += sum_lanes(tr, B);
            }
        }
    }
}

/// [`BlockSym32::chunk_rows`] for blocks of 3 in lanes of 4, in AVX2 vectors.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::super::simd::{add_sums, block, load, load_f32};
    use super::BlockSym32;

    /// Values ahead (8 KB) that the blocks' stream is prefetched: from
    /// memory, on a 516,186-unknown matrix, 24–26 ms against 31–36 ms
    /// without (three interleaved runs, medians of 31 products each).
    const PF: usize = 2048;

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chunk_rows_3(m: &BlockSym32, first: usize, x: &[f64], part: &mut [f64]) {
        let end = (first + m.chunk).min(m.n_blocks);
        let up = &m.up;
        for j in first..end {
            let xb = [_mm256_set1_pd(x[j * 4]), _mm256_set1_pd(x[j * 4 + 1]), _mm256_set1_pd(x[j * 4 + 2])];
            let mut t = [_mm256_setzero_pd(); 3];
            for k in up.ptr[j]..up.ptr[j + 1] {
                let i = up.col[k] as usize;
                let a = &up.val[k * 9..];
                // A prefetch past the end of the values is harmless (it never faults).
                _mm_prefetch(a.as_ptr().wrapping_add(PF) as *const i8, _MM_HINT_T0);
                let a = [load_f32(a), load_f32(&a[3..]), load_f32(&a[6..])];
                let to = (i != j).then(|| (&mut part[(i - first) * 4..], &xb));
                block(&mut t, &a, load(&x[i * 4..]), to);
            }
            add_sums(&mut part[(j - first) * 4..], &t);
        }
    }
}

impl Operator for BlockSym32 {
    fn n(&self) -> usize {
        self.n_blocks * self.b
    }
    fn apply_into(&self, x: &[f64], y: &mut [f64]) {
        match self.b {
            1 => self.apply_block::<1, 1>(x, y),
            2 => self.apply_block::<2, 2>(x, y),
            _ => self.apply_block::<3, 4>(x, y),
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

    /// The layout is read from each node's first column and checked on all
    /// of them: a column whose rows break it is named.
    #[test]
    fn nodal_blocks_reads_the_layout_and_names_a_column_that_breaks_it() {
        let (pattern, _) = ring(23, 3);
        let upper = nodal_blocks(&pattern, 3).unwrap();
        assert_eq!(upper.len(), 23);
        assert_eq!(upper[0], [0, 1, 2, 7]);
        assert_eq!(upper[22], [22]);
        // Node 5's second column (dof 16) loses its last row.
        let mut broken = pattern.clone();
        let end = broken.col_ptr[17] - 1;
        broken.row_idx.remove(end);
        broken.col_ptr[17..].iter_mut().for_each(|p| *p -= 1);
        let err = nodal_blocks(&broken, 3).unwrap_err().to_string();
        assert!(err.contains("column 15 is not in nodal-block layout"), "{err}");
    }

    #[test]
    fn chunks_are_a_sixteenth_of_the_nodes_within_their_bounds() {
        assert_eq!(chunk_nodes(1), CHUNK_NODES);
        assert_eq!(chunk_nodes(16 * CHUNK_NODES + 15), CHUNK_NODES);
        assert_eq!(chunk_nodes(16 * 10_000 + 3), 10_000);
        assert_eq!(chunk_nodes(350_270), CHUNK_NODES_MAX);
    }

    #[test]
    fn product_matches_the_double_precision_lower_triangle() {
        for b in 1..=3 {
            let (pattern, values) = ring(23, b);
            let x: Vec<f64> = (0..pattern.n).map(|i| (i as f64 * 0.37).sin()).collect();
            let want = pattern.sym_matvec(&values, &x);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            // One chunk, and chunks that blocks cross (the ring couples node
            // 0 with 22, and each node with the next 1, 2 and 7).
            for chunk in [CHUNK_NODES, 5, 1] {
                let mut m = BlockSym32::with_chunks(&nodal_blocks(&pattern, b).unwrap(), b, chunk).unwrap();
                m.update(&pattern, &values);
                assert_eq!(m.reach.len(), 23usize.div_ceil(chunk), "b = {b}, chunk {chunk}");
                let mut y = vec![0.0; pattern.n];
                m.apply_into(&x, &mut y);
                for (p, q) in y.iter().zip(&want) {
                    assert!((p - q).abs() < 1e-6 * scale, "b = {b}, chunk {chunk}: {p} vs {q}");
                }
                assert!(m.memory_bytes() > 0);
                // Bitwise the same with and without the AVX2 loops.
                let lanes = if b == 3 { 4 } else { b };
                let mut padded = vec![0.0; pattern.n / b * lanes];
                for (p, v) in padded.chunks_exact_mut(lanes).zip(x.chunks_exact(b)) {
                    p[..b].copy_from_slice(v);
                }
                let mut portable = vec![0.0; pattern.n];
                match b {
                    1 => product_by_chunks::<1, 1>(&m.reach, chunk, &mut portable, |f, p| m.chunk_rows::<1, 1>(f, &padded, p)),
                    2 => product_by_chunks::<2, 2>(&m.reach, chunk, &mut portable, |f, p| m.chunk_rows::<2, 2>(f, &padded, p)),
                    _ => product_by_chunks::<3, 4>(&m.reach, chunk, &mut portable, |f, p| m.chunk_rows::<3, 4>(f, &padded, p)),
                }
                assert!(y.iter().zip(&portable).all(|(p, q)| p.to_bits() == q.to_bits()), "b = {b}, chunk {chunk}");
            }
        }
    }

    #[test]
    fn x_is_padded_in_a_new_vector_while_the_kept_one_is_in_use() {
        let x: Vec<f64> = (0..9).map(f64::from).collect();
        let want = [0.0, 1.0, 2.0, 0.0, 3.0, 4.0, 5.0, 0.0, 6.0, 7.0, 8.0, 0.0];
        let padded = Padded::default();
        let first = padded.fill::<3, 4>(&x);
        let second = padded.fill::<3, 4>(&x);
        assert!(matches!(first, PaddedX::Kept(_)) && matches!(second, PaddedX::New(_)));
        assert_eq!((&*first, &*second), (&want[..], &want[..]));
        drop((first, second));
        assert!(matches!(padded.fill::<3, 4>(&x[..6]), PaddedX::Kept(v) if v[..] == want[..8]));
    }

    #[test]
    fn a_pattern_not_in_nodal_blocks_is_refused() {
        let (mut pattern, _) = ring(5, 3);
        pattern.row_idx.swap(1, 2);
        assert!(BlockSym32::try_new(&pattern, 3).is_err());
        assert!(BlockSym32::try_new(&pattern, 2).is_err());
    }
}
