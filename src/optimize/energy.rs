//! The regularised distortion energy of the optimisation stage.
//!
//! At a point of an element, F = ∂x/∂X maps the straight-sided element X to
//! the curved one x (as in [`crate::quality`]), J = det F. The pointwise
//! measure is a shape term plus a size term,
//!
//! μ(F) = |F|² / (d σ(J)^(2/d)) + γ ((J² + 1) / (2 σ(J)) − 1),
//!
//! with the regularised determinant of Escobar et al. (2003),
//! σ(J) = (J + √(J² + 4δ²)) / 2. With δ = 0 and J > 0, σ = J: the shape
//! term is the mean-ratio distortion (≥ 1, = 1 iff F is a scaled rotation)
//! and the size term (J − 1)²/(2J) (≥ 0, = 1 at J = 1); both blow up as
//! J → 0⁺, so a minimiser that never crosses infinity keeps every sampled
//! point valid. With δ > 0 the measure is finite for J ≤ 0 too and decreases
//! as J grows: minimising it untangles. This is the simultaneous untangling
//! and smoothing of Escobar et al., applied to high-order elements as in
//! Gargallo-Peiró et al. (2015), with the straight-sided element as the
//! ideal one, so an element that stays straight has μ = 1 everywhere.

use crate::linalg::{self, Mat3};
use crate::mapping;

/// Weight γ of the size term.
pub const SIZE_WEIGHT: f64 = 0.5;

/// μ(F) and ∂μ/∂F at one point, or None where it is infinite (δ = 0 and
/// J ≤ 0, or a non-finite F).
#[inline(always)]
pub fn distortion(dim: usize, f: &Mat3, delta: f64) -> Option<(f64, Mat3)> {
    let j = linalg::det(dim, f);
    let s = (j * j + 4.0 * delta * delta).sqrt();
    let sigma = 0.5 * (j + s);
    if sigma.is_nan() || sigma <= 0.0 || !sigma.is_finite() {
        return None;
    }
    let d = dim as f64;
    let mut ff = 0.0;
    for i in 0..dim {
        for k in 0..dim {
            ff += f[i][k] * f[i][k];
        }
    }
    // σ^(2/d) without powf (a tenth of the optimisation's time when it was
    // powf), nor Rust's correctly rounded cbrt (as much again).
    let scale = if dim == 3 {
        let c = linalg::cbrt_positive(sigma);
        c * c
    } else {
        sigma
    };
    let shape = ff / (d * scale);
    let size = (j * j + 1.0) / (2.0 * sigma) - 1.0;
    let mu = shape + SIZE_WEIGHT * size;
    // dσ/dJ = σ / s (s > 0 since σ > 0).
    let dsigma = sigma / s;
    let dmu_dsigma = -(2.0 / d) * shape / sigma - SIZE_WEIGHT * (j * j + 1.0) / (2.0 * sigma * sigma);
    let dmu_dj = SIZE_WEIGHT * j / sigma + dmu_dsigma * dsigma;
    let cof = linalg::cofactor(dim, f);
    let mut g = [[0.0; 3]; 3];
    for i in 0..dim {
        for k in 0..dim {
            g[i][k] = 2.0 * f[i][k] / (d * scale) + dmu_dj * cof[i][k];
        }
    }
    mu.is_finite().then_some((mu, g))
}

/// The sample points of one element, with the physical gradients of the
/// basis on its straight-sided element: F at point q is Σ_a x_a ⊗ G_a(q).
#[derive(Debug, Clone)]
pub struct ElementSamples {
    /// `grads[(q * n_basis + a) * dim + i]` = ∂N_a/∂X_i at point q.
    pub grads: Vec<f64>,
}

/// Per-point weights and reference gradients shared by every element of one
/// order: the element energy is Σ_q w_q μ(F_q), the weights summing to 1, so
/// that every element counts alike whatever its size.
#[derive(Debug, Clone)]
pub struct SampleRule {
    pub dim: usize,
    pub n_basis: usize,
    pub weights: Vec<f64>,
    /// Reference gradients, as in [`mapping::ElementCache::ref_grads`].
    pub ref_grads: Vec<f64>,
}

impl SampleRule {
    pub fn n_points(&self) -> usize {
        self.weights.len()
    }

    /// Physical gradients of the basis on the straight element whose
    /// vertices are the first dim + 1 nodes of `xs`; None if that element is
    /// degenerate.
    pub fn element(&self, xs: &[f64]) -> Option<ElementSamples> {
        let dim = self.dim;
        let xv: Vec<[f64; 3]> = (0..=dim)
            .map(|a| {
                let mut v = [0.0; 3];
                v[..dim].copy_from_slice(&xs[a * dim..(a + 1) * dim]);
                v
            })
            .collect();
        let (w_inv, det) = linalg::inverse(dim, &mapping::affine_jacobian(dim, &xv));
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let mut grads = vec![0.0; self.ref_grads.len()];
        let s = self.n_basis * dim;
        for q in 0..self.n_points() {
            mapping::physical_gradients_into(
                dim,
                &self.ref_grads[q * s..(q + 1) * s],
                &w_inv,
                &mut grads[q * s..(q + 1) * s],
            );
        }
        Some(ElementSamples { grads })
    }

