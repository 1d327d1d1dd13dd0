//! Transversely isotropic hyperelastic model of Bonet & Burton (paper Table 2),
//! fibre direction N:
//! ```text
//! Ψ = α(I1 − 3) + β(I2 − 3) − μ̃ ln J + λ/2 (J − 1)² + η1(I4 − 1)
//!   + η2(I1 − 3)(I4 − 1) + γ(I4 − 1)² − η1/2 (I5 − 1),
//! ```
//! with I4 = FN·FN and I5 = FᵀFN·FᵀFN.
//!
//! # Derivation
//! From the invariant derivation of `invariants.rs`, with a = FN:
//! Ψ_1 = α + η2(I4 − 1), Ψ_2 = β, Ψ_J = λ(J − 1) − μ̃/J,
//! Ψ_4 = η1 + η2(I1 − 3) + 2γ(I4 − 1), Ψ_5 = −η1/2;
//! Ψ_JJ = λ + μ̃/J², Ψ_14 = η2, Ψ_44 = 2γ (all others zero). Hence
//!
//! ```text
//! σ = (2/J)[(α + η2(I4 − 1)) b + β(I1 b − b²) + (η1 + η2(I1 − 3) + 2γ(I4 − 1)) a⊗a
//!     − (η1/2)(a⊗ba + ba⊗a)] + (λ(J − 1) − μ̃/J) I,
//!
//! c_ijkl = (2β/J)(2 b_ij b_kl − b_ik b_jl − b_il b_jk) + λ(2J − 1) δ_ij δ_kl
//!        + (μ̃/J − λ(J − 1)) 𝓘_ijkl + (4η2/J)(b_ij a_k a_l + a_i a_j b_kl)
//!        + (8γ/J) a_i a_j a_k a_l − (η1/J)(b_ik a_j a_l + b_jk a_i a_l + b_il a_j a_k + b_jl a_i a_k).
//! ```
//!
//! # Calibration
//! At F = I (N = e3): σ = 0 iff μ̃ = 2α + 4β; C11 = 4α + 8β + λ, C12 = 4β + λ,
//! C13 = 4β + λ + 4η2, C33 = 4α + 8β + λ − 4η1 + 8η2 + 8γ, C44 = G_A = 2α + 2β − η1,
//! C66 = 2α + 2β. With α = β = C66/4 (= E/(8(1+ν))): λ = C11 − 12α,
//! η1 = 4α − G_A, 4η2 = C13 − 4α − λ, 8γ = C33 − 12α + 4η1 − 8η2 − λ, where the
//! C's invert the TI compliance ([`super::TiEngineeringConstants::try_stiffness`]).
//! For the paper's E_A = 5E/2, ν_A = ν, G_A = E/2 (E = 1):
//!
//! | ν | α = β | λ | η1 | η2 | γ |
//! |---|---|---|---|---|---|
//! | 0.001 | 0.1249 | −0.4985 | −0.0005 | +0.0000 | +0.1873 |
//! | 0.3 | 0.0962 | +0.0269 | −0.1154 | +0.0165 | +0.1265 |
//! | 0.495 | 0.0836 | +0.9493 | −0.1656 | +0.0796 | +0.1043 |
//!
//! η1 = E/(2(1+ν)) − E/2 ≤ 0 always, and **λ < 0 for ν < 0.2888**. The
//! linearisation is still exactly the positive definite TI tensor, so small
//! strains are fine, but with λ < 0 the volumetric term λ/2 (J − 1)² is
//! concave: Ψ_JJ = λ + μ̃/J² turns negative for J > √(μ̃/|λ|) (≈ 1.22 at
//! ν → 0) and Ψ → −∞ as J → ∞. Together with the non-polyconvex I5 term
//! (paper section 6) the model can lose ellipticity at large deformation.

use super::invariants::{material_from_invariants, InvariantEnergy, Invariants, I1, I2, I4, I5, JAC};
use super::TiStiffness;

/// Constants of the Bonet–Burton transversely isotropic model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransverselyIsotropic {
    pub alpha: f64,
    pub beta: f64,
    pub mu_tilde: f64,
    pub lambda: f64,
    pub eta1: f64,
    pub eta2: f64,
    pub gamma: f64,
}

