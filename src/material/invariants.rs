//! σ and c of any strain energy written in the invariants
//! v = (I1, I2, J, I4, I5) of C = FᵀF (paper eq. (16)–(19)):
//! I1 = tr C = F:F, I2 = tr cof C = H:H = ½(I1² − tr C²), J = √det C,
//! I4 = N·CN = FN·FN, I5 = N·C²N = FᵀFN·FᵀFN.
//!
//! # Derivation (used for NI-MR and TI, checked against NH and MR)
//!
//! With Ψ_a = ∂Ψ/∂v_a and Ψ_ab = ∂²Ψ/∂v_a∂v_b,
//! S = 2 ∂Ψ/∂C = 2 Σ_a Ψ_a ∂v_a/∂C and (eq. (7))
//! 𝒞 = 4 ∂²Ψ/∂C∂C = 4 [Σ_ab Ψ_ab ∂v_a/∂C ⊗ ∂v_b/∂C + Σ_a Ψ_a ∂²v_a/∂C∂C].
//!
//! First derivatives (symmetric 2-tensors in the material frame):
//! ∂I1/∂C = I, ∂I2/∂C = I1 I − C, ∂J/∂C = ½ J C⁻¹, ∂I4/∂C = N⊗N,
//! ∂I5/∂C = N⊗CN + CN⊗N.
//!
//! Second derivatives (from the second directional derivatives for symmetric
//! increments dC₁, dC₂, then symmetrised in IJ and KL):
//! - I1, I4: zero;
//! - I2: D²I2 = tr dC₁ tr dC₂ − tr(dC₁dC₂) ⇒ I⊗I − ½(δ_IK δ_JL + δ_IL δ_JK);
//! - J: D²J = ¼J (C⁻¹:dC₁)(C⁻¹:dC₂) − ½J tr(C⁻¹dC₁C⁻¹dC₂)
//!   ⇒ ¼J C⁻¹⊗C⁻¹ − ¼J (C⁻¹_IK C⁻¹_JL + C⁻¹_IL C⁻¹_JK);
//! - I5: D²I5 = N·(dC₁dC₂ + dC₂dC₁)N = 2 dC₁N·dC₂N
//!   ⇒ ½(δ_IK N_J N_L + δ_JK N_I N_L + δ_IL N_J N_K + δ_JL N_I N_K).
//!
//! Push-forward A ↦ F A Fᵀ (σ = J⁻¹ F S Fᵀ, eq. (8); c by eq. (10)) maps
//! I ↦ b = FFᵀ, C ↦ b², C⁻¹ ↦ I, N ↦ a = FN, CN ↦ F C N = b a, and in
//! fourth-order terms δ_IK ↦ b_ik, C⁻¹_IK ↦ δ_ik. Hence, with
//! G_1 = b, G_2 = I1 b − b², G_J = ½J I, G_4 = a⊗a, G_5 = a⊗ba + ba⊗a:
//!
//! ```text
//! σ = (2/J) Σ_a Ψ_a G_a,
//!
//! c_ijkl = (4/J) [ Σ_ab Ψ_ab (G_a)_ij (G_b)_kl
//!        + Ψ_2 (b_ij b_kl − ½(b_ik b_jl + b_il b_jk))
//!        + Ψ_J ¼J (δ_ij δ_kl − δ_ik δ_jl − δ_il δ_jk)
//!        + Ψ_5 ½(b_ik a_j a_l + b_jk a_i a_l + b_il a_j a_k + b_jl a_i a_k) ].
//! ```
//!
//! At F = I a model is stress-free iff Ψ_1 + 2Ψ_2 + ½Ψ_J = 0 (isotropic part),
//! and its isotropic tangent then has μ = 2Ψ_1 + 2Ψ_2,
//! λ = 4[Ψ_11 + 4Ψ_22 + ¼Ψ_JJ + 4Ψ_12 + Ψ_1J + 2Ψ_2J + Ψ_2 + ¼Ψ_J].

use super::tensor::{delta, dot3, matvec, transpose, ZERO_TANGENT};
use super::Tangent;
use crate::linalg::{cofactor, det, matmul, Mat3};

/// Index of each invariant in the derivative arrays.
pub(crate) const I1: usize = 0;
pub(crate) const I2: usize = 1;
pub(crate) const JAC: usize = 2;
pub(crate) const I4: usize = 3;
pub(crate) const I5: usize = 4;

