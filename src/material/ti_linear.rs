//! Transversely isotropic linear elasticity with axis N: engineering
//! constants, the stiffness obtained by inverting the compliance, the
//! fourth-order tensor for any axis, and the model σ = c:ε.
//!
//! Compliance (axis = 3, Voigt order 11, 22, 33, 23, 13, 12, engineering shear):
//! ```text
//! ε11 =  σ11/E − ν σ22/E − ν_A σ33/E_A      γ23 = σ23/G_A
//! ε22 = −ν σ11/E + σ22/E − ν_A σ33/E_A      γ13 = σ13/G_A
//! ε33 = −ν_A (σ11 + σ22)/E_A + σ33/E_A      γ12 = 2(1 + ν) σ12/E
//! ```
//! i.e. ν_A = −ε_transverse/ε_axial under axial load. (With this convention
//! the paper's E_A = 5E/2, ν_A = ν stays positive definite up to ν = 0.5:
//! 1 − ν − 2ν_A² E/E_A = 1 − ν − 0.8ν² > 0.)
//!
//! For a unit axis N and A = N⊗N the stiffness is
//! ```text
//! c = C12 I⊗I + C66 𝓘 + (C13 − C12)(I⊗A + A⊗I)
//!   + (C44 − C66)(δ_ik A_jl + δ_il A_jk + A_ik δ_jl + A_il δ_jk)
//!   + (C33 + C12 + 2C66 − 2C13 − 4C44) A⊗A,
//! ```
//! which for N = e3 gives c_1111 = C12 + 2C66 = C11, c_1122 = C12, c_1133 = C13,
//! c_3333 = C33, c_2323 = C44 = G_A, c_1212 = C66.

use super::tensor::{contract, ddot, delta, small_strain, ZERO_TANGENT};
use super::{Material, Tangent};
use crate::linalg::{inverse, Mat3};
use crate::{Error, Result};

/// Engineering constants of a transversely isotropic solid: transverse E, ν;
/// axial E_A, ν_A, G_A.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiEngineeringConstants {
    pub young: f64,
    pub poisson: f64,
    pub young_axial: f64,
    pub poisson_axial: f64,
    pub shear_axial: f64,
}

/// The independent stiffness components for axis e3 (C66 = (C11 − C12)/2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiStiffness {
    pub c11: f64,
    pub c12: f64,
    pub c13: f64,
    pub c33: f64,
    /// c_2323 = G_A.
    pub c44: f64,
    /// c_1212 = E/(2(1 + ν)).
    pub c66: f64,
}

impl TiEngineeringConstants {
    /// The paper's choice (Table 2): E_A = 5E/2, ν_A = ν, G_A = E/2.
    pub fn paper_default(young: f64, poisson: f64) -> TiEngineeringConstants {
        TiEngineeringConstants {
            young,
            poisson,
            young_axial: 2.5 * young,
            poisson_axial: poisson,
            shear_axial: 0.5 * young,
        }
    }

    /// Invert the normal block of the compliance (module doc);
    /// `Error::InvalidInput` unless the compliance is positive definite.
    pub fn try_stiffness(&self) -> Result<TiStiffness> {
        let &TiEngineeringConstants { young: e, poisson: nu, young_axial: ea, poisson_axial: nua, shear_axial: ga } =
            self;
        let finite = [e, nu, ea, nua, ga].iter().all(|x| x.is_finite());
        // Positive definiteness: E, E_A, G_A > 0, |ν| < 1, 1 − ν − 2ν_A² E/E_A > 0.
        if !(finite && e > 0.0 && ea > 0.0 && ga > 0.0 && nu.abs() < 1.0 && 1.0 - nu - 2.0 * nua * nua * e / ea > 0.0) {
            return Err(Error::InvalidInput(format!(
                "transversely isotropic constants are not positive definite: {self:?}"
            )));
        }
        let s: Mat3 = [[1.0 / e, -nu / e, -nua / ea], [-nu / e, 1.0 / e, -nua / ea], [-nua / ea, -nua / ea, 1.0 / ea]];
        let (c, _) = inverse(3, &s);
        Ok(TiStiffness {
            c11: c[0][0],
            c12: c[0][1],
            c13: c[0][2],
            c33: c[2][2],
            c44: ga,
            c66: 0.5 * (c[0][0] - c[0][1]),
        })
    }
}

