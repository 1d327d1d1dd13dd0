//! The reference → physical map of one element and its derivatives: the
//! Jacobian matrix ∂x/∂ξ, its determinant and inverse, physical gradients of
//! the basis, and the deformation gradient F between two configurations.
//! Pure pointwise algebra; no mesh storage.

use crate::linalg::Mat3;
use crate::quadrature::QuadratureRule;
use crate::reference::LagrangeBasis;

/// Reference basis gradients tabulated at the quadrature points, shared by
/// every element of one order.
#[derive(Debug, Clone)]
pub struct ElementCache {
    pub dim: usize,
    pub n_basis: usize,
    pub weights: Vec<f64>,
    /// `ref_grads[(q * n_basis + a) * dim + j]` = ∂N_a/∂ξ_j at point q.
    pub ref_grads: Vec<f64>,
    /// `values[q * n_basis + a]` = N_a at point q.
    pub values: Vec<f64>,
    /// The gradients again, the points innermost ([`PointGradients`]).
    pub by_point: PointGradients,
}

impl ElementCache {
    pub fn new(basis: &LagrangeBasis, rule: &QuadratureRule) -> ElementCache {
        let tab = basis.tabulate(&rule.points);
        ElementCache {
            dim: tab.dim,
            n_basis: tab.n_basis,
            weights: rule.weights.clone(),
            by_point: PointGradients::new(tab.dim, tab.n_basis, &tab.grads),
            ref_grads: tab.grads,
            values: tab.values,
        }
    }
    /// Basis values and gradients at arbitrary `points`, without weights
    /// (for sampling, e.g. quality measures).
    pub fn at_points(basis: &LagrangeBasis, points: &[[f64; 3]]) -> ElementCache {
        let tab = basis.tabulate(points);
        ElementCache {
            dim: tab.dim,
            n_basis: tab.n_basis,
            weights: vec![0.0; points.len()],
            by_point: PointGradients::new(tab.dim, tab.n_basis, &tab.grads),
            ref_grads: tab.grads,
            values: tab.values,
        }
    }
    pub fn n_points(&self) -> usize {
        self.weights.len()
    }
    /// Reference gradients of all basis functions at point `q`.
    #[inline]
    pub fn grads_at(&self, q: usize) -> &[f64] {
        let s = self.n_basis * self.dim;
        &self.ref_grads[q * s..(q + 1) * s]
    }
}

/// Reference gradients of the basis at a set of points, laid out
/// `[(a * dim + j) * n_points + q]` = ∂N_a/∂ξ_j at point q: the points
/// innermost, so that sums over the nodes run in SIMD lanes over the points.
#[derive(Debug, Clone)]
pub struct PointGradients {
    pub dim: usize,
    pub n_basis: usize,
    n_points: usize,
    grads: Vec<f64>,
}

/// Points whose sums [`PointGradients::jacobians_into`] keeps in registers at once.
const POINT_CHUNK: usize = 8;

impl PointGradients {
    /// From gradients laid out as [`crate::reference::Tabulation::grads`]
    /// (`(q * n_basis + a) * dim + j`).
    pub fn new(dim: usize, n_basis: usize, grads: &[f64]) -> PointGradients {
        let n_points = grads.len() / (n_basis * dim).max(1);
        let mut by_point = vec![0.0; grads.len()];
        for (q, at_point) in grads.chunks_exact(n_basis * dim).enumerate() {
            for (aj, &g) in at_point.iter().enumerate() {
                by_point[aj * n_points + q] = g;
            }
        }
        PointGradients { dim, n_basis, n_points, grads: by_point }
    }

    pub fn n_points(&self) -> usize {
        self.n_points
    }

    /// ∂N_a/∂ξ_j at every point.
    #[inline(always)]
    pub fn of(&self, a: usize, j: usize) -> &[f64] {
        &self.grads[(a * self.dim + j) * self.n_points..][..self.n_points]
    }