impl TransverselyIsotropic {
    /// The calibration of the module documentation (α = β).
    pub fn from_stiffness(s: &TiStiffness) -> TransverselyIsotropic {
        let alpha = 0.25 * s.c66;
        let beta = alpha;
        let lambda = s.c11 - 12.0 * alpha;
        let eta1 = 4.0 * alpha - s.c44;
        let eta2 = 0.25 * (s.c13 - 4.0 * alpha - lambda);
        let gamma = (s.c33 - 12.0 * alpha + 4.0 * eta1 - 8.0 * eta2 - lambda) / 8.0;
        TransverselyIsotropic { alpha, beta, mu_tilde: 2.0 * alpha + 4.0 * beta, lambda, eta1, eta2, gamma }
    }
}

impl InvariantEnergy for TransverselyIsotropic {
    const ANISOTROPIC: bool = true;
    fn psi(&self, v: &Invariants) -> f64 {
        let (e1, e4) = (v.i1 - 3.0, v.i4 - 1.0);
        self.alpha * e1 + self.beta * (v.i2 - 3.0) - self.mu_tilde * v.j.ln()
            + 0.5 * self.lambda * (v.j - 1.0).powi(2)
            + self.eta1 * e4
            + self.eta2 * e1 * e4
            + self.gamma * e4 * e4
            - 0.5 * self.eta1 * (v.i5 - 1.0)
    }
    fn derivatives(&self, v: &Invariants) -> ([f64; 5], [[f64; 5]; 5]) {
        let (e1, e4) = (v.i1 - 3.0, v.i4 - 1.0);
        let mut d1 = [0.0; 5];
        let mut d2 = [[0.0; 5]; 5];
        d1[I1] = self.alpha + self.eta2 * e4;
        d1[I2] = self.beta;
        d1[JAC] = self.lambda * (v.j - 1.0) - self.mu_tilde / v.j;
        d1[I4] = self.eta1 + self.eta2 * e1 + 2.0 * self.gamma * e4;
        d1[I5] = -0.5 * self.eta1;
        d2[JAC][JAC] = self.lambda + self.mu_tilde / (v.j * v.j);
        d2[I1][I4] = self.eta2;
        d2[I4][I1] = self.eta2;
        d2[I4][I4] = 2.0 * self.gamma;
        (d1, d2)
    }
}

material_from_invariants!(TransverselyIsotropic, "transversely-isotropic");

#[cfg(test)]
mod tests {
    use super::super::tensor::{delta, transpose};
    use super::super::testing::*;
    use super::super::ti_linear::tests::engineering_from_tangent;
    use super::super::{make_material, Material, MaterialModel, TiEngineeringConstants};
    use super::*;
    use crate::linalg::{det, matmul};

    fn model(nu: f64) -> (TransverselyIsotropic, TiStiffness) {
        let s = TiEngineeringConstants::paper_default(1.0, nu).try_stiffness().unwrap();
        (TransverselyIsotropic::from_stiffness(&s), s)
    }

    #[test]
    fn transversely_isotropic_stress_matches_fd_of_energy() {
        for nu in [0.001, 0.3, 0.495] {
            assert_stress_matches_fd_of_energy(&model(nu).0, 61);
        }
    }

    #[test]
    fn transversely_isotropic_tangent_matches_fd_of_stress() {
        for nu in [0.001, 0.3, 0.495] {
            assert_tangent_matches_fd_of_stress(&model(nu).0, 62);
        }
    }

