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
/// What the energy needs of one straight element: the inverse of its affine
/// Jacobian, which maps the reference gradients to physical ones.
#[derive(Debug, Clone)]
pub struct ElementSamples {
    w_inv: Mat3,
}

/// Lanes of the sums over the sample points in [`SampleRule::energy_grad`]:
/// independent partial sums, which the compiler keeps in vector registers.
const LANES: usize = 8;

thread_local! {
    /// F (then w ∂μ/∂F) at every sample point, `(i * dim + k) * n_points + q`.
    static PER_POINT: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Sample points of the energy with weights, and the reference gradients
/// of the basis there, shared by every cell.
///
/// The physical gradients are not stored per cell: at p = 8 in 3D they
/// would be 1.2 MB per cell, read at every evaluation of a patch's energy;
/// F = (Σ_a x_a ⊗ ∇_ξ N_a) W⁻¹ reads the reference ones from cache instead.
#[derive(Debug, Clone)]
pub struct SampleRule {
    pub dim: usize,
    pub n_basis: usize,
    pub weights: Vec<f64>,
    /// `ref_grads[(a * dim + k) * n_points + q]` = ∂N_a/∂ξ_k at point q: the
    /// points innermost, so that the loops over them run in SIMD lanes.
    ref_grads: Vec<f64>,
}

impl SampleRule {
    /// The rule of `weights` with the reference gradients `grads`, laid out
    /// as [`crate::reference::Tabulation::grads`] (`(q * n_basis + a) * dim + k`).
    pub fn new(dim: usize, n_basis: usize, weights: Vec<f64>, grads: &[f64]) -> SampleRule {
        let nq = weights.len();
        let mut ref_grads = vec![0.0; grads.len()];
        for (q, at_point) in grads.chunks_exact(n_basis * dim).enumerate() {
            for (ak, &g) in at_point.iter().enumerate() {
                ref_grads[ak * nq + q] = g;
            }
        }
        SampleRule { dim, n_basis, weights, ref_grads }
    }

    pub fn n_points(&self) -> usize {
        self.weights.len()
    }

    /// The straight element whose vertices are the first dim + 1 nodes of
    /// `xs`; None if it is degenerate.
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
        (det != 0.0 && det.is_finite()).then_some(ElementSamples { w_inv })
    }

    /// F at point q of an element with node coordinates `xe`.
    #[cfg(test)]
    pub fn deformation(&self, e: &ElementSamples, xe: &[f64], q: usize) -> Mat3 {
        let (dim, nq) = (self.dim, self.n_points());
        let mut f = [[0.0; 3]; 3];
        for a in 0..self.n_basis {
            for i in 0..dim {
                for k in 0..dim {
                    for j in 0..dim {
                        f[i][k] += xe[a * dim + i] * self.ref_grads[(a * dim + j) * nq + q] * e.w_inv[j][k];
                    }
                }
            }
        }
        f
    }

    /// Σ_a x_a,i ∂N_a/∂ξ_j at every sample point into `fq[(i * D + j) * n_points + q]`.
    #[inline(always)]
    fn reference_deformations_into<const D: usize>(&self, xe: &[f64], fq: &mut Vec<f64>) {
        let nq = self.n_points();
        fq.clear();
        fq.resize(D * D * nq, 0.0);
        for (a, xa) in xe[..self.n_basis * D].chunks_exact(D).enumerate() {
            for j in 0..D {
                let g = &self.ref_grads[(a * D + j) * nq..][..nq];
                for (i, &x) in xa.iter().enumerate() {
                    for (f, &gq) in fq[(i * D + j) * nq..][..nq].iter_mut().zip(g) {
                        *f += x * gq;
                    }
                }
            }
        }
    }

    /// F = F_ref W⁻¹ at point q, F_ref out of [`Self::reference_deformations_into`].
    #[inline(always)]
    fn point<const D: usize>(fq: &[f64], nq: usize, q: usize, w_inv: &Mat3) -> Mat3 {
        let mut f = [[0.0; 3]; 3];
        for (i, row) in f.iter_mut().enumerate().take(D) {
            for (k, v) in row.iter_mut().enumerate().take(D) {
                for (j, w) in w_inv.iter().enumerate().take(D) {
                    *v += fq[(i * D + j) * nq + q] * w[k];
                }
            }
        }
        f
    }

    /// Smallest J = det F over the sample points of the element.
    pub fn min_det(&self, e: &ElementSamples, xe: &[f64]) -> f64 {
        match self.dim {
            2 => self.min_det_in::<2>(e, xe),
            _ => self.min_det_in::<3>(e, xe),
        }
    }

    fn min_det_in<const D: usize>(&self, e: &ElementSamples, xe: &[f64]) -> f64 {
        let nq = self.n_points();
        PER_POINT.with_borrow_mut(|fq| {
            self.reference_deformations_into::<D>(xe, fq);
            (0..nq).map(|q| linalg::det(D, &Self::point::<D>(fq, nq, q, &e.w_inv))).fold(f64::INFINITY, f64::min)
        })
    }

    /// The element energy Σ_q w_q μ(F_q), adding its gradient with respect to
    /// the node coordinates `xe` into `grad` (same layout as `xe`); None if
    /// it is infinite.
    pub fn energy_grad(&self, e: &ElementSamples, xe: &[f64], delta: f64, grad: &mut [f64]) -> Option<f64> {
        // The optimisation's inner loop: one copy per dimension, so that the
        // loops over it are unrolled, each compiled for AVX2 where the
        // processor has it.
        PER_POINT.with_borrow_mut(|fq| {
            crate::linalg::with_avx2(
                #[inline(always)]
                || match self.dim {
                    2 => self.energy_grad_in::<2>(e, xe, delta, grad, fq),
                    _ => self.energy_grad_in::<3>(e, xe, delta, grad, fq),
                },
            )
        })
    }

    /// [`Self::energy_grad`] in dimension `D`, with `fq` for the values at
    /// the points: F at every point (sums over the nodes, in SIMD lanes over
    /// the points), μ and P = ∂μ/∂F point by point, then ∂/∂x_a,i = Σ_q w_q
    /// Σ_j (P W⁻ᵀ)_ij ∂N_a/∂ξ_j (sums over the points, in [`LANES`] partial
    /// sums).
    #[inline(always)]
    fn energy_grad_in<const D: usize>(
        &self,
        e: &ElementSamples,
        xe: &[f64],
        delta: f64,
        grad: &mut [f64],
        fq: &mut Vec<f64>,
    ) -> Option<f64> {
        let (nq, w_inv) = (self.n_points(), &e.w_inv);
        self.reference_deformations_into::<D>(xe, fq);
        let mut total = 0.0;
        for (q, &w) in self.weights.iter().enumerate() {
            let (mu, p) = distortion(D, &Self::point::<D>(fq, nq, q, w_inv), delta)?;
            total += w * mu;
            for (i, row) in p.iter().enumerate().take(D) {
                for (j, wj) in w_inv.iter().enumerate().take(D) {
                    let v: f64 = (0..D).map(|k| row[k] * wj[k]).sum();
                    fq[(i * D + j) * nq + q] = w * v;
                }
            }
        }
        for (a, out) in grad[..self.n_basis * D].chunks_exact_mut(D).enumerate() {
            for (i, o) in out.iter_mut().enumerate() {
                let mut lanes = [0.0f64; LANES];
                let mut tail = 0.0;
                for j in 0..D {
                    let pw = &fq[(i * D + j) * nq..][..nq];
                    let g = &self.ref_grads[(a * D + j) * nq..][..nq];
                    let (pc, gc) = (pw.chunks_exact(LANES), g.chunks_exact(LANES));
                    tail += pc.remainder().iter().zip(gc.remainder()).map(|(x, y)| x * y).sum::<f64>();
                    for (x, y) in pc.zip(gc) {
                        for l in 0..LANES {
                            lanes[l] += x[l] * y[l];
                        }
                    }
                }
                *o += lanes.iter().sum::<f64>() + tail;
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

    #[test]
    fn the_avx2_copy_gives_bitwise_the_portable_energy_and_gradient() {
        use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};
        for (simplex, p) in [(Simplex::Tri, 4), (Simplex::Tet, 5)] {
            let basis = LagrangeBasis::new(&NodeSet::new(simplex, p, NodeSpacing::Optimal));
            let points = NodeSet::new(simplex, 2 * p + 1, NodeSpacing::Equispaced);
            let tab = basis.tabulate(&points.coords);
            let rule = SampleRule::new(tab.dim, tab.n_basis, vec![1.0 / points.len() as f64; points.len()], &tab.grads);
            let dim = simplex.dim();
            let xs: Vec<f64> = basis.nodes().coords.iter().flat_map(|c| c[..dim].to_vec()).collect();
            let xe: Vec<f64> =
                xs.iter().enumerate().map(|(k, x)| x + 0.02 * ((k * 7919 % 101) as f64 / 101.0 - 0.5)).collect();
            let e = rule.element(&xs).unwrap();
            let (mut dispatched, mut portable) = (vec![0.0; xe.len()], vec![0.0; xe.len()]);
            let v = rule.energy_grad(&e, &xe, 0.1, &mut dispatched).unwrap();
            let w = match dim {
                2 => rule.energy_grad_in::<2>(&e, &xe, 0.1, &mut portable, &mut Vec::new()),
                _ => rule.energy_grad_in::<3>(&e, &xe, 0.1, &mut portable, &mut Vec::new()),
            }
            .unwrap();
            assert_eq!(v.to_bits(), w.to_bits(), "{simplex:?}: {v} vs {w}");
            assert!(dispatched.iter().zip(&portable).all(|(a, b)| a.to_bits() == b.to_bits()), "{simplex:?}");
            assert!(dispatched.iter().any(|&g| g != 0.0));
        }
    }

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
