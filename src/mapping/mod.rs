//! The reference → physical map of one element and its derivatives: the
//! Jacobian matrix ∂x/∂ξ, its determinant and inverse, physical gradients of
//! the basis, and the deformation gradient F between two configurations.
//! Pure pointwise algebra; no mesh storage.

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
}

impl ElementCache {
    pub fn new(basis: &LagrangeBasis, rule: &QuadratureRule) -> ElementCache {
        let tab = basis.tabulate(&rule.points);
        ElementCache {
            dim: tab.dim,
            n_basis: tab.n_basis,
            weights: rule.weights.clone(),
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

/// A small square matrix stored as 3×3; in 2D only the leading 2×2 block is used.
pub type Mat3 = [[f64; 3]; 3];

/// ∂x/∂ξ at one point: `J[i][j] = Σ_a x[a*dim+i] · grads[a*dim+j]`, where
/// `grads[a*dim+j] = ∂N_a/∂ξ_j`.
#[inline]
pub fn jacobian(dim: usize, x: &[f64], grads: &[f64]) -> Mat3 {
    let mut j = [[0.0; 3]; 3];
    let n = grads.len() / dim;
    for a in 0..n {
        for r in 0..dim {
            let xa = x[a * dim + r];
            for c in 0..dim {
                j[r][c] += xa * grads[a * dim + c];
            }
        }
    }
    j
}

/// Determinant of the leading `dim`×`dim` block.
#[inline]
pub fn det(dim: usize, m: &Mat3) -> f64 {
    if dim == 2 {
        m[0][0] * m[1][1] - m[0][1] * m[1][0]
    } else {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }
}

/// Cofactor matrix of the leading block: cof(M) = det(M) M⁻ᵀ (defined for any M).
#[inline]
pub fn cofactor(dim: usize, m: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    if dim == 2 {
        c[0][0] = m[1][1];
        c[0][1] = -m[1][0];
        c[1][0] = -m[0][1];
        c[1][1] = m[0][0];
    } else {
        for i in 0..3 {
            for j in 0..3 {
                let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
                let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
                c[i][j] = m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1];
            }
        }
    }
    c
}

/// Inverse and determinant of the leading block. The inverse is meaningless
/// when the determinant is zero; callers check it.
#[inline]
pub fn inverse(dim: usize, m: &Mat3) -> (Mat3, f64) {
    let d = det(dim, m);
    let c = cofactor(dim, m);
    let mut inv = [[0.0; 3]; 3];
    for i in 0..dim {
        for j in 0..dim {
            inv[i][j] = c[j][i] / d;
        }
    }
    (inv, d)
}

/// Product of the leading blocks.
#[inline]
pub fn matmul(dim: usize, a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..dim {
        for j in 0..dim {
            c[i][j] = (0..dim).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_times_matrix_is_identity_in_2d_and_3d() {
        let m: Mat3 = [[2.0, 0.3, -0.1], [0.2, 1.5, 0.4], [-0.3, 0.1, 1.1]];
        for dim in [2, 3] {
            let (inv, d) = inverse(dim, &m);
            assert!(d.abs() > 0.1);
            let id = matmul(dim, &m, &inv);
            for i in 0..dim {
                for j in 0..dim {
                    let e = if i == j { 1.0 } else { 0.0 };
                    assert!((id[i][j] - e).abs() < 1e-14, "{dim} {i} {j} {}", id[i][j]);
                }
            }
        }
    }

    #[test]
    fn cofactor_is_det_times_inverse_transpose() {
        let m: Mat3 = [[1.0, 2.0, 0.5], [0.0, 1.0, -1.0], [3.0, 0.2, 2.0]];
        let (inv, d) = inverse(3, &m);
        let c = cofactor(3, &m);
        for i in 0..3 {
            for j in 0..3 {
                assert!((c[i][j] - d * inv[j][i]).abs() < 1e-13);
            }
        }
    }

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
