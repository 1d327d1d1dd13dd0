//! Small tensor helpers shared by the models: Kronecker delta, the isotropic
//! fourth-order tensors, double contraction and the small strain of F.

use super::Tangent;
use crate::linalg::Mat3;

pub(crate) const ZERO_TANGENT: Tangent = [[[[0.0; 3]; 3]; 3]; 3];

/// δ_ij.
#[inline]
pub(crate) fn delta(i: usize, j: usize) -> f64 {
    if i == j {
        1.0
    } else {
        0.0
    }
}

/// λ I⊗I + μ 𝓘, i.e. c_ijkl = λ δ_ij δ_kl + μ (δ_ik δ_jl + δ_il δ_jk).
pub(crate) fn isotropic_tangent(lambda: f64, mu: f64) -> Tangent {
    let mut c = ZERO_TANGENT;
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                for l in 0..3 {
                    c[i][j][k][l] = lambda * delta(i, j) * delta(k, l)
                        + mu * (delta(i, k) * delta(j, l) + delta(i, l) * delta(j, k));
                }
            }
        }
    }
    c
}

/// (c:ε)_ij = c_ijkl ε_kl.
pub(crate) fn contract(c: &Tangent, e: &Mat3) -> Mat3 {
    let mut s = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let mut acc = 0.0;
            for k in 0..3 {
                for l in 0..3 {
                    acc += c[i][j][k][l] * e[k][l];
                }
            }
            s[i][j] = acc;
        }
    }
    s
}

/// Small strain of F: ε = ½(F + Fᵀ) − I.
pub(crate) fn small_strain(f: &Mat3) -> Mat3 {
    let mut e = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            e[i][j] = 0.5 * (f[i][j] + f[j][i]) - delta(i, j);
        }
    }
    e
}

/// A:B = A_ij B_ij.
#[inline]
pub(crate) fn ddot(a: &Mat3, b: &Mat3) -> f64 {
    (0..3).map(|i| (0..3).map(|j| a[i][j] * b[i][j]).sum::<f64>()).sum()
}

/// Transpose.
#[inline]
pub(crate) fn transpose(a: &Mat3) -> Mat3 {
    let mut t = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            t[i][j] = a[j][i];
        }
    }
    t
}

/// M v.
#[inline]
pub(crate) fn matvec(m: &Mat3, v: &[f64; 3]) -> [f64; 3] {
    let mut r = [0.0; 3];
    for i in 0..3 {
        r[i] = (0..3).map(|j| m[i][j] * v[j]).sum();
    }
    r
}

/// u·v.
#[inline]
pub(crate) fn dot3(u: &[f64; 3], v: &[f64; 3]) -> f64 {
    u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
}
