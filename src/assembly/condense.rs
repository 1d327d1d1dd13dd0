//! Static condensation of the cell-interior nodes.
//!
//! A node inside a cell (every barycentric count positive: one at p = 4 in 3D,
//! ten at p = 6; one at p = 3 in 2D) couples only with the nodes of its own
//! cell. Splitting the element's dofs into interior I and the rest B (the
//! cell's vertex, edge and face nodes, free or prescribed), the element system
//!
//! [K_BB K_BI; K_IB K_II] [u_B; u_I] = [f_B; f_I]
//!
//! gives u_I = K_II⁻¹ (f_I − K_IB u_B), so that only
//!
//! (K_BB − K_BI K_II⁻¹ K_IB) u_B = f_B − K_BI K_II⁻¹ f_I
//!
//! is assembled: the global system loses the interior unknowns and their
//! couplings, and each cell keeps W = K_II⁻¹ K_IB and g = K_II⁻¹ f_I to
//! recover u_I = g − W u_B after the solve. The Schur complement of a
//! symmetric positive definite matrix is symmetric positive definite, so every
//! solver path applies unchanged; K_II is factored by LU with partial pivoting
//! (an indefinite CIL or Newton tangent can reach it).

use rayon::prelude::*;

use super::DofMap;
use crate::mesh::HighOrderMesh;
use crate::reference::NodeSet;

/// Local dofs (node · dim + component) of one cell, interior and boundary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LocalSplit {
    /// Dofs of the cell-interior nodes.
    pub interior: Vec<usize>,
    /// All other dofs of the cell.
    pub boundary: Vec<usize>,
}

impl LocalSplit {
    /// The split of an order-`mesh.order` cell; `interior` is empty below
    /// order 3 (2D) or 4 (3D).
    pub fn new(mesh: &HighOrderMesh) -> LocalSplit {
        let dim = mesh.dim();
        let nodes = NodeSet::new(mesh.simplex, mesh.order, mesh.spacing);
        let (mut interior, mut boundary) = (Vec::new(), Vec::new());
        for (a, m) in nodes.multi.iter().enumerate() {
            let side = if m[..=dim].iter().all(|&k| k > 0) { &mut interior } else { &mut boundary };
            side.extend(a * dim..(a + 1) * dim);
        }
        LocalSplit { interior, boundary }
    }

    /// Doubles kept per cell for the recovery: W (|I| × |B|) and g (|I|).
    pub fn stride(&self) -> usize {
        self.interior.len() * (self.boundary.len() + 1)
    }
}

/// [`condense_element`] met a singular interior block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SingularInterior;

/// Scratch space of [`condense_element`].
#[derive(Debug, Clone, Default)]
pub struct CondenseWorkspace {
    lu: Vec<f64>,
    perm: Vec<usize>,
    kbi: Vec<f64>,
}