    /// ∂x/∂ξ at every point of the element with node coordinates `xe`
    /// (`D` per node) into `out[(i * D + j) * n_points + q]` = Σ_a x_a,i
    /// ∂N_a/∂ξ_j: [`POINT_CHUNK`] points at a time, the D sums of a
    /// direction j held in registers over the nodes. Each sum runs over a
    /// in increasing order from zero, as [`jacobian`] takes it, so the
    /// entries are bitwise those of [`jacobian`] at each point.
    #[inline(always)]
    pub fn jacobians_into<const D: usize>(&self, xe: &[f64], out: &mut Vec<f64>) {
        const L: usize = POINT_CHUNK;
        let (nq, n) = (self.n_points, self.n_basis);
        out.clear();
        out.resize(D * D * nq, 0.0);
        let full = nq - nq % L;
        for j in 0..D {
            for q0 in (0..full).step_by(L) {
                let mut acc = [[0.0; L]; D];
                for (a, xa) in xe[..n * D].chunks_exact(D).enumerate() {
                    let g = &self.grads[(a * D + j) * nq + q0..][..L];
                    for (acc, &x) in acc.iter_mut().zip(xa) {
                        for l in 0..L {
                            acc[l] += x * g[l];
                        }
                    }
                }
                for (i, acc) in acc.iter().enumerate() {
                    out[(i * D + j) * nq + q0..][..L].copy_from_slice(acc);
                }
            }
            for q in full..nq {
                for i in 0..D {
                    let mut v = 0.0;
                    for a in 0..n {
                        v += xe[a * D + i] * self.grads[(a * D + j) * nq + q];
                    }
                    out[(i * D + j) * nq + q] = v;
                }
            }
        }
    }
}

/// ∂x/∂ξ at point q of `jac`, laid out as [`PointGradients::jacobians_into`]
/// writes it for `nq` points.
#[inline(always)]
pub fn jacobian_at<const D: usize>(jac: &[f64], nq: usize, q: usize) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate().take(D) {
        for (j, v) in row.iter_mut().enumerate().take(D) {
            *v = jac[(i * D + j) * nq + q];
        }
    }
    m
}

/// ∂x/∂ξ at one point: `J[i][j] = Σ_a x[a*dim+i] · grads[a*dim+j]`, where
/// `grads[a*dim+j] = ∂N_a/∂ξ_j`.
#[inline]
pub fn jacobian(dim: usize, x: &[f64], grads: &[f64]) -> Mat3 {
    match dim {
        2 => jacobian_in::<2>(x, grads),
        _ => jacobian_in::<3>(x, grads),
    }
}

/// [`jacobian`] in dimension `D`, its loops unrolled.
#[inline(always)]
pub fn jacobian_in<const D: usize>(x: &[f64], grads: &[f64]) -> Mat3 {
    let mut j = [[0.0; 3]; 3];
    for (xa, ga) in x.chunks_exact(D).zip(grads.chunks_exact(D)) {
        for r in 0..D {
            for c in 0..D {
                j[r][c] += xa[r] * ga[c];
            }
        }
    }
    j
}

/// Physical gradients: `out[a*dim+i] = Σ_j ∂N_a/∂ξ_j (J⁻¹)_{j i}`.
#[inline]
pub fn physical_gradients_into(dim: usize, ref_grads: &[f64], jinv: &Mat3, out: &mut [f64]) {
    let n = ref_grads.len() / dim;
    for a in 0..n {
        let g = &ref_grads[a * dim..(a + 1) * dim];
        for i in 0..dim {
            out[a * dim + i] = (0..dim).map(|j| g[j] * jinv[j][i]).sum();
        }
    }
}

/// Jacobian ∂X/∂ξ of the straight (affine) simplex with vertices `xv`.
pub fn affine_jacobian(dim: usize, xv: &[[f64; 3]]) -> Mat3 {
    let mut j = [[0.0; 3]; 3];
    for r in 0..dim {
        for c in 0..dim {
            j[r][c] = xv[c + 1][r] - xv[0][r];
        }
    }
    j
}

/// The inverse and the determinant of [`affine_jacobian`] for the straight
/// simplex whose vertices are the first dim + 1 nodes of `xs` (`dim`
/// coordinates each); the inverse is meaningless where the determinant is
/// zero.
pub fn straight_inverse(dim: usize, xs: &[f64]) -> (Mat3, f64) {
    let mut xv = [[0.0; 3]; 4];
    for (a, v) in xv.iter_mut().enumerate().take(dim + 1) {
        v[..dim].copy_from_slice(&xs[a * dim..(a + 1) * dim]);
    }
    crate::linalg::inverse(dim, &affine_jacobian(dim, &xv[..=dim]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_of_affine_map_from_linear_basis() {
        // Linear basis on the triangle: N0 = 1 - x - y, N1 = x, N2 = y.
        let grads = [-1.0, -1.0, 1.0, 0.0, 0.0, 1.0];
        let x = [1.0, 1.0, 3.0, 1.0, 1.0, 4.0];
        let j = jacobian(2, &x, &grads);
        assert_eq!(j[0][0], 2.0);
        assert_eq!(j[1][1], 3.0);
        assert_eq!(j[0][1], 0.0);
        assert_eq!(j[1][0], 0.0);
        let xv = [[1.0, 1.0, 0.0], [3.0, 1.0, 0.0], [1.0, 4.0, 0.0]];
        assert_eq!(affine_jacobian(2, &xv), j);
    }
}
