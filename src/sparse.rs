//! Sparse matrix storage shared by the assembly and the solvers: the lower
//! triangle of a symmetric matrix by columns ([`SymmetricCsc`]) and a
//! rectangular matrix by rows ([`SparseRows`], the multigrid transfers).

use rayon::prelude::*;

/// Lower triangle (row ≥ column) of a symmetric `n`×`n` sparse matrix, CSC.
#[derive(Debug, Clone, Default)]
pub struct SymmetricCsc {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column; 32-bit (half the memory of
    /// usize: 0.7 GB at a million unknowns, p = 4), so n < 2^32.
    pub row_idx: Vec<u32>,
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
        let row = u32::try_from(row).ok()?;
        self.row_idx[s..e].binary_search(&row).ok().map(|k| s + k)
    }

    /// y = A x for the symmetric matrix whose lower triangle is stored.
    pub fn sym_matvec(&self, values: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.n];
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[k] as usize;
                y[r] += values[k] * x[c];
                if r != c {
                    y[c] += values[k] * x[r];
                }
            }
        }
        y
    }
}

/// A rectangular sparse matrix by compressed rows (u32 column indices).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SparseRows {
    pub n_rows: usize,
    pub n_cols: usize,
    pub row_ptr: Vec<usize>,
    pub col: Vec<u32>,
    pub val: Vec<f64>,
}

impl SparseRows {
    /// Build from one list of (column, value) per row.
    pub fn from_rows(n_cols: usize, rows: &[Vec<(u32, f64)>]) -> SparseRows {
        let mut m = SparseRows { n_rows: rows.len(), n_cols, row_ptr: vec![0], ..Default::default() };
        for row in rows {
            for &(c, v) in row {
                m.col.push(c);
                m.val.push(v);
            }
            m.row_ptr.push(m.col.len());
        }
        m
    }

    /// y = M x.
    pub fn matvec_into(&self, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(1024).enumerate().for_each(|(i, yc)| {
            for (j, yr) in yc.iter_mut().enumerate() {
                let r = i * 1024 + j;
                *yr = (self.row_ptr[r]..self.row_ptr[r + 1]).map(|k| self.val[k] * x[self.col[k] as usize]).sum();
            }
        });
    }

    /// Mᵀ as compressed rows.
    pub fn transpose(&self) -> SparseRows {
        let mut ptr = vec![0usize; self.n_cols + 1];
        for &c in &self.col {
            ptr[c as usize + 1] += 1;
        }
        for i in 0..self.n_cols {
            ptr[i + 1] += ptr[i];
        }
        let mut fill = ptr.clone();
        let mut col = vec![0u32; self.col.len()];
        let mut val = vec![0.0; self.col.len()];
        for r in 0..self.n_rows {
            for k in self.row_ptr[r]..self.row_ptr[r + 1] {
                let c = self.col[k] as usize;
                col[fill[c]] = r as u32;
                val[fill[c]] = self.val[k];
                fill[c] += 1;
            }
        }
        SparseRows { n_rows: self.n_cols, n_cols: self.n_rows, row_ptr: ptr, col, val }
    }
}

/// Disjoint groups of nodes (node k owns the matrix rows k·b .. k·b + b for
/// nodal blocks of size b): group g is `nodes[ptr[g]..ptr[g + 1]]`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NodeGroups {
    pub ptr: Vec<usize>,
    pub nodes: Vec<u32>,
}

impl NodeGroups {
    /// Groups from lists of nodes; a node listed again (in the same or a
    /// later list) is kept only where it first appears, and groups left with
    /// fewer than two nodes are dropped (a nodal block smooths those).
    pub fn from_lists(lists: &[Vec<u32>], n_nodes: usize) -> NodeGroups {
        let mut taken = vec![false; n_nodes];
        let mut out = NodeGroups { ptr: vec![0], nodes: Vec::new() };
        for list in lists {
            let start = out.nodes.len();
            for &v in list {
                if !std::mem::replace(&mut taken[v as usize], true) {
                    out.nodes.push(v);
                }
            }
            match out.nodes.len() - start {
                0 => {}
                1 => {
                    taken[out.nodes[start] as usize] = false;
                    out.nodes.truncate(start);
                }
                _ => out.ptr.push(out.nodes.len()),
            }
        }
        out
    }

    /// Number of groups.
    pub fn len(&self) -> usize {
        self.ptr.len().saturating_sub(1)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The nodes of group `g`.
    pub fn group(&self, g: usize) -> &[u32] {
        &self.nodes[self.ptr[g]..self.ptr[g + 1]]
    }
}

/// `values` cut into the disjoint slices of compressed rows `ptr`, with
/// `per` values per entry (row k: entries ptr[k]..ptr[k + 1]).
pub(crate) fn split_by<'a, T>(values: &'a mut [T], ptr: &[usize], per: usize) -> Vec<&'a mut [T]> {
    let mut rows = Vec::with_capacity(ptr.len().saturating_sub(1));
    let mut rest = values;
    for w in ptr.windows(2) {
        let (head, tail) = rest.split_at_mut((w[1] - w[0]) * per);
        rows.push(head);
        rest = tail;
    }
    rows
}
