//! Compressible neo-Hookean model (paper eq. (20)–(22)):
//! Ψ = μ/2 (I1 − 3) − μ ln J + λ/2 (J − 1)²,
//! σ = μ/J (b − I) + λ(J − 1) I,
//! c = λ(2J − 1) I⊗I + (μ/J − λ(J − 1)) 𝓘;
//! calibration μ = μ_lin, λ = λ_lin.

use super::invariants::{InvariantEnergy, Invariants, I1, JAC};
use super::tensor::{delta, transpose};
use super::{Material, Tangent};
use crate::linalg::{det, matmul, Mat3};

/// Neo-Hookean constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeoHookean {
    pub lambda: f64,
    pub mu: f64,
}

impl NeoHookean {
    /// λ = λ_lin, μ = μ_lin.
    pub fn from_lame(lambda: f64, mu: f64) -> NeoHookean {
        NeoHookean { lambda, mu }
    }
}

impl InvariantEnergy for NeoHookean {
    const ANISOTROPIC: bool = false;
    fn psi(&self, v: &Invariants) -> f64 {
        0.5 * self.mu * (v.i1 - 3.0) - self.mu * v.j.ln() + 0.5 * self.lambda * (v.j - 1.0).powi(2)
    }
    fn derivatives(&self, v: &Invariants) -> ([f64; 5], [[f64; 5]; 5]) {
        let mut d1 = [0.0; 5];
        let mut d2 = [[0.0; 5]; 5];
        d1[I1] = 0.5 * self.mu;
        d1[JAC] = -self.mu / v.j + self.lambda * (v.j - 1.0);
        d2[JAC][JAC] = self.mu / (v.j * v.j) + self.lambda;
        (d1, d2)
    }
}

impl Material for NeoHookean {
    fn name(&self) -> &'static str {
        "neo-hookean"
    }

    fn energy(&self, f: &Mat3, fibre: &[f64; 3]) -> f64 {
        self.psi(&Invariants::of(f, fibre))
    }

    fn stress(&self, f: &Mat3, _fibre: &[f64; 3]) -> Mat3 {
        let j = det(3, f);
        let b = matmul(3, f, &transpose(f));
        let mut s = [[0.0; 3]; 3];
        for p in 0..3 {
            for q in 0..3 {
                s[p][q] = self.mu / j * (b[p][q] - delta(p, q)) + self.lambda * (j - 1.0) * delta(p, q);
            }
        }
        s
    }

    fn stress_and_tangent(&self, f: &Mat3, fibre: &[f64; 3]) -> (Mat3, Tangent) {
        let j = det(3, f);
        let a = self.lambda * (2.0 * j - 1.0);
        let m = self.mu / j - self.lambda * (j - 1.0);
        (self.stress(f, fibre), super::tensor::isotropic_tangent(a, m))
    }
}

#[cfg(test)]
mod tests {
    use super::super::invariants::invariant_stress_and_tangent;
    use super::super::testing::*;
    use super::super::LinearElastic;
    use super::*;

    fn model(nu: f64) -> (NeoHookean, LinearElastic) {
        let lin = LinearElastic::try_from_young_poisson(1.0, nu).unwrap();
        (NeoHookean::from_lame(lin.lambda, lin.mu), lin)
    }

    #[test]
    fn neo_hookean_stress_matches_fd_of_energy() {
        for nu in [0.001, 0.3, 0.495] {
            assert_stress_matches_fd_of_energy(&model(nu).0, 11);
        }
    }

    #[test]
    fn neo_hookean_tangent_matches_fd_of_stress() {
        for nu in [0.001, 0.3, 0.495] {
            assert_tangent_matches_fd_of_stress(&model(nu).0, 12);
        }
    }

    #[test]
    fn neo_hookean_tangent_at_identity_equals_linear_tensor() {
        for nu in POISSON_SWEEP {
            let (m, lin) = model(nu);
            let expected = super::super::tensor::isotropic_tangent(lin.lambda, lin.mu);
            assert_tangent_at_identity(&m, &[1.0, 0.0, 0.0], &expected);
        }
    }

    #[test]
    fn neo_hookean_tangent_symmetries_and_objectivity() {
        assert_symmetries(&model(0.3).0, true, 13);
        assert_objective(&model(0.3).0, 14);
    }

    #[test]
    fn neo_hookean_closed_form_matches_invariant_derivation() {
        let (m, _) = model(0.35);
        for (f, n) in samples(15) {
            let (s0, c0) = m.stress_and_tangent(&f, &n);
            let (s1, c1) = invariant_stress_and_tangent(&m, &f, &n);
            assert!(max_diff(&s0, &s1) < 1e-12 * max_abs(&s0).max(1.0));
            assert!(max_diff_t(&c0, &c1) < 1e-12 * max_abs_t(&c0));
        }
    }
}
