//! Line blocks of a smoother: groups of nodes whose whole diagonal block of
//! the matrix is factored and solved at once.
//!
//! On a mesh of stretched layers the strong couplings run across the thin
//! layers; a smoother that inverts only each node's own block (nodal block
//! Jacobi) leaves the error that is smooth along those lines almost
//! untouched, and the Krylov iterations grow with the stretching. A group is
//! the nodes of a line of cells through the layers (the caller finds them:
//! the solver sees only matrices); here its nodes are put in reverse
//! Cuthill–McKee order, so that its block is banded, about one
//! cross-section of the line wide, and its Cholesky factor is stored in
//! envelope (skyline) form, which keeps the band.

use rayon::prelude::*;

use super::{NodeGroups, SymmetricCsc};
use crate::{Error, Result, SolverFailure};

/// Envelope Cholesky factors L (L Lᵀ = the group's block of A) of every group.
#[derive(Debug, Clone)]
pub struct LineFactors {
    block: usize,
    groups: NodeGroups,
    /// Group g's local rows are rows[g]..rows[g + 1] of the envelope.
    rows: Vec<usize>,
    /// Per local row (all groups one after another): its first column in
    /// the envelope, local to the group.
    first: Vec<u32>,
    /// Per local row: where its entries (columns first..=row) start in `l`.
    start: Vec<usize>,
    /// The factors' entries, in single precision (a smoother's accuracy;
    /// half the memory of the envelopes, which are the bulk of it).
    l: Vec<f32>,
}

impl LineFactors {
    /// Factor the diagonal blocks of `groups` in the matrix with lower
    /// triangle (`pattern`, `values`), nodal blocks of size `block`. Fails
    /// if a group's block is not positive definite (then neither is the matrix).
    pub fn try_new(pattern: &SymmetricCsc, values: &[f64], block: usize, groups: &NodeGroups) -> Result<LineFactors> {
        let b = block;
        let n_nodes = pattern.n / b;
        let groups = &banded_order(pattern, b, groups, &places(groups, n_nodes));
        let place = places(groups, n_nodes);
        // The envelope: a node's first coupled position in its group.
        let mut first_node: Vec<u32> =
            (0..groups.len()).flat_map(|g| (0..groups.group(g).len() as u32).collect::<Vec<_>>()).collect();
        for g in 0..groups.len() {
            coupled_pairs(pattern, b, groups, &place, g, |pi, pj| {
                let f = &mut first_node[groups.ptr[g] + pi.max(pj) as usize];
                *f = (*f).min(pi.min(pj));
            });
        }
        let mut rows = Vec::with_capacity(groups.len() + 1);
        let (mut first, mut start) = (Vec::new(), Vec::new());
        let mut len = 0;
        rows.push(0);
        for g in 0..groups.len() {
            for k in 0..groups.group(g).len() {
                let f = first_node[groups.ptr[g] + k] as usize * b;
                for d in 0..b {
                    let row = k * b + d;
                    first.push(f as u32);
                    start.push(len);
                    len += row + 1 - f;
                }
            }
            rows.push(first.len());
        }
        start.push(len);
        let mut out = LineFactors { block, groups: groups.clone(), rows, first, start, l: vec![0.0f32; len] };
        out.fill_and_factor(pattern, values, &place)?;
        Ok(out)
    }

