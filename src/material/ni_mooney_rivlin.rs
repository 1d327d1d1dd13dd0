//! Nearly incompressible Mooney–Rivlin model (paper Table 2):
//! Ψ = α J^(−2/3) I1 + β J^(−2) I2^(3/2) + κ/2 (J − 1)² − (3α + 3√3 β).
//!
//! # Derivation
//! σ and c come from the invariant derivation of `invariants.rs` with
//! - Ψ_1 = α J^(−2/3), Ψ_2 = (3/2) β J^(−2) I2^(1/2),
//!   Ψ_J = −(2/3) α J^(−5/3) I1 − 2β J^(−3) I2^(3/2) + κ(J − 1);
//! - Ψ_22 = (3/4) β J^(−2) I2^(−1/2), Ψ_1J = −(2/3) α J^(−5/3),
//!   Ψ_2J = −3β J^(−3) I2^(1/2), Ψ_JJ = (10/9) α J^(−8/3) I1 + 6β J^(−4) I2^(3/2) + κ,
//!   Ψ_11 = Ψ_12 = 0.
//!
//! With g = HHᵀ = I2 I − I1 b + b² (Cayley–Hamilton) the stress reads
//! ```text
//! σ = 2α J^(−5/3) b − 3β J^(−3) (tr g)^(1/2) g
//!     + (κ(J − 1) − (2α/3) J^(−5/3) tr b + β J^(−3) (tr g)^(3/2)) I,
//! ```
//! which agrees with the paper's printed σ; its printed c is garbled and is
//! replaced by the general formula (checked against finite differences).
//!
//! # Calibration
//! At F = I: Ψ_1 + 2Ψ_2 + ½Ψ_J = 0 (stress free for any α, β, κ), μ = 2α + 3√3 β
//! and λ = κ − 4α/3 − 2√3 β. So 2α + 3√3 β = μ_lin and κ − 4α/3 − 2√3 β = λ_lin.
//! The paper's choice α = μ_lin/2 forces **β = 0** (then κ = λ_lin + 2μ_lin/3,
//! the bulk modulus): the default model is the decoupled neo-Hookean
//! α J^(−2/3) I1 + κ/2 (J − 1)². β ≥ 0 requires α ≤ μ_lin/2;
//! [`NearlyIncompressibleMooneyRivlin::from_lame`] accepts any such α.

use super::invariants::{material_from_invariants, InvariantEnergy, Invariants, I1, I2, JAC};

const SQRT3: f64 = 1.732_050_807_568_877_2;

/// Nearly incompressible Mooney–Rivlin constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearlyIncompressibleMooneyRivlin {
    pub alpha: f64,
    pub beta: f64,
    pub kappa: f64,
}

impl NearlyIncompressibleMooneyRivlin {
    /// β = (μ_lin − 2α)/(3√3), κ = λ_lin + 4α/3 + 2√3 β (the default, used by
    /// `MaterialModel::NearlyIncompressibleMooneyRivlin`, is α = μ_lin/2, giving
    /// β = 0). β < 0 (α > μ_lin/2) is accepted but makes Ψ non-convex in I2.
    pub fn from_lame(lambda: f64, mu: f64, alpha: f64) -> NearlyIncompressibleMooneyRivlin {
        let beta = (mu - 2.0 * alpha) / (3.0 * SQRT3);
        NearlyIncompressibleMooneyRivlin { alpha, beta, kappa: lambda + 4.0 * alpha / 3.0 + 2.0 * SQRT3 * beta }
    }
}

impl InvariantEnergy for NearlyIncompressibleMooneyRivlin {
    const ANISOTROPIC: bool = false;
    fn psi(&self, v: &Invariants) -> f64 {
        let (a, b, k) = (self.alpha, self.beta, self.kappa);
        a * v.j.powf(-2.0 / 3.0) * v.i1 + b * v.i2.powf(1.5) / (v.j * v.j) + 0.5 * k * (v.j - 1.0).powi(2)
            - (3.0 * a + 3.0 * SQRT3 * b)
    }
    fn derivatives(&self, v: &Invariants) -> ([f64; 5], [[f64; 5]; 5]) {
        let (a, b, k) = (self.alpha, self.beta, self.kappa);
        let j = v.j;
        let j23 = j.powf(-2.0 / 3.0);
        let j53 = j23 / j;
        let j83 = j53 / j;
        let (s, s3) = (v.i2.sqrt(), v.i2 * v.i2.sqrt());
        let (jm2, jm3) = (1.0 / (j * j), 1.0 / (j * j * j));
        let mut d1 = [0.0; 5];
        let mut d2 = [[0.0; 5]; 5];
        d1[I1] = a * j23;
        d1[I2] = 1.5 * b * jm2 * s;
        d1[JAC] = -2.0 / 3.0 * a * j53 * v.i1 - 2.0 * b * jm3 * s3 + k * (j - 1.0);
        d2[I2][I2] = 0.75 * b * jm2 / s;
        d2[I1][JAC] = -2.0 / 3.0 * a * j53;
        d2[JAC][I1] = d2[I1][JAC];
        d2[I2][JAC] = -3.0 * b * jm3 * s;
        d2[JAC][I2] = d2[I2][JAC];
        d2[JAC][JAC] = 10.0 / 9.0 * a * j83 * v.i1 + 6.0 * b * jm3 / j * s3 + k;
        (d1, d2)
    }
}

