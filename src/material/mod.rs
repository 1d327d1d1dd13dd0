//! Constitutive models: pointwise stress and tangent of the deformation
//! gradient. No mesh here.
//!
//! Issue-2 scope: the isotropic linear elastic model, calibrated from Young's
//! modulus E and Poisson's ratio ν (paper section 4):
//! λ = Eν/((1+ν)(1−2ν)), μ = E/(2(1+ν)); σ = λ tr ε I + 2μ ε,
//! c = λ I⊗I + μ 𝓘 with 𝓘_ijkl = δ_ik δ_jl + δ_il δ_jk.

use crate::{Error, Result};

/// Isotropic linear elasticity in Lamé form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearElastic {
    pub lambda: f64,
    pub mu: f64,
}

impl LinearElastic {
    /// Calibrate from Young's modulus `young` > 0 and Poisson's ratio
    /// 0 ≤ `poisson` < 0.5 (the paper's range is [0.001, 0.495]).
    pub fn try_from_young_poisson(young: f64, poisson: f64) -> Result<LinearElastic> {
        if !(young.is_finite() && young > 0.0) {
            return Err(Error::InvalidInput(format!(
                "Young's modulus must be positive and finite, got {young}"
            )));
        }
        if !(poisson.is_finite() && (0.0..0.5).contains(&poisson)) {
            return Err(Error::InvalidInput(format!(
                "Poisson's ratio must be in [0, 0.5), got {poisson}"
            )));
        }
        Ok(LinearElastic {
            lambda: young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson)),
            mu: young / (2.0 * (1.0 + poisson)),
        })
    }

    /// Spatial tangent component c_ijkl = λ δ_ij δ_kl + μ (δ_ik δ_jl + δ_il δ_jk).
    pub fn tangent(&self, i: usize, j: usize, k: usize, l: usize) -> f64 {
        let d = |a: usize, b: usize| if a == b { 1.0 } else { 0.0 };
        self.lambda * d(i, j) * d(k, l) + self.mu * (d(i, k) * d(j, l) + d(i, l) * d(j, k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_constants_reproduce_young_and_poisson() {
        let m = LinearElastic::try_from_young_poisson(2.0e5, 0.3).unwrap();
        // E = μ(3λ + 2μ)/(λ + μ), ν = λ / (2(λ + μ))
        let e = m.mu * (3.0 * m.lambda + 2.0 * m.mu) / (m.lambda + m.mu);
        let nu = m.lambda / (2.0 * (m.lambda + m.mu));
        assert!((e - 2.0e5).abs() < 1e-9 * 2.0e5);
        assert!((nu - 0.3).abs() < 1e-14);
    }

    #[test]
    fn out_of_range_parameters_are_rejected() {
        for (e, nu) in [
            (0.0, 0.3),
            (-1.0, 0.3),
            (1.0, 0.5),
            (1.0, -0.1),
            (f64::NAN, 0.2),
            (1.0, f64::INFINITY),
        ] {
            assert!(
                LinearElastic::try_from_young_poisson(e, nu).is_err(),
                "{e} {nu}"
            );
        }
    }

    #[test]
    fn tangent_has_major_and_minor_symmetry() {
        let m = LinearElastic::try_from_young_poisson(1.0, 0.25).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    for l in 0..3 {
                        let c = m.tangent(i, j, k, l);
                        assert_eq!(c, m.tangent(k, l, i, j));
                        assert_eq!(c, m.tangent(j, i, k, l));
                    }
                }
            }
        }
    }
}