    /// Copy each group's block into its envelope and factor it in place.
    fn fill_and_factor(&mut self, pattern: &SymmetricCsc, values: &[f64], place: &[(u32, u32)]) -> Result<()> {
        let b = self.block;
        let entry_ptr: Vec<usize> = self.rows.iter().map(|&r| self.start[r]).collect();
        let slices = super::split_by(&mut self.l, &entry_ptr, 1);
        let (groups, rows, first, start) = (&self.groups, &self.rows, &self.first, &self.start);
        slices.into_par_iter().enumerate().try_for_each(|(g, out)| {
            let mut l = vec![0.0f64; out.len()];
            let (r0, base) = (rows[g], start[rows[g]]);
            let at = |row: usize, col: usize| start[r0 + row] - base + col - first[r0 + row] as usize;
            for &v in groups.group(g) {
                let pi = place[v as usize].1 as usize;
                for dc in 0..b {
                    let c = v as usize * b + dc;
                    for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                        let r = pattern.row_idx[k] as usize;
                        let (gr, pj) = place[r / b];
                        if gr as usize != g {
                            continue;
                        }
                        let (lr, lc) = (pj as usize * b + r % b, pi * b + dc);
                        l[at(lr.max(lc), lr.min(lc))] = values[k];
                    }
                }
            }
            let n = rows[g + 1] - r0;
            envelope_cholesky(&mut l, &first[r0..r0 + n], &start[r0..=r0 + n], base).map_err(|row| {
                Error::solver(
                    SolverFailure::NotPositiveDefinite,
                    format!("line smoother: the block of line {g} is not positive definite (row {row})"),
                )
            })?;
            out.iter_mut().zip(&l).for_each(|(o, &x)| *o = x as f32);
            Ok(())
        })
    }

    /// z = D⁻¹ r on the groups' rows (D the groups' blocks); other rows of `z` untouched.
    pub fn solve_into(&self, r: &[f64], z: &mut [f64]) {
        self.map_into(r, z, |f, g, y| {
            f.forward(g, y);
            f.backward(g, y);
        });
    }

    /// y = L⁻ᵀ x (`transposed`: y = L⁻¹ x) on the groups' rows: R = L⁻ᵀ has
    /// R Rᵀ = D⁻¹, the factor the Lanczos estimate of λ_max(D⁻¹A) needs.
    pub fn factor_into(&self, x: &[f64], y: &mut [f64], transposed: bool) {
        self.map_into(x, y, |f, g, v| if transposed { f.forward(g, v) } else { f.backward(g, v) });
    }

    /// Gather each group's rows of `x`, apply `op` in place, scatter into `y`.
    fn map_into(&self, x: &[f64], y: &mut [f64], op: impl Fn(&Self, usize, &mut [f64]) + Sync) {
        let b = self.block;
        let mut buf = vec![0.0; self.first.len()];
        let slices = super::split_by(&mut buf, &self.rows, 1);
        slices.into_par_iter().enumerate().for_each(|(g, v)| {
            for (k, &node) in self.groups.group(g).iter().enumerate() {
                v[k * b..(k + 1) * b].copy_from_slice(&x[node as usize * b..(node as usize + 1) * b]);
            }
            op(self, g, v);
        });
        let mut at = 0;
        for &node in &self.groups.nodes {
            y[node as usize * b..(node as usize + 1) * b].copy_from_slice(&buf[at..at + b]);
            at += b;
        }
    }

    /// v = L⁻¹ v for group g.
    fn forward(&self, g: usize, v: &mut [f64]) {
        let r0 = self.rows[g];
        for i in 0..v.len() {
            let f = self.first[r0 + i] as usize;
            let row = &self.l[self.start[r0 + i]..self.start[r0 + i + 1]];
            let s: f64 = row[..i - f].iter().zip(&v[f..i]).map(|(&a, b)| a as f64 * b).sum();
            v[i] = (v[i] - s) / row[i - f] as f64;
        }
    }

    /// v = L⁻ᵀ v for group g.
    fn backward(&self, g: usize, v: &mut [f64]) {
        let r0 = self.rows[g];
        for i in (0..v.len()).rev() {
            let f = self.first[r0 + i] as usize;
            let row = &self.l[self.start[r0 + i]..self.start[r0 + i + 1]];
            let xi = v[i] / row[i - f] as f64;
            v[i] = xi;
            for (vk, &a) in v[f..i].iter_mut().zip(&row[..i - f]) {
                *vk -= a as f64 * xi;
            }
        }
    }
}

/// Each node's group and position in it ((u32::MAX, 0) outside every group).
fn places(groups: &NodeGroups, n_nodes: usize) -> Vec<(u32, u32)> {
    let mut place = vec![(u32::MAX, 0u32); n_nodes];
    for g in 0..groups.len() {
        for (k, &v) in groups.group(g).iter().enumerate() {
            place[v as usize] = (g as u32, k as u32);
        }
    }
    place
}