    /// F at point q of an element with node coordinates `xe`.
    #[inline]
    pub fn deformation(&self, e: &ElementSamples, xe: &[f64], q: usize) -> Mat3 {
        let s = self.n_basis * self.dim;
        mapping::jacobian(self.dim, xe, &e.grads[q * s..(q + 1) * s])
    }

    /// Smallest J = det F over the sample points of the element.
    pub fn min_det(&self, e: &ElementSamples, xe: &[f64]) -> f64 {
        (0..self.n_points()).map(|q| linalg::det(self.dim, &self.deformation(e, xe, q))).fold(f64::INFINITY, f64::min)
    }

    /// The element energy Σ_q w_q μ(F_q), adding its gradient with respect to
    /// the node coordinates `xe` into `grad` (same layout as `xe`); None if
    /// it is infinite.
    pub fn energy_grad(&self, e: &ElementSamples, xe: &[f64], delta: f64, grad: &mut [f64]) -> Option<f64> {
        // The optimisation's inner loop: one copy per dimension, so that the
        // loops over it are unrolled (the arithmetic is the same).
        match self.dim {
            2 => self.energy_grad_in::<2>(e, xe, delta, grad),
            _ => self.energy_grad_in::<3>(e, xe, delta, grad),
        }
    }

    /// [`Self::energy_grad`] in dimension `D`.
    #[inline(always)]
    fn energy_grad_in<const D: usize>(
        &self,
        e: &ElementSamples,
        xe: &[f64],
        delta: f64,
        grad: &mut [f64],
    ) -> Option<f64> {
        let s = self.n_basis * D;
        let (xe, grad) = (&xe[..s], &mut grad[..s]);
        let mut total = 0.0;
        for (g, &w) in e.grads.chunks_exact(s).zip(&self.weights) {
            let f = mapping::jacobian_in::<D>(xe, g);
            let (mu, p) = distortion(D, &f, delta)?;
            total += w * mu;
            // ∂μ/∂x_a,i = Σ_k P_ik G_a,k.
            for (ga, out) in g.chunks_exact(D).zip(grad.chunks_exact_mut(D)) {
                for i in 0..D {
                    let mut v = 0.0;
                    for k in 0..D {
                        v += p[i][k] * ga[k];
                    }
                    out[i] += w * v;
                }
            }
        }
        Some(total)
    }

    /// The element energy alone.
    #[cfg(test)]
    pub fn energy(&self, e: &ElementSamples, xe: &[f64], delta: f64) -> Option<f64> {
        let mut total = 0.0;
        for q in 0..self.n_points() {
            let (mu, _) = distortion(self.dim, &self.deformation(e, xe, q), delta)?;
            total += self.weights[q] * mu;
        }
        Some(total)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_f(dim: usize, seed: u64) -> Mat3 {
        let mut s = seed;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut f = [[0.0; 3]; 3];
        for i in 0..dim {
            for k in 0..dim {
                f[i][k] = if i == k { 1.0 } else { 0.0 } + 0.6 * next();
            }
        }
        f
    }

    #[test]
    fn distortion_is_one_at_the_identity_and_stationary_there() {
        for dim in [2, 3] {
            let mut id = [[0.0; 3]; 3];
            for i in 0..dim {
                id[i][i] = 1.0;
            }
            let (mu, g) = distortion(dim, &id, 0.0).unwrap();
            assert!((mu - 1.0).abs() < 1e-15, "{mu}");
            for row in &g[..dim] {
                for v in &row[..dim] {
                    assert!(v.abs() < 1e-14, "{g:?}");
                }
            }
        }
    }

    #[test]
    fn distortion_gradient_matches_finite_differences() {
        for dim in [2, 3] {
            for (seed, delta) in [(1, 0.0), (2, 0.1), (3, 0.3), (4, 0.0)] {
                let mut f = sample_f(dim, seed);
                if delta > 0.0 {
                    // An inverted point: the regularised measure is finite.
                    for k in 0..dim {
                        f[0][k] = -f[0][k];
                    }
                }
                let (_, g) = distortion(dim, &f, delta).unwrap();
                let h = 1e-6;
                for i in 0..dim {
                    for k in 0..dim {
                        let (mut fp, mut fm) = (f, f);
                        fp[i][k] += h;
                        fm[i][k] -= h;
                        let fd = (distortion(dim, &fp, delta).unwrap().0 - distortion(dim, &fm, delta).unwrap().0)
                            / (2.0 * h);
                        assert!((fd - g[i][k]).abs() < 1e-6 * (1.0 + fd.abs()), "{dim} {i}{k}: {fd} vs {}", g[i][k]);
                    }
                }
            }
        }
    }

    #[test]
    fn distortion_is_infinite_for_inverted_points_without_regularisation_and_decreases_with_j_with_it() {
        let mut f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -0.2]];
        assert!(distortion(3, &f, 0.0).is_none());
        let a = distortion(3, &f, 0.1).unwrap().0;
        f[2][2] = 0.1;
        let b = distortion(3, &f, 0.1).unwrap().0;
        assert!(b < a, "{a} {b}");
    }

    #[test]
    fn distortion_is_invariant_under_rotation() {
        let f = sample_f(3, 7);
        let (c, s) = (0.6f64, 0.8f64);
        let r = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
        let rf = linalg::matmul(3, &r, &f);
        let (a, b) = (distortion(3, &f, 0.0).unwrap().0, distortion(3, &rf, 0.0).unwrap().0);
        assert!((a - b).abs() < 1e-13);
    }
}
