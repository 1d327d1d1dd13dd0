//! Isotropic linear elasticity as a [`Material`] (paper eq. (23)–(25)):
//! Ψ = ½ ε:c:ε = λ/2 (tr ε)² + μ ε:ε, σ = c:ε = λ tr ε I + 2μ ε,
//! c = λ I⊗I + μ 𝓘, with the small strain ε = sym(F) − I.
//!
//! σ is the small-strain stress ∂Ψ/∂F (not J⁻¹PFᵀ): it is meant for the
//! ILE/LINEAR formulations, which measure F from the current configuration
//! and only use the constant c.

use super::tensor::{contract, ddot, isotropic_tangent, small_strain};
use super::{LinearElastic, Material, Tangent};
use crate::linalg::Mat3;

impl Material for LinearElastic {
    fn name(&self) -> &'static str {
        "linear"
    }

    fn energy(&self, f: &Mat3, _fibre: &[f64; 3]) -> f64 {
        let e = small_strain(f);
        let tr = e[0][0] + e[1][1] + e[2][2];
        0.5 * self.lambda * tr * tr + self.mu * ddot(&e, &e)
    }

    fn stress(&self, f: &Mat3, _fibre: &[f64; 3]) -> Mat3 {
        let e = small_strain(f);
        let tr = e[0][0] + e[1][1] + e[2][2];
        let mut s = e.map(|row| row.map(|x| 2.0 * self.mu * x));
        for (i, row) in s.iter_mut().enumerate() {
            row[i] += self.lambda * tr;
        }
        s
    }

    fn stress_and_tangent(&self, f: &Mat3, _fibre: &[f64; 3]) -> (Mat3, Tangent) {
        let c = isotropic_tangent(self.lambda, self.mu);
        (contract(&c, &small_strain(f)), c)
    }

    fn is_linear(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    fn model(nu: f64) -> LinearElastic {
        LinearElastic::try_from_young_poisson(1.0, nu).unwrap()
    }

    #[test]
    fn linear_stress_matches_fd_of_energy() {
        for nu in [0.001, 0.3, 0.495] {
            assert_stress_matches_fd_of_energy(&model(nu), 1);
        }
    }

    #[test]
    fn linear_tangent_matches_fd_of_stress() {
        for nu in [0.001, 0.3, 0.495] {
            assert_tangent_matches_fd_of_stress(&model(nu), 2);
        }
    }

    #[test]
    fn linear_tangent_at_identity_equals_linear_tensor() {
        for nu in POISSON_SWEEP {
            let m = model(nu);
            let mut expected = [[[[0.0; 3]; 3]; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        for l in 0..3 {
                            expected[i][j][k][l] = m.tangent(i, j, k, l);
                        }
                    }
                }
            }
            assert_tangent_at_identity(&m, &[1.0, 0.0, 0.0], &expected);
        }
    }

    #[test]
    fn linear_tangent_has_minor_and_major_symmetry() {
        assert_symmetries(&model(0.3), true, 3);
    }

    #[test]
    fn linear_model_is_not_objective_but_exact_in_small_strain() {
        assert_rotation_stresses_linear_model(&model(0.3));
    }
}