/// `f(i, j)` for every pair of distinct positions i, j of group `g` whose
/// nodes the matrix couples (once per pair and dof of the first node's
/// column, so possibly more than once).
fn coupled_pairs(
    pattern: &SymmetricCsc,
    b: usize,
    groups: &NodeGroups,
    place: &[(u32, u32)],
    g: usize,
    mut f: impl FnMut(u32, u32),
) {
    for &v in groups.group(g) {
        let (_, pi) = place[v as usize];
        let c = v as usize * b;
        for &r in &pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]] {
            let (gr, pj) = place[r as usize / b];
            if gr as usize == g && pj != pi {
                f(pi, pj);
            }
        }
    }
}

/// The groups with each one's nodes in reverse Cuthill–McKee order:
/// breadth-first over the couplings from the node found last by a first
/// breadth-first pass (an end of the line), neighbours by increasing
/// degree, then reversed. A line's nodes then come
/// cross-section by cross-section, which keeps the envelope of its block
/// near the width of one cross-section; in the order the cells list them
/// the envelope was about twice as wide (3D layers, p = 4).
fn banded_order(pattern: &SymmetricCsc, b: usize, groups: &NodeGroups, place: &[(u32, u32)]) -> NodeGroups {
    let nodes: Vec<Vec<u32>> = (0..groups.len())
        .into_par_iter()
        .map(|g| {
            let members = groups.group(g);
            let mut adj = vec![Vec::new(); members.len()];
            coupled_pairs(pattern, b, groups, place, g, |i, j| {
                adj[i as usize].push(j);
                adj[j as usize].push(i);
            });
            for a in adj.iter_mut() {
                a.sort_unstable();
                a.dedup();
            }
            // Breadth-first from `root` over the unseen nodes, appended to `order`.
            let bfs = |root: usize, seen: &mut [bool], order: &mut Vec<u32>| {
                let mut head = order.len();
                seen[root] = true;
                order.push(root as u32);
                while head < order.len() {
                    let mut next: Vec<u32> =
                        adj[order[head] as usize].iter().copied().filter(|&j| !seen[j as usize]).collect();
                    next.sort_by_key(|&j| (adj[j as usize].len(), j));
                    for j in next {
                        seen[j as usize] = true;
                        order.push(j);
                    }
                    head += 1;
                }
            };
            let mut seen = vec![false; members.len()];
            let mut order = Vec::with_capacity(members.len());
            for root in 0..members.len() {
                if seen[root] {
                    continue;
                }
                // Start from the node found last from `root`: an end of the line.
                let mut probe = seen.clone();
                let mut reached = Vec::new();
                bfs(root, &mut probe, &mut reached);
                bfs(*reached.last().expect("the root itself") as usize, &mut seen, &mut order);
            }
            order.iter().rev().map(|&k| members[k as usize]).collect()
        })
        .collect();
    let mut out = NodeGroups { ptr: vec![0], nodes: Vec::with_capacity(groups.nodes.len()) };
    for list in nodes {
        out.nodes.extend(list);
        out.ptr.push(out.nodes.len());
    }
    out
}

