//! Constitutive models: pointwise strain energy Ψ, Cauchy stress σ and
//! spatial tangent c of the deformation gradient F (paper sections 2 and 4,
//! Table 2). No mesh here, but for the default fibre directions of a mesh's
//! cells (`fibres.rs`).
//!
//! Every model is calibrated from Young's modulus E and Poisson's ratio ν so
//! that its tangent at F = I equals the linear tensor
//! c_lin = λ_lin I⊗I + μ_lin 𝓘 (TI: the transversely isotropic linear tensor),
//! with λ_lin = Eν/((1+ν)(1−2ν)), μ_lin = E/(2(1+ν)) (paper eq. (26)) and
//! 𝓘_ijkl = δ_ik δ_jl + δ_il δ_jk.
//!
//! | model | file | σ, c |
//! |---|---|---|
//! | linear elastic | `linear.rs` | σ = λ tr ε I + 2μ ε, c = c_lin |
//! | neo-Hookean | `neo_hookean.rs` | paper eq. (21), (22) |
//! | compressible Mooney–Rivlin | `mooney_rivlin.rs` | closed form |
//! | nearly incompressible Mooney–Rivlin | `ni_mooney_rivlin.rs` | derived through `invariants.rs` |
//! | transversely isotropic (Bonet–Burton) | `transversely_isotropic.rs` | derived through `invariants.rs` |
//! | transversely isotropic linear | `ti_linear.rs` | σ = c:ε, c = TI linear tensor |
//!
//! `invariants.rs` holds the one derivation every hyperelastic model shares:
//! σ and c of any Ψ(I1, I2, J, I4, I5).
//!
//! ```
//! use hocurve::material::{make_material, MaterialModel};
//! let m = make_material(MaterialModel::NeoHookean, 1.0e5, 0.3).unwrap();
//! let f = [[1.1, 0.1, 0.0], [0.0, 0.95, 0.0], [0.0, 0.0, 1.0]];
//! let (sigma, c) = m.stress_and_tangent(&f, &[1.0, 0.0, 0.0]);
//! assert!(sigma[0][0] > 0.0 && c[0][0][0][0] > 0.0);
//! ```

mod fibres;
mod invariants;
mod linear;
mod mooney_rivlin;
mod neo_hookean;
mod ni_mooney_rivlin;
mod tensor;
mod ti_linear;
mod transversely_isotropic;

#[cfg(test)]
mod testing;

pub(crate) use fibres::checked_fibres;
pub use fibres::default_fibres;
pub use invariants::{anisotropic_invariants, Invariants};
pub use mooney_rivlin::MooneyRivlin;
pub use neo_hookean::NeoHookean;
pub use ni_mooney_rivlin::NearlyIncompressibleMooneyRivlin;
pub use ti_linear::{TiEngineeringConstants, TiStiffness, TransverselyIsotropicLinear};
pub use transversely_isotropic::TransverselyIsotropic;

use crate::linalg::Mat3;
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
            return Err(Error::InvalidInput(format!("Young's modulus must be positive and finite, got {young}")));
        }
        if !(poisson.is_finite() && (0.0..0.5).contains(&poisson)) {
            return Err(Error::InvalidInput(format!("Poisson's ratio must be in [0, 0.5), got {poisson}")));
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

/// Fourth-order tensor, `c[i][j][k][l]`.
pub type Tangent = [[[[f64; 3]; 3]; 3]; 3];

/// A hyperelastic (or linear) constitutive model evaluated pointwise.
///
/// F is always 3×3 (2D plane strain: `F = [[F11, F12, 0], [F21, F22, 0], [0, 0, 1]]`),
/// det F > 0. `fibre` is the unit material fibre direction N (ignored by the
/// isotropic models).
pub trait Material: Send + Sync + std::fmt::Debug {
    /// The CLI name of the model.
    fn name(&self) -> &'static str;
    /// Strain energy density Ψ(F) per unit undeformed volume.
    /// Linear models: Ψ = ½ ε:c:ε with ε = sym(F) − I.
    fn energy(&self, f: &Mat3, fibre: &[f64; 3]) -> f64;
    /// Cauchy stress σ = J⁻¹ P Fᵀ with P = ∂Ψ/∂F (paper eq. (8)).
    /// Linear models: the small-strain stress σ = c:ε = ∂Ψ/∂F.
    fn stress(&self, f: &Mat3, fibre: &[f64; 3]) -> Mat3;
    /// Cauchy stress and the spatial tangent of paper eq. (10):
    /// c_ijkl = J⁻¹ 𝒞_IJKL F_iI F_jJ F_kK F_lL with 𝒞 = 4 ∂²Ψ/∂C∂C (eq. (7)).
    /// Linear models: (c:ε, c) with the constant linear tensor c.
    fn stress_and_tangent(&self, f: &Mat3, fibre: &[f64; 3]) -> (Mat3, Tangent);
    /// True for the two linear models: c is constant and σ = c:ε vanishes at
    /// F = I, the only configuration at which ILE and LINEAR evaluate them.
    fn is_linear(&self) -> bool {
        false
    }
}

/// The constitutive models, named as on the command line.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MaterialModel {
    LinearElastic,
    NeoHookean,
    MooneyRivlin,
    NearlyIncompressibleMooneyRivlin,
    TransverselyIsotropic,
    TransverselyIsotropicLinear,
}