/// Condense the element matrix `ke` (row-major, `n` = |I| + |B| dofs) and,
/// when given, the internal-force vector `re` (f = −re) onto the boundary
/// dofs, in place: the B×B block of `ke` becomes the Schur complement and
/// re_B becomes re_B + K_BI g; the I rows and columns are left as they were
/// and must not be assembled. Writes W (row-major |I| × |B|) then g into
/// `keep`. Fails if K_II is singular (to round-off).
pub fn condense_element(
    split: &LocalSplit,
    ke: &mut [f64],
    re: Option<&mut [f64]>,
    keep: &mut [f64],
    ws: &mut CondenseWorkspace,
) -> Result<(), SingularInterior> {
    crate::linalg::with_avx2(#[inline(always)] || condense(split, ke, re, keep, ws))
}

/// [`condense_element`], inlined into each copy.
#[inline(always)]
fn condense(
    split: &LocalSplit,
    ke: &mut [f64],
    re: Option<&mut [f64]>,
    keep: &mut [f64],
    ws: &mut CondenseWorkspace,
) -> Result<(), SingularInterior> {
    let (ii, bb) = (&split.interior, &split.boundary);
    let (ni, nb) = (ii.len(), bb.len());
    let n = ni + nb;
    let (w, g) = keep.split_at_mut(ni * nb);
    factor_interior(ii, ke, n, ws)?;
    // The native node order puts the interior nodes last: the boundary dofs
    // are then 0..nb, and rows of K_IB and K_BB are contiguous slices.
    let prefix = bb.iter().enumerate().all(|(k, &c)| k == c);
    // Right-hand sides in the pivoted row order: K_IB and f_I = −re_I.
    for (i, &pi) in ws.perm.iter().enumerate() {
        let r = ii[pi];
        let wi = &mut w[i * nb..(i + 1) * nb];
        if prefix {
            wi.copy_from_slice(&ke[r * n..r * n + nb]);
        } else {
            wi.iter_mut().zip(bb).for_each(|(x, &c)| *x = ke[r * n + c]);
        }
        g[i] = re.as_ref().map_or(0.0, |re| -re[r]);
    }
    substitute(&ws.lu, ni, nb, w, g);
    schur_update(split, prefix, ke, re, w, g, ws);
    Ok(())
}

/// LU of K_II with partial pivoting into `ws.lu` and `ws.perm`; fails on a pivot ≤ 1e-14 of the largest entry.
#[inline(always)]
fn factor_interior(ii: &[usize], ke: &[f64], n: usize, ws: &mut CondenseWorkspace) -> Result<(), SingularInterior> {
    let ni = ii.len();
    ws.lu.clear();
    for &r in ii {
        ws.lu.extend(ii.iter().map(|&c| ke[r * n + c]));
    }
    ws.perm.clear();
    ws.perm.extend(0..ni);
    let lu = &mut ws.lu;
    let scale = lu.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for k in 0..ni {
        let p = (k..ni).max_by(|&a, &b| lu[a * ni + k].abs().total_cmp(&lu[b * ni + k].abs())).expect("k < ni");
        let pivot = lu[p * ni + k].abs();
        if pivot.is_nan() || pivot <= 1e-14 * scale {
            return Err(SingularInterior);
        }
        if p != k {
            for j in 0..ni {
                lu.swap(k * ni + j, p * ni + j);
            }
            ws.perm.swap(k, p);
        }
        let pivot = lu[k * ni + k];
        for i in k + 1..ni {
            let l = lu[i * ni + k] / pivot;
            lu[i * ni + k] = l;
            for j in k + 1..ni {
                lu[i * ni + j] -= l * lu[k * ni + j];
            }
        }
    }
    Ok(())
}

/// W ← K_II⁻¹ W and g ← K_II⁻¹ g by forward and backward substitution with the LU factors `lu`.
#[inline(always)]
fn substitute(lu: &[f64], ni: usize, nb: usize, w: &mut [f64], g: &mut [f64]) {
    // Forward (unit L) then backward (U) substitution, row by row over all columns.
    for i in 0..ni {
        for k in 0..i {
            let l = lu[i * ni + k];
            if l != 0.0 {
                let (done, row) = w.split_at_mut(i * nb);
                for (x, y) in row[..nb].iter_mut().zip(&done[k * nb..(k + 1) * nb]) {
                    *x = (-l).mul_add(*y, *x);
                }
                g[i] -= l * g[k];
            }
        }
    }
    for i in (0..ni).rev() {
        for k in i + 1..ni {
            let u = lu[i * ni + k];
            let (head, tail) = w.split_at_mut(k * nb);
            for (x, y) in head[i * nb..(i + 1) * nb].iter_mut().zip(&tail[..nb]) {
                *x = (-u).mul_add(*y, *x);
            }
            g[i] -= u * g[k];
        }
        let d = 1.0 / lu[i * ni + i];
        w[i * nb..(i + 1) * nb].iter_mut().for_each(|x| *x *= d);
        g[i] *= d;
    }
}

/// K_BB −= K_BI W and re_B += K_BI g, in place in `ke` and `re`; `prefix`:
/// the boundary dofs are 0..|B|.
#[inline(always)]
fn schur_update(
    split: &LocalSplit,
    prefix: bool,
    ke: &mut [f64],
    mut re: Option<&mut [f64]>,
    w: &[f64],
    g: &[f64],
    ws: &mut CondenseWorkspace,
) {
    let (ii, bb) = (&split.interior, &split.boundary);
    let nb = bb.len();
    let n = ii.len() + nb;
    for &r in bb {
        let row = &mut ke[r * n..(r + 1) * n];
        ws.kbi.clear();
        ws.kbi.extend(ii.iter().map(|&c| row[c]));
        let kbi = &ws.kbi;
        // Row r of K_BB minus each row of W in turn, contiguous (vectorised)
        // when the boundary dofs come first.
        for (i, &k) in kbi.iter().enumerate() {
            let wi = &w[i * nb..(i + 1) * nb];
            if prefix {
                row[..nb].iter_mut().zip(wi).for_each(|(x, y)| *x = (-k).mul_add(*y, *x));
            } else {
                bb.iter().zip(wi).for_each(|(&c, y)| row[c] = (-k).mul_add(*y, row[c]));
            }
        }
        if let Some(re) = re.as_deref_mut() {
            re[r] += kbi.iter().zip(g.iter()).map(|(k, gi)| k * gi).sum::<f64>();
        }
    }
}

/// What the condensed assembly kept to recover the interior unknowns: W and g
/// of every cell ([`condense_element`]).
#[derive(Debug, Clone)]
pub struct InteriorRecovery {
    pub(super) split: LocalSplit,
    pub(super) keep: Vec<f64>,
    /// The cell of each of `keep`'s chunks, when they are not in the
    /// mesh's order (the products from the cells keep them in theirs).
    pub(super) order: Option<std::sync::Arc<[usize]>>,
}

impl InteriorRecovery {
    /// Fill the interior entries of `u` (free-dof numbering of `dofs`, the
    /// system ones already solved) from u_I = g − W u_B, with the prescribed
    /// dofs of u_B taken from `prescribed` (one value per dof).
    pub fn recover(&self, mesh: &HighOrderMesh, dofs: &DofMap, prescribed: &[f64], u: &mut [f64]) {
        let dim = mesh.dim();
        let (ni, nb) = (self.split.interior.len(), self.split.boundary.len());
        let known: &[f64] = u;
        let local = |c: usize, l: usize| mesh.cell(c)[l / dim] * dim + l % dim;
        // Per cell in parallel (reads only), then written in one pass.
        let mut interior = vec![0.0; self.keep.len() / self.split.stride() * ni];
        interior.par_chunks_mut(ni).zip(self.keep.par_chunks_exact(self.split.stride())).enumerate().for_each_init(
            || vec![0.0; nb],
            |ub, (k, (values, keep))| {
                let c = self.cell(k);
                for (v, &l) in ub.iter_mut().zip(&self.split.boundary) {
                    let dof = local(c, l);
                    *v = match dofs.free_index(dof) {
                        Some(f) => known[f],
                        None => prescribed[dof],
                    };
                }
                let (w, g) = keep.split_at(ni * nb);
                for ((v, g), w) in values.iter_mut().zip(g).zip(w.chunks_exact(nb)) {
                    *v = g - w.iter().zip(ub.iter()).map(|(a, b)| a * b).sum::<f64>();
                }
            },
        );
        for (k, values) in interior.chunks_exact(ni).enumerate() {
            let c = self.cell(k);
            for (&l, &v) in self.split.interior.iter().zip(values) {
                u[dofs.free_index(local(c, l)).expect("interior dofs are free")] = v;
            }
        }
    }

    /// The cell whose W and g are `keep`'s chunk k.
    fn cell(&self, k: usize) -> usize {
        self.order.as_ref().map_or(k, |o| o[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    /// A random symmetric positive definite n×n matrix (row-major).
    fn spd(n: usize, seed: &mut u64) -> Vec<f64> {
        let a: Vec<f64> = (0..n * n).map(|_| lcg(seed)).collect();
        let mut k = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                k[i * n + j] =
                    (0..n).map(|l| a[i * n + l] * a[j * n + l]).sum::<f64>() + if i == j { 0.5 } else { 0.0 };
            }
        }
        k
    }

    /// Dense solve by Gaussian elimination with partial pivoting (the reference).
    fn solve(n: usize, a: &[f64], b: &[f64]) -> Vec<f64> {
        let mut m: Vec<Vec<f64>> = (0..n).map(|i| a[i * n..(i + 1) * n].to_vec()).collect();
        let mut x = b.to_vec();
        for k in 0..n {
            let p = (k..n).max_by(|&i, &j| m[i][k].abs().total_cmp(&m[j][k].abs())).unwrap();
            m.swap(k, p);
            x.swap(k, p);
            for i in k + 1..n {
                let l = m[i][k] / m[k][k];
                for j in k..n {
                    m[i][j] -= l * m[k][j];
                }
                x[i] -= l * x[k];
            }
        }
        for i in (0..n).rev() {
            x[i] = (x[i] - (i + 1..n).map(|j| m[i][j] * x[j]).sum::<f64>()) / m[i][i];
        }
        x
    }

    #[test]
    fn the_avx2_copy_condenses_bitwise_as_the_portable_one() {
        // Four interior and five boundary unknowns of a random SPD matrix.
        let n = 9;
        let mut k = vec![0.0; n * n];
        for r in 0..n {
            for c in 0..n {
                k[r * n + c] = ((r * 7 + c * 3) % 11) as f64 / 11.0 + ((c * 7 + r * 3) % 11) as f64 / 11.0;
            }
            k[r * n + r] += 2.0 * n as f64;
        }
        let split = LocalSplit { interior: vec![1, 4, 6, 8], boundary: vec![0, 2, 3, 5, 7] };
        let (mut k1, mut k2) = (k.clone(), k.clone());
        let (mut r1, mut r2) = (vec![0.3; n], vec![0.3; n]);
        let (mut keep1, mut keep2) = (vec![0.0; 4 * 5 + 4], vec![0.0; 4 * 5 + 4]);
        condense_element(&split, &mut k1, Some(&mut r1), &mut keep1, &mut CondenseWorkspace::default()).unwrap();
        condense(&split, &mut k2, Some(&mut r2), &mut keep2, &mut CondenseWorkspace::default()).unwrap();
        let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        assert!(same(&k1, &k2) && same(&r1, &r2) && same(&keep1, &keep2));
        assert!(k1 != k);
    }

    #[test]
    fn condensed_solve_equals_the_full_solve_with_prescribed_boundary_dofs() {
        let mut seed = 7;
        // Interior dofs scattered among the boundary ones, as in a cell's local order.
        let split = LocalSplit { interior: vec![1, 4, 5, 9], boundary: vec![0, 2, 3, 6, 7, 8, 10, 11] };
        let n = 12;
        for indefinite in [false, true] {
            let mut k = spd(n, &mut seed);
            if indefinite {
                k[4 * n + 4] -= 40.0; // K_II indefinite but regular: needs the pivoting
            }
            let re: Vec<f64> = (0..n).map(|_| lcg(&mut seed)).collect();
            // Boundary dofs 0 and 7 prescribed, the others free.
            let fixed = [(0usize, 0.3), (7usize, -0.2)];
            let free: Vec<usize> = (0..n).filter(|d| fixed.iter().all(|f| f.0 != *d)).collect();
            // Reference: the full system on the free dofs with K_fd u_d moved right.
            let kff: Vec<f64> =
                free.iter().flat_map(|&r| free.iter().map(move |&c| (r, c))).map(|(r, c)| k[r * n + c]).collect();
            let bf: Vec<f64> =
                free.iter().map(|&r| -re[r] - fixed.iter().map(|&(d, v)| k[r * n + d] * v).sum::<f64>()).collect();
            let uf = solve(free.len(), &kff, &bf);
            let mut full = vec![0.0; n];
            fixed.iter().for_each(|&(d, v)| full[d] = v);
            free.iter().zip(&uf).for_each(|(&d, &v)| full[d] = v);
            // Condensed: the Schur system on the free boundary dofs, then the recovery.
            let (mut kc, mut rc) = (k.clone(), re.clone());
            let mut keep = vec![0.0; split.stride()];
            condense_element(&split, &mut kc, Some(&mut rc), &mut keep, &mut CondenseWorkspace::default()).unwrap();
            let fb: Vec<usize> = split.boundary.iter().copied().filter(|d| free.contains(d)).collect();
            let ks: Vec<f64> =
                fb.iter().flat_map(|&r| fb.iter().map(move |&c| (r, c))).map(|(r, c)| kc[r * n + c]).collect();
            let bs: Vec<f64> =
                fb.iter().map(|&r| -rc[r] - fixed.iter().map(|&(d, v)| kc[r * n + d] * v).sum::<f64>()).collect();
            let us = solve(fb.len(), &ks, &bs);
            let mut cond = vec![0.0; n];
            fixed.iter().for_each(|&(d, v)| cond[d] = v);
            fb.iter().zip(&us).for_each(|(&d, &v)| cond[d] = v);
            let (w, g) = keep.split_at(split.interior.len() * split.boundary.len());
            for (i, &d) in split.interior.iter().enumerate() {
                let nb = split.boundary.len();
                cond[d] = g[i] - (0..nb).map(|b| w[i * nb + b] * cond[split.boundary[b]]).sum::<f64>();
            }
            for d in 0..n {
                assert!(
                    (cond[d] - full[d]).abs() < 1e-10 * (1.0 + full[d].abs()),
                    "dof {d}: {} vs {}",
                    cond[d],
                    full[d]
                );
            }
            // The Schur complement of a symmetric matrix is symmetric.
            for &r in &split.boundary {
                for &c in &split.boundary {
                    assert!((kc[r * n + c] - kc[c * n + r]).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn boundary_dofs_first_condense_as_the_same_dofs_scattered() {
        // The native order (interior dofs last) takes the contiguous path;
        // the same matrix with its dofs scattered takes the indexed one.
        let mut seed = 11;
        let n = 10;
        let scattered = LocalSplit { interior: vec![2, 5, 9], boundary: vec![0, 1, 3, 4, 6, 7, 8] };
        let order: Vec<usize> = scattered.boundary.iter().chain(&scattered.interior).copied().collect();
        let native = LocalSplit { interior: vec![7, 8, 9], boundary: (0..7).collect() };
        let k = spd(n, &mut seed);
        let re: Vec<f64> = (0..n).map(|_| lcg(&mut seed)).collect();
        let (mut ks, mut rs) = (k.clone(), re.clone());
        let mut kn: Vec<f64> = (0..n * n).map(|e| k[order[e / n] * n + order[e % n]]).collect();
        let mut rn: Vec<f64> = order.iter().map(|&d| re[d]).collect();
        let (mut keep_s, mut keep_n) = (vec![0.0; scattered.stride()], vec![0.0; native.stride()]);
        let ws = &mut CondenseWorkspace::default();
        condense_element(&scattered, &mut ks, Some(&mut rs), &mut keep_s, ws).unwrap();
        condense_element(&native, &mut kn, Some(&mut rn), &mut keep_n, ws).unwrap();
        assert_eq!(keep_s, keep_n);
        for (b, &r) in scattered.boundary.iter().enumerate() {
            assert_eq!(rs[r], rn[b]);
            for (c, &s) in scattered.boundary.iter().enumerate() {
                assert_eq!(ks[r * n + s], kn[b * n + c], "Schur complement ({b}, {c})");
            }
        }
        assert_ne!(kn[0], k[0]);
    }

    #[test]
    fn a_singular_interior_block_is_reported() {
        let split = LocalSplit { interior: vec![0, 1], boundary: vec![2] };
        let mut k = vec![1.0, 2.0, 0.5, 2.0, 4.0, 0.1, 0.5, 0.1, 3.0];
        let mut keep = vec![0.0; split.stride()];
        assert!(condense_element(&split, &mut k, None, &mut keep, &mut CondenseWorkspace::default()).is_err());
    }
}