/// Cholesky factorisation in place of a symmetric matrix stored by rows in
/// envelope form (row i: columns `first[i]..=i` at `start[i] - base`
/// onwards in `l`); the factor has the same envelope. Err(row) at a pivot
/// that is not positive.
fn envelope_cholesky(l: &mut [f64], first: &[u32], start: &[usize], base: usize) -> std::result::Result<(), usize> {
    let n = first.len();
    for i in 0..n {
        let fi = first[i] as usize;
        let si = start[i] - base;
        for j in fi..=i {
            let fj = first[j] as usize;
            let sj = start[j] - base;
            let k0 = fi.max(fj);
            let mut s = l[si + j - fi];
            for k in k0..j {
                s -= l[si + k - fi] * l[sj + k - fj];
            }
            if j < i {
                l[si + j - fi] = s / l[sj + j - fj];
            } else {
                if !(s > 0.0 && s.is_finite()) {
                    return Err(i);
                }
                l[si + i - fi] = s.sqrt();
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::pcg::tests::grid_laplacian;

    /// The dense symmetric matrix of a lower triangle.
    fn dense(a: &SymmetricCsc, v: &[f64]) -> Vec<Vec<f64>> {
        let mut m = vec![vec![0.0; a.n]; a.n];
        for c in 0..a.n {
            for k in a.col_ptr[c]..a.col_ptr[c + 1] {
                let r = a.row_idx[k] as usize;
                m[r][c] = v[k];
                m[c][r] = v[k];
            }
        }
        m
    }

    fn groups_of_grid(m: usize) -> NodeGroups {
        // Columns of the m × m grid, one in reverse order, and a lone node
        // (dropped), over nodes numbered row by row.
        let mut lists: Vec<Vec<u32>> = (0..m - 1).map(|c| (0..m).map(|r| (r * m + c) as u32).collect()).collect();
        lists[1].reverse();
        lists.push(vec![(m - 1) as u32]);
        NodeGroups::from_lists(&lists, m * m)
    }

    #[test]
    fn group_solves_match_dense_solves_of_the_group_blocks() {
        let m = 7;
        for block in [1, 2, 3] {
            let (a, v) = grid_laplacian(m, block);
            let groups = groups_of_grid(m);
            assert_eq!(groups.len(), m - 1, "the lone node is dropped");
            let f = LineFactors::try_new(&a, &v, block, &groups).unwrap();
            let full = dense(&a, &v);
            let r: Vec<f64> = (0..a.n).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
            let mut z = vec![f64::NAN; a.n];
            f.solve_into(&r, &mut z);
            for g in 0..groups.len() {
                let rows: Vec<usize> =
                    groups.group(g).iter().flat_map(|&v| (0..block).map(move |d| v as usize * block + d)).collect();
                // The group's block times z equals r on its rows.
                for &i in &rows {
                    let s: f64 = rows.iter().map(|&j| full[i][j] * z[j]).sum();
                    assert!((s - r[i]).abs() < 1e-5 * (1.0 + r[i].abs()), "block {block} group {g}: {s} vs {}", r[i]);
                }
            }
            // Rows outside every group are untouched.
            let outside = (m - 1) * block;
            assert!(z[outside].is_nan());
            // R Rᵀ = D⁻¹ with R = L⁻ᵀ: R (Rᵀ r) equals the solve.
            let (mut t, mut y) = (vec![0.0; a.n], vec![0.0; a.n]);
            f.factor_into(&r, &mut t, true);
            f.factor_into(&t, &mut y, false);
            for i in 0..a.n {
                if !z[i].is_nan() {
                    assert!((y[i] - z[i]).abs() < 1e-12 * (1.0 + z[i].abs()));
                }
            }
        }
    }

    #[test]
    fn a_line_listed_out_of_order_is_factored_with_the_band_of_a_path() {
        // One column of the grid (a path of m nodes) listed scrambled: in
        // path order its block is tridiagonal, an envelope of 2m − 1 entries.
        let m = 9;
        let (a, v) = grid_laplacian(m, 1);
        let scrambled: Vec<u32> = [4, 0, 8, 2, 6, 1, 7, 3, 5].iter().map(|&r| (r * m) as u32).collect();
        let groups = NodeGroups::from_lists(&[scrambled], m * m);
        let f = LineFactors::try_new(&a, &v, 1, &groups).unwrap();
        assert_eq!(f.l.len(), 2 * m - 1);
    }

    #[test]
    fn an_indefinite_group_block_is_refused() {
        let (a, mut v) = grid_laplacian(5, 1);
        // Negate the diagonal entry of node 10 (x = 0, y = 2: the first column's group).
        let k = a.col_ptr[10];
        v[k] = -v[k];
        let groups = groups_of_grid(5);
        let e = LineFactors::try_new(&a, &v, 1, &groups).unwrap_err();
        assert!(e.to_string().contains("not positive definite"), "{e}");
    }
}