impl TiStiffness {
    /// The fourth-order stiffness with axis `n` (unit), module doc formula.
    pub fn tangent(&self, n: &[f64; 3]) -> Tangent {
        let a = |i: usize, j: usize| n[i] * n[j];
        let k_aa = self.c33 + self.c12 + 2.0 * self.c66 - 2.0 * self.c13 - 4.0 * self.c44;
        let mut c = ZERO_TANGENT;
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    for l in 0..3 {
                        c[i][j][k][l] = self.c12 * delta(i, j) * delta(k, l)
                            + self.c66 * (delta(i, k) * delta(j, l) + delta(i, l) * delta(j, k))
                            + (self.c13 - self.c12) * (delta(i, j) * a(k, l) + a(i, j) * delta(k, l))
                            + (self.c44 - self.c66)
                                * (delta(i, k) * a(j, l)
                                    + delta(i, l) * a(j, k)
                                    + a(i, k) * delta(j, l)
                                    + a(i, l) * delta(j, k))
                            + k_aa * a(i, j) * a(k, l);
                    }
                }
            }
        }
        c
    }
}

/// Transversely isotropic linear elasticity: Ψ = ½ ε:c:ε, σ = c:ε with the
/// small strain ε = sym(F) − I and c = [`TiStiffness::tangent`] about the fibre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransverselyIsotropicLinear {
    pub stiffness: TiStiffness,
}