material_from_invariants!(NearlyIncompressibleMooneyRivlin, "ni-mooney-rivlin");

#[cfg(test)]
mod tests {
    use super::super::tensor::{delta, isotropic_tangent, transpose};
    use super::super::testing::*;
    use super::super::{LinearElastic, Material};
    use super::*;
    use crate::linalg::{cofactor, det, matmul};

    /// The default (α = μ/2, β = 0) and α = μ/4 (β > 0) so that the
    /// β terms are exercised.
    fn models(nu: f64) -> ([NearlyIncompressibleMooneyRivlin; 2], LinearElastic) {
        let lin = LinearElastic::try_from_young_poisson(1.0, nu).unwrap();
        (
            [
                NearlyIncompressibleMooneyRivlin::from_lame(lin.lambda, lin.mu, lin.mu / 2.0),
                NearlyIncompressibleMooneyRivlin::from_lame(lin.lambda, lin.mu, lin.mu / 4.0),
            ],
            lin,
        )
    }

    #[test]
    fn ni_mooney_rivlin_default_calibration_has_zero_beta_and_bulk_kappa() {
        for nu in POISSON_SWEEP {
            let ([m, m2], lin) = models(nu);
            assert_eq!(m.beta, 0.0);
            assert!((m.kappa - (lin.lambda + 2.0 * lin.mu / 3.0)).abs() < 1e-14 * m.kappa);
            assert!(m2.beta > 0.0);
            for x in [m, m2] {
                assert!((2.0 * x.alpha + 3.0 * SQRT3 * x.beta - lin.mu).abs() < 1e-14);
                let l = x.kappa - 4.0 * x.alpha / 3.0 - 2.0 * SQRT3 * x.beta;
                assert!((l - lin.lambda).abs() < 1e-13 * lin.lambda.max(1.0));
            }
        }
    }

    #[test]
    fn ni_mooney_rivlin_stress_matches_fd_of_energy() {
        for nu in [0.001, 0.3, 0.495] {
            for m in models(nu).0 {
                assert_stress_matches_fd_of_energy(&m, 31);
            }
        }
    }

    #[test]
    fn ni_mooney_rivlin_tangent_matches_fd_of_stress() {
        for nu in [0.001, 0.3, 0.495] {
            for m in models(nu).0 {
                assert_tangent_matches_fd_of_stress(&m, 32);
            }
        }
    }

    #[test]
    fn ni_mooney_rivlin_tangent_at_identity_equals_linear_tensor() {
        for nu in POISSON_SWEEP {
            let (ms, lin) = models(nu);
            let expected = isotropic_tangent(lin.lambda, lin.mu);
            for m in ms {
                assert_tangent_at_identity(&m, &[1.0, 0.0, 0.0], &expected);
            }
        }
    }

    #[test]
    fn ni_mooney_rivlin_tangent_symmetries_and_objectivity() {
        for m in models(0.3).0 {
            assert_symmetries(&m, true, 33);
            assert_objective(&m, 34);
        }
    }

    #[test]
    fn ni_mooney_rivlin_stress_matches_the_papers_g_form() {
        let m = models(0.3).0[1];
        for (f, n) in samples(35) {
            let j = det(3, &f);
            let b = matmul(3, &f, &transpose(&f));
            let h = cofactor(3, &f);
            let g = matmul(3, &h, &transpose(&h));
            let (trb, trg) = (b[0][0] + b[1][1] + b[2][2], g[0][0] + g[1][1] + g[2][2]);
            let (a, be, k) = (m.alpha, m.beta, m.kappa);
            let p = k * (j - 1.0) - 2.0 * a / 3.0 * j.powf(-5.0 / 3.0) * trb + be * j.powi(-3) * trg.powf(1.5);
            let mut s = [[0.0; 3]; 3];
            for i in 0..3 {
                for l in 0..3 {
                    s[i][l] = 2.0 * a * j.powf(-5.0 / 3.0) * b[i][l] - 3.0 * be * j.powi(-3) * trg.sqrt() * g[i][l]
                        + p * delta(i, l);
                }
            }
            let sigma = m.stress(&f, &n);
            assert!(max_diff(&s, &sigma) < 1e-12 * max_abs(&s).max(1.0));
        }
    }
}