impl MaterialModel {
    /// Every model, in declaration order.
    pub const ALL: [MaterialModel; 6] = [
        MaterialModel::LinearElastic,
        MaterialModel::NeoHookean,
        MaterialModel::MooneyRivlin,
        MaterialModel::NearlyIncompressibleMooneyRivlin,
        MaterialModel::TransverselyIsotropic,
        MaterialModel::TransverselyIsotropicLinear,
    ];

    /// The CLI name, e.g. `"ni-mooney-rivlin"`.
    pub fn name(self) -> &'static str {
        match self {
            MaterialModel::LinearElastic => "linear",
            MaterialModel::NeoHookean => "neo-hookean",
            MaterialModel::MooneyRivlin => "mooney-rivlin",
            MaterialModel::NearlyIncompressibleMooneyRivlin => "ni-mooney-rivlin",
            MaterialModel::TransverselyIsotropic => "transversely-isotropic",
            MaterialModel::TransverselyIsotropicLinear => "transversely-isotropic-linear",
        }
    }

    /// Inverse of [`MaterialModel::name`] (ASCII case-insensitive);
    /// `Error::InvalidInput` for an unknown name.
    pub fn parse(s: &str) -> Result<MaterialModel> {
        let t = s.trim();
        MaterialModel::ALL.into_iter().find(|m| m.name().eq_ignore_ascii_case(t)).ok_or_else(|| {
            let names: Vec<&str> = MaterialModel::ALL.iter().map(|m| m.name()).collect();
            Error::InvalidInput(format!("unknown material {s:?}; expected one of {}", names.join(", ")))
        })
    }

    /// True for the two models that use the fibre direction.
    pub fn is_transversely_isotropic(self) -> bool {
        matches!(self, MaterialModel::TransverselyIsotropic | MaterialModel::TransverselyIsotropicLinear)
    }
}

/// Build a model calibrated from E > 0 and 0 ≤ ν < 0.5 (`Error::InvalidInput`
/// otherwise), as follows:
/// - linear, neo-Hookean: λ = λ_lin, μ = μ_lin;
/// - Mooney–Rivlin: λ = λ_lin, α = β = μ_lin/4 (α + β = μ_lin/2);
/// - NI-MR: α = μ_lin/2, so 2α + 3√3β = μ_lin gives β = 0 and
///   κ − 4α/3 − 2√3β = λ_lin gives κ = λ_lin + 2μ_lin/3 (the bulk modulus);
/// - TI and TI linear: transverse E, ν; axial E_A = 5E/2, ν_A = ν, G_A = E/2
///   (see [`TiEngineeringConstants::paper_default`]).
pub fn make_material(model: MaterialModel, young: f64, poisson: f64) -> Result<Box<dyn Material>> {
    let lin = LinearElastic::try_from_young_poisson(young, poisson)?;
    Ok(match model {
        MaterialModel::LinearElastic => Box::new(lin),
        MaterialModel::NeoHookean => Box::new(NeoHookean::from_lame(lin.lambda, lin.mu)),
        MaterialModel::MooneyRivlin => Box::new(MooneyRivlin::from_lame(lin.lambda, lin.mu, lin.mu / 4.0)),
        MaterialModel::NearlyIncompressibleMooneyRivlin => {
            Box::new(NearlyIncompressibleMooneyRivlin::from_lame(lin.lambda, lin.mu, lin.mu / 2.0))
        }
        MaterialModel::TransverselyIsotropic => {
            let s = TiEngineeringConstants::paper_default(young, poisson).try_stiffness()?;
            Box::new(TransverselyIsotropic::from_stiffness(&s))
        }
        MaterialModel::TransverselyIsotropicLinear => {
            let s = TiEngineeringConstants::paper_default(young, poisson).try_stiffness()?;
            Box::new(TransverselyIsotropicLinear { stiffness: s })
        }
    })
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
        for (e, nu) in [(0.0, 0.3), (-1.0, 0.3), (1.0, 0.5), (1.0, -0.1), (f64::NAN, 0.2), (1.0, f64::INFINITY)] {
            assert!(LinearElastic::try_from_young_poisson(e, nu).is_err(), "{e} {nu}");
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
    #[test]
    fn model_names_round_trip_and_unknown_names_are_rejected() {
        for m in MaterialModel::ALL {
            assert_eq!(MaterialModel::parse(m.name()).unwrap(), m);
            assert_eq!(make_material(m, 1.0, 0.3).unwrap().name(), m.name());
            assert_eq!(m.is_transversely_isotropic(), m.name().starts_with("transversely"));
        }
        assert_eq!(MaterialModel::parse("Neo-Hookean").unwrap(), MaterialModel::NeoHookean);
        assert!(matches!(MaterialModel::parse("rubber"), Err(Error::InvalidInput(_))));
    }

    #[test]
    fn make_material_rejects_bad_parameters_and_flags_linear_models() {
        for m in MaterialModel::ALL {
            assert!(make_material(m, -1.0, 0.3).is_err());
            assert!(make_material(m, 1.0, 0.5).is_err());
            let linear = matches!(m, MaterialModel::LinearElastic | MaterialModel::TransverselyIsotropicLinear);
            assert_eq!(make_material(m, 1.0, 0.3).unwrap().is_linear(), linear);
        }
    }
}