/// The invariants (I1, I2, J, I4, I5) of one deformation gradient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Invariants {
    pub i1: f64,
    pub i2: f64,
    pub j: f64,
    pub i4: f64,
    pub i5: f64,
}

impl Invariants {
    /// Straight from the definitions: I1 = F:F, I2 = H:H with H = cof F,
    /// J = det F, I4 = FN·FN, I5 = FᵀFN·FᵀFN.
    pub fn of(f: &Mat3, fibre: &[f64; 3]) -> Invariants {
        let h = cofactor(3, f);
        let sq = |m: &Mat3| -> f64 { m.iter().flatten().map(|x| x * x).sum() };
        let (i4, i5) = anisotropic_invariants(f, fibre);
        Invariants { i1: sq(f), i2: sq(&h), j: det(3, f), i4, i5 }
    }
}

/// I4 = FN·FN and I5 = FᵀFN·FᵀFN (paper eq. (19); quality measures Q4, Q5).
pub fn anisotropic_invariants(f: &Mat3, fibre: &[f64; 3]) -> (f64, f64) {
    let a = matvec(f, fibre);
    let fta = matvec(&transpose(f), &a);
    (dot3(&a, &a), dot3(&fta, &fta))
}

/// A strain energy Ψ(I1, I2, J, I4, I5).
pub(crate) trait InvariantEnergy {
    fn psi(&self, v: &Invariants) -> f64;
    /// ∂Ψ/∂v_a and ∂²Ψ/∂v_a∂v_b in the order (I1, I2, J, I4, I5).
    fn derivatives(&self, v: &Invariants) -> ([f64; 5], [[f64; 5]; 5]);
    /// False for isotropic energies (skips the fibre terms).
    const ANISOTROPIC: bool;
}

/// The spatial quantities the push-forward needs.
struct Spatial {
    b: Mat3,
    a: [f64; 3],
    inv: Invariants,
    /// G_a of the module documentation.
    g: [Mat3; 5],
}

fn spatial(f: &Mat3, fibre: &[f64; 3], anisotropic: bool) -> Spatial {
    let b = matmul(3, f, &transpose(f));
    let b2 = matmul(3, &b, &b);
    let j = det(3, f);
    let i1 = b[0][0] + b[1][1] + b[2][2];
    let i2 = 0.5 * (i1 * i1 - (b2[0][0] + b2[1][1] + b2[2][2]));
    let (a, ba) = if anisotropic {
        let a = matvec(f, fibre);
        (a, matvec(&b, &a))
    } else {
        ([0.0; 3], [0.0; 3])
    };
    let mut g = [[[0.0; 3]; 3]; 5];
    for p in 0..3 {
        for q in 0..3 {
            g[I1][p][q] = b[p][q];
            g[I2][p][q] = i1 * b[p][q] - b2[p][q];
            g[JAC][p][q] = 0.5 * j * delta(p, q);
            g[I4][p][q] = a[p] * a[q];
            g[I5][p][q] = a[p] * ba[q] + ba[p] * a[q];
        }
    }
    Spatial { b, a, inv: Invariants { i1, i2, j, i4: dot3(&a, &a), i5: dot3(&a, &ba) }, g }
}

fn cauchy(s: &Spatial, d1: &[f64; 5]) -> Mat3 {
    let mut sigma = [[0.0; 3]; 3];
    let k = 2.0 / s.inv.j;
    for p in 0..3 {
        for q in 0..3 {
            sigma[p][q] = k * (0..5).map(|a| d1[a] * s.g[a][p][q]).sum::<f64>();
        }
    }
    sigma
}

/// σ = (2/J) Σ_a Ψ_a G_a.
pub(crate) fn invariant_stress<M: InvariantEnergy>(m: &M, f: &Mat3, fibre: &[f64; 3]) -> Mat3 {
    let s = spatial(f, fibre, M::ANISOTROPIC);
    let (d1, _) = m.derivatives(&s.inv);
    cauchy(&s, &d1)
}