    #[test]
    fn transversely_isotropic_tangent_at_identity_equals_linear_tensor() {
        let mut rng = Rng::new(63);
        for nu in POISSON_SWEEP {
            let (m, s) = model(nu);
            for n in [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], random_unit(&mut rng, false), random_unit(&mut rng, true)] {
                assert_tangent_at_identity(&m, &n, &s.tangent(&n));
            }
        }
    }

    #[test]
    fn transversely_isotropic_tangent_symmetries_and_objectivity() {
        let m = model(0.3).0;
        assert_symmetries(&m, true, 64);
        assert_objective(&m, 65);
    }

    #[test]
    fn transversely_isotropic_calibration_reproduces_engineering_constants() {
        for nu in POISSON_SWEEP {
            for young in [1.0, 1.0e5] {
                let m = make_material(MaterialModel::TransverselyIsotropic, young, nu).unwrap();
                let (_, c) = m.stress_and_tangent(&IDENTITY, &[0.0, 0.0, 1.0]);
                let got = engineering_from_tangent(&c);
                // E, ν, E_A = 5E/2, ν_A = ν, G_A = E/2, G_T = E/(2(1+ν)).
                let want = [young, nu, 2.5 * young, nu, 0.5 * young, young / (2.0 * (1.0 + nu))];
                for (g, w) in got.iter().zip(want) {
                    let s = if w.abs() < 1.0 { 1.0 } else { young };
                    assert!((g - w).abs() < 1e-10 * s, "ν={nu}: {got:?} vs {want:?}");
                }
            }
        }
    }

    #[test]
    fn transversely_isotropic_constants_follow_the_spec_relations() {
        for nu in POISSON_SWEEP {
            let (m, s) = model(nu);
            let e = 1.0;
            assert!((m.alpha - e / (8.0 * (1.0 + nu))).abs() < 1e-15);
            assert_eq!(m.alpha, m.beta);
            assert_eq!(m.mu_tilde, 2.0 * m.alpha + 4.0 * m.beta);
            assert!((m.eta1 - (e / (2.0 * (1.0 + nu)) - e / 2.0)).abs() < 1e-15);
            assert!((12.0 * m.alpha + m.lambda - s.c11).abs() < 1e-13 * s.c11);
            assert!((4.0 * m.eta2 - (s.c13 - 4.0 * m.alpha - m.lambda)).abs() < 1e-13 * s.c11);
            let g8 = s.c33 - 12.0 * m.alpha + 4.0 * m.eta1 - 8.0 * m.eta2 - m.lambda;
            assert!((8.0 * m.gamma - g8).abs() < 1e-13 * s.c33);
        }
    }

    #[test]
    fn transversely_isotropic_lambda_is_negative_below_nu_0_2888() {
        assert!(model(0.001).0.lambda < 0.0 && model(0.288).0.lambda < 0.0);
        assert!(model(0.2889).0.lambda > 0.0 && model(0.495).0.lambda > 0.0);
        for nu in POISSON_SWEEP {
            assert!(model(nu).0.eta1 <= 0.0 && model(nu).0.gamma > 0.0);
        }
    }

    #[test]
    fn transversely_isotropic_stress_matches_the_papers_closed_form() {
        let m = model(0.3).0;
        for (f, n) in samples(66) {
            let j = det(3, &f);
            let b = matmul(3, &f, &transpose(&f));
            let b2 = matmul(3, &b, &b);
            let a: Vec<f64> = (0..3).map(|i| (0..3).map(|k| f[i][k] * n[k]).sum()).collect();
            let ba: Vec<f64> = (0..3).map(|i| (0..3).map(|k| b[i][k] * a[k]).sum()).collect();
            let trb = b[0][0] + b[1][1] + b[2][2];
            let i4: f64 = a.iter().map(|x| x * x).sum();
            let mut s = [[0.0; 3]; 3];
            for p in 0..3 {
                for q in 0..3 {
                    s[p][q] = 2.0 / j
                        * ((m.alpha + m.eta2 * (i4 - 1.0)) * b[p][q]
                            + m.beta * (trb * b[p][q] - b2[p][q])
                            + (m.eta1 + m.eta2 * (trb - 3.0) + 2.0 * m.gamma * (i4 - 1.0)) * a[p] * a[q]
                            - 0.5 * m.eta1 * (a[p] * ba[q] + ba[p] * a[q]))
                        + (m.lambda * (j - 1.0) - m.mu_tilde / j) * delta(p, q);
                }
            }
            let sigma = m.stress(&f, &n);
            assert!(max_diff(&s, &sigma) < 1e-12 * max_abs(&s).max(1.0));
        }
    }

    #[test]
    fn anisotropic_invariants_match_fibre_stretch() {
        // Stretch λ along N: I4 = λ², I5 = λ⁴.
        let n = [0.6, 0.8, 0.0];
        let l = 1.7;
        let mut f = IDENTITY;
        for i in 0..3 {
            for k in 0..3 {
                f[i][k] += (l - 1.0) * n[i] * n[k];
            }
        }
        let (i4, i5) = super::super::anisotropic_invariants(&f, &n);
        assert!((i4 - l * l).abs() < 1e-13 && (i5 - l.powi(4)).abs() < 1e-12);
        // Simple shear of the fibre: FN = (1, 0, k), FᵀFN = (1 + k², 0, k).
        let k = 0.5;
        let g = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [k, 0.0, 1.0]];
        let (i4, i5) = super::super::anisotropic_invariants(&g, &[1.0, 0.0, 0.0]);
        let want5 = (1.0f64 + k * k).powi(2) + k * k;
        assert!((i4 - (1.0 + k * k)).abs() < 1e-14 && (i5 - want5).abs() < 1e-13);
        // A rotation leaves both at 1.
        let q = random_rotation(&mut Rng::new(67));
        let (i4, i5) = super::super::anisotropic_invariants(&q, &n);
        assert!((i4 - 1.0).abs() < 1e-13 && (i5 - 1.0).abs() < 1e-13);
    }
}
