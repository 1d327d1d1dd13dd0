//! Small dense matrices: 2×2 and 3×3 blocks stored as 3×3, with their
//! determinant, cofactor, inverse and product. The element maps, the
//! materials and the optimisation energy share them.

/// A small square matrix stored as 3×3; in 2D only the leading 2×2 block is used.
pub type Mat3 = [[f64; 3]; 3];

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
}
