//! Compressible Mooney–Rivlin model (paper Table 2):
//! Ψ = α I1 + β I2 − 4β J − 2α ln J + λ/2 (J − 1)² − (3α − β),
//! σ = (2/J)[α b + β(tr b · b − b²)] + (λ(J − 1) − 4β − 2α/J) I,
//! c_ijkl = (2β/J)(2 b_ij b_kl − b_ik b_jl − b_il b_jk) + (λ(2J − 1) − 4β) δ_ij δ_kl
//!          − (λ(J − 1) − 4β − 2α/J) 𝓘_ijkl.
//! These follow from the invariant derivation (`invariants.rs`) with Ψ_1 = α,
//! Ψ_2 = β, Ψ_J = λ(J − 1) − 4β − 2α/J, Ψ_JJ = λ + 2α/J²; at F = I they give
//! μ = 2α + 2β and λ, hence the calibration λ = λ_lin, α + β = μ_lin/2.

use super::invariants::{InvariantEnergy, Invariants, I1, I2, JAC};
use super::tensor::{delta, transpose};
use super::{Material, Tangent};
use crate::linalg::{det, matmul, Mat3};

/// Compressible Mooney–Rivlin constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MooneyRivlin {
    pub alpha: f64,
    pub beta: f64,
    pub lambda: f64,
}

impl MooneyRivlin {
    /// λ = λ_lin and β = μ_lin/2 − α (the default, used by
    /// `MaterialModel::MooneyRivlin`, is α = β = μ_lin/4).
    pub fn from_lame(lambda: f64, mu: f64, alpha: f64) -> MooneyRivlin {
        MooneyRivlin { alpha, beta: 0.5 * mu - alpha, lambda }
    }

    fn pressure_like(&self, j: f64) -> f64 {
        self.lambda * (j - 1.0) - 4.0 * self.beta - 2.0 * self.alpha / j
    }
}

impl InvariantEnergy for MooneyRivlin {
    const ANISOTROPIC: bool = false;
    fn psi(&self, v: &Invariants) -> f64 {
        let (a, b) = (self.alpha, self.beta);
        a * v.i1 + b * v.i2 - 4.0 * b * v.j - 2.0 * a * v.j.ln() + 0.5 * self.lambda * (v.j - 1.0).powi(2)
            - (3.0 * a - b)
    }
    fn derivatives(&self, v: &Invariants) -> ([f64; 5], [[f64; 5]; 5]) {
        let mut d1 = [0.0; 5];
        let mut d2 = [[0.0; 5]; 5];
        d1[I1] = self.alpha;
        d1[I2] = self.beta;
        d1[JAC] = self.pressure_like(v.j);
        d2[JAC][JAC] = self.lambda + 2.0 * self.alpha / (v.j * v.j);
        (d1, d2)
    }
}

impl Material for MooneyRivlin {
    fn name(&self) -> &'static str {
        "mooney-rivlin"
    }

    fn energy(&self, f: &Mat3, fibre: &[f64; 3]) -> f64 {
        self.psi(&Invariants::of(f, fibre))
    }

    fn stress(&self, f: &Mat3, _fibre: &[f64; 3]) -> Mat3 {
        let j = det(3, f);
        let b = matmul(3, f, &transpose(f));
        let b2 = matmul(3, &b, &b);
        let trb = b[0][0] + b[1][1] + b[2][2];
        let p = self.pressure_like(j);
        let mut s = [[0.0; 3]; 3];
        for i in 0..3 {
            for k in 0..3 {
                s[i][k] = 2.0 / j * (self.alpha * b[i][k] + self.beta * (trb * b[i][k] - b2[i][k])) + p * delta(i, k);
            }
        }
        s
    }

    fn stress_and_tangent(&self, f: &Mat3, fibre: &[f64; 3]) -> (Mat3, Tangent) {
        let j = det(3, f);
        let b = matmul(3, f, &transpose(f));
        let p = self.pressure_like(j);
        let q = self.lambda * (2.0 * j - 1.0) - 4.0 * self.beta;
        let kb = 2.0 * self.beta / j;
        let mut c = super::tensor::ZERO_TANGENT;
        for i in 0..3 {
            for jj in 0..3 {
                for k in 0..3 {
                    for l in 0..3 {
                        c[i][jj][k][l] = kb * (2.0 * b[i][jj] * b[k][l] - b[i][k] * b[jj][l] - b[i][l] * b[jj][k])
                            + q * delta(i, jj) * delta(k, l)
                            - p * (delta(i, k) * delta(jj, l) + delta(i, l) * delta(jj, k));
                    }
                }
            }
        }
        (self.stress(f, fibre), c)
    }
}

#[cfg(test)]
mod tests {
    use super::super::invariants::invariant_stress_and_tangent;
    use super::super::testing::*;
    use super::super::LinearElastic;
    use super::*;

    /// The default split (α = β = μ/4) and a lopsided one (α = 3β).
    fn models(nu: f64) -> ([MooneyRivlin; 2], LinearElastic) {
        let lin = LinearElastic::try_from_young_poisson(1.0, nu).unwrap();
        (
            [
                MooneyRivlin::from_lame(lin.lambda, lin.mu, lin.mu / 4.0),
                MooneyRivlin::from_lame(lin.lambda, lin.mu, 3.0 * lin.mu / 8.0),
            ],
            lin,
        )
    }

    #[test]
    fn mooney_rivlin_default_split_is_alpha_equals_beta() {
        let ([m, _], lin) = models(0.3);
        assert!((m.alpha - m.beta).abs() < 1e-15 && (m.alpha + m.beta - lin.mu / 2.0).abs() < 1e-15);
    }

    #[test]
    fn mooney_rivlin_stress_matches_fd_of_energy() {
        for nu in [0.001, 0.3, 0.495] {
            for m in models(nu).0 {
                assert_stress_matches_fd_of_energy(&m, 21);
            }
        }
    }

    #[test]
    fn mooney_rivlin_tangent_matches_fd_of_stress() {
        for nu in [0.001, 0.3, 0.495] {
            for m in models(nu).0 {
                assert_tangent_matches_fd_of_stress(&m, 22);
            }
        }
    }

    #[test]
    fn mooney_rivlin_tangent_at_identity_equals_linear_tensor() {
        for nu in POISSON_SWEEP {
            let (ms, lin) = models(nu);
            let expected = super::super::tensor::isotropic_tangent(lin.lambda, lin.mu);
            for m in ms {
                assert_tangent_at_identity(&m, &[1.0, 0.0, 0.0], &expected);
            }
        }
    }

    #[test]
    fn mooney_rivlin_tangent_symmetries_and_objectivity() {
        for m in models(0.3).0 {
            assert_symmetries(&m, true, 23);
            assert_objective(&m, 24);
        }
    }

    #[test]
    fn mooney_rivlin_closed_form_matches_invariant_derivation() {
        for m in models(0.35).0 {
            for (f, n) in samples(25) {
                let (s0, c0) = m.stress_and_tangent(&f, &n);
                let (s1, c1) = invariant_stress_and_tangent(&m, &f, &n);
                assert!(max_diff(&s0, &s1) < 1e-12 * max_abs(&s0).max(1.0));
                assert!(max_diff_t(&c0, &c1) < 1e-12 * max_abs_t(&c0));
            }
        }
    }
}