impl Material for TransverselyIsotropicLinear {
    fn name(&self) -> &'static str {
        "transversely-isotropic-linear"
    }
    fn energy(&self, f: &Mat3, fibre: &[f64; 3]) -> f64 {
        let e = small_strain(f);
        0.5 * ddot(&e, &contract(&self.stiffness.tangent(fibre), &e))
    }
    fn stress(&self, f: &Mat3, fibre: &[f64; 3]) -> Mat3 {
        self.stress_and_tangent(f, fibre).0
    }
    fn stress_and_tangent(&self, f: &Mat3, fibre: &[f64; 3]) -> (Mat3, Tangent) {
        let c = self.stiffness.tangent(fibre);
        (contract(&c, &small_strain(f)), c)
    }
    fn is_linear(&self) -> bool {
        true
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::testing::*;
    use super::*;

    fn model(nu: f64) -> TransverselyIsotropicLinear {
        TransverselyIsotropicLinear {
            stiffness: TiEngineeringConstants::paper_default(1.0, nu).try_stiffness().unwrap(),
        }
    }

    /// Solve the 6×6 system by Gauss–Jordan with partial pivoting: the inverse.
    pub(crate) fn invert6(m: [[f64; 6]; 6]) -> [[f64; 6]; 6] {
        let mut a = m;
        let mut inv = [[0.0; 6]; 6];
        for (i, row) in inv.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        for col in 0..6 {
            let piv = (col..6).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs())).unwrap();
            a.swap(col, piv);
            inv.swap(col, piv);
            let d = a[col][col];
            assert!(d.abs() > 1e-300);
            for k in 0..6 {
                a[col][k] /= d;
                inv[col][k] /= d;
            }
            for r in 0..6 {
                if r != col {
                    let fct = a[r][col];
                    for k in 0..6 {
                        a[r][k] -= fct * a[col][k];
                        inv[r][k] -= fct * inv[col][k];
                    }
                }
            }
        }
        inv
    }

    /// Voigt matrix of c (order 11, 22, 33, 23, 13, 12; engineering shear).
    pub(crate) fn voigt(c: &Tangent) -> [[f64; 6]; 6] {
        const P: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];
        let mut v = [[0.0; 6]; 6];
        for (a, &(i, j)) in P.iter().enumerate() {
            for (b, &(k, l)) in P.iter().enumerate() {
                v[a][b] = c[i][j][k][l];
            }
        }
        v
    }

    /// Engineering constants read back from the compliance S = D⁻¹ (axis e3):
    /// (E, ν, E_A, ν_A, G_A, G_T).
    pub(crate) fn engineering_from_tangent(c: &Tangent) -> [f64; 6] {
        let s = invert6(voigt(c));
        let e = 1.0 / s[0][0];
        let ea = 1.0 / s[2][2];
        [e, -s[0][1] * e, ea, -s[0][2] * ea, 1.0 / s[3][3], 1.0 / s[5][5]]
    }

    #[test]
    fn ti_linear_stiffness_reproduces_engineering_constants() {
        for nu in POISSON_SWEEP {
            let k = TiEngineeringConstants::paper_default(2.0, nu);
            let st = k.try_stiffness().unwrap();
            assert!((st.c66 - 2.0 / (2.0 * (1.0 + nu))).abs() < 1e-13);
            let got = engineering_from_tangent(&st.tangent(&[0.0, 0.0, 1.0]));
            let want = [2.0, nu, 5.0, nu, 1.0, 1.0 / (1.0 + nu)];
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 1e-12 * w.abs().max(1.0), "ν={nu}: {got:?} vs {want:?}");
            }
            // The other components are decoupled (no normal–shear coupling).
            let v = voigt(&st.tangent(&[0.0, 0.0, 1.0]));
            for a in 0..3 {
                for b in 3..6 {
                    assert_eq!(v[a][b], 0.0);
                }
            }
        }
    }

    #[test]
    fn ti_linear_rejects_non_positive_definite_constants() {
        let mut k = TiEngineeringConstants::paper_default(1.0, 0.3);
        k.poisson_axial = 1.5;
        assert!(k.try_stiffness().is_err());
        k = TiEngineeringConstants::paper_default(1.0, 0.3);
        k.shear_axial = 0.0;
        assert!(k.try_stiffness().is_err());
    }

    #[test]
    fn ti_linear_tensor_rotates_with_its_axis() {
        let st = TiEngineeringConstants::paper_default(1.0, 0.3).try_stiffness().unwrap();
        let c3 = st.tangent(&[0.0, 0.0, 1.0]);
        let mut rng = Rng::new(41);
        for _ in 0..5 {
            let q = random_rotation(&mut rng);
            let n = [q[0][2], q[1][2], q[2][2]];
            let cn = st.tangent(&n);
            let mut rot = ZERO_TANGENT;
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        for l in 0..3 {
                            let mut acc = 0.0;
                            for p in 0..3 {
                                for r in 0..3 {
                                    for s in 0..3 {
                                        for t in 0..3 {
                                            acc += q[i][p] * q[j][r] * q[k][s] * q[l][t] * c3[p][r][s][t];
                                        }
                                    }
                                }
                            }
                            rot[i][j][k][l] = acc;
                        }
                    }
                }
            }
            assert!(max_diff_t(&rot, &cn) < 1e-12 * max_abs_t(&c3));
        }
    }

    #[test]
    fn transversely_isotropic_linear_stress_matches_fd_of_energy() {
        for nu in [0.001, 0.3, 0.495] {
            assert_stress_matches_fd_of_energy(&model(nu), 51);
        }
    }

    #[test]
    fn transversely_isotropic_linear_tangent_matches_fd_of_stress() {
        for nu in [0.001, 0.3, 0.495] {
            assert_tangent_matches_fd_of_stress(&model(nu), 52);
        }
    }

    #[test]
    fn transversely_isotropic_linear_tangent_at_identity_equals_linear_tensor() {
        let mut rng = Rng::new(53);
        for nu in POISSON_SWEEP {
            let m = model(nu);
            let n = random_unit(&mut rng, false);
            assert_tangent_at_identity(&m, &n, &m.stiffness.tangent(&n));
        }
    }

    #[test]
    fn transversely_isotropic_linear_tangent_symmetries() {
        assert_symmetries(&model(0.3), true, 54);
        assert_rotation_stresses_linear_model(&model(0.3));
    }
}