/// σ and c of the module documentation.
pub(crate) fn invariant_stress_and_tangent<M: InvariantEnergy>(m: &M, f: &Mat3, fibre: &[f64; 3]) -> (Mat3, Tangent) {
    let s = spatial(f, fibre, M::ANISOTROPIC);
    let (d1, d2) = m.derivatives(&s.inv);
    let sigma = cauchy(&s, &d1);
    let (b, a, j) = (&s.b, &s.a, s.inv.j);
    let k = 4.0 / j;
    // Only the non-zero second derivatives (most models have a few).
    let mut active = [(0usize, 0usize, 0.0f64); 25];
    let mut n_active = 0;
    for p in 0..5 {
        for q in 0..5 {
            if d2[p][q] != 0.0 {
                active[n_active] = (p, q, d2[p][q]);
                n_active += 1;
            }
        }
    }
    let active = &active[..n_active];
    let mut c = ZERO_TANGENT;
    for i in 0..3 {
        for jj in 0..3 {
            for kk in 0..3 {
                for l in 0..3 {
                    let mut v: f64 = active.iter().map(|&(p, q, h)| h * s.g[p][i][jj] * s.g[q][kk][l]).sum();
                    v += d1[I2] * (b[i][jj] * b[kk][l] - 0.5 * (b[i][kk] * b[jj][l] + b[i][l] * b[jj][kk]));
                    v += d1[JAC]
                        * 0.25
                        * j
                        * (delta(i, jj) * delta(kk, l) - delta(i, kk) * delta(jj, l) - delta(i, l) * delta(jj, kk));
                    if M::ANISOTROPIC {
                        v += d1[I5]
                            * 0.5
                            * (b[i][kk] * a[jj] * a[l]
                                + b[jj][kk] * a[i] * a[l]
                                + b[i][l] * a[jj] * a[kk]
                                + b[jj][l] * a[i] * a[kk]);
                    }
                    c[i][jj][kk][l] = k * v;
                }
            }
        }
    }
    (sigma, c)
}

/// `impl Material` for an energy whose stress and tangent come from its
/// invariants alone ([`invariant_stress`], [`invariant_stress_and_tangent`]).
macro_rules! material_from_invariants {
    ($model:ty, $name:literal) => {
        impl $crate::material::Material for $model {
            fn name(&self) -> &'static str {
                $name
            }
            fn energy(&self, f: &$crate::linalg::Mat3, fibre: &[f64; 3]) -> f64 {
                $crate::material::invariants::InvariantEnergy::psi(
                    self,
                    &$crate::material::invariants::Invariants::of(f, fibre),
                )
            }
            fn stress(&self, f: &$crate::linalg::Mat3, fibre: &[f64; 3]) -> $crate::linalg::Mat3 {
                $crate::material::invariants::invariant_stress(self, f, fibre)
            }
            fn stress_and_tangent(
                &self,
                f: &$crate::linalg::Mat3,
                fibre: &[f64; 3],
            ) -> ($crate::linalg::Mat3, $crate::material::Tangent) {
                $crate::material::invariants::invariant_stress_and_tangent(self, f, fibre)
            }
        }
    };
}
pub(crate) use material_from_invariants;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invariants_from_definitions_match_the_spatial_ones() {
        let f = [[1.2, 0.3, -0.1], [0.05, 0.9, 0.2], [0.1, -0.2, 1.1]];
        let n = [0.6, 0.0, 0.8];
        let direct = Invariants::of(&f, &n);
        let s = spatial(&f, &n, true);
        for (x, y) in [
            (direct.i1, s.inv.i1),
            (direct.i2, s.inv.i2),
            (direct.j, s.inv.j),
            (direct.i4, s.inv.i4),
            (direct.i5, s.inv.i5),
        ] {
            assert!((x - y).abs() < 1e-13 * x.abs().max(1.0), "{x} {y}");
        }
        // Plane strain (F33 = 1): I1 = |F₂|² + 1 and I2 = |F₂|² + J².
        let p = [[1.1, 0.2, 0.0], [-0.1, 0.8, 0.0], [0.0, 0.0, 1.0]];
        let v = Invariants::of(&p, &[1.0, 0.0, 0.0]);
        let j2 = v.j * v.j;
        let f22: f64 = (0..2).flat_map(|i| (0..2).map(move |k| (i, k))).map(|(i, k)| p[i][k] * p[i][k]).sum();
        assert!((v.i1 - (f22 + 1.0)).abs() < 1e-14);
        assert!((v.i2 - (f22 + j2)).abs() < 1e-14);
    }
}
