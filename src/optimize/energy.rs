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
use crate::mapping::{self, PointGradients};

/// Weight γ of the size term.
pub const SIZE_WEIGHT: f64 = 0.5;

/// μ(F) and ∂μ/∂F at one point, or None where it is infinite (δ = 0 and
/// J ≤ 0, or a non-finite F): [`distortion_lanes`] with one lane.
#[cfg(test)]
pub fn distortion(dim: usize, f: &Mat3, delta: f64) -> Option<(f64, Mat3)> {
    let lanes = f.map(|row| row.map(|v| [v]));
    let (mut mu, mut g) = ([0.0], [[[0.0]; 3]; 3]);
    let finite = match dim {
        2 => distortion_lanes::<2, 1>(&lanes, delta, 1, &mut mu, &mut g),
        _ => distortion_lanes::<3, 1>(&lanes, delta, 1, &mut mu, &mut g),
    };
    finite.then(|| (mu[0], g.map(|row| row.map(|v| v[0]))))
}

/// L matrices of D×D, lane l of entry (i, k) at `[i][k][l]`.
type MatLanes<const L: usize> = [[[f64; L]; 3]; 3];

/// μ(F) and ∂μ/∂F (module docs) at L points at once, lane l being the point with F =
/// `f[·][·][l]`: μ into `mu`, ∂μ/∂F into `g`. Every lane takes the same
/// operations in the same order, with no branch but where the cube root
/// leaves the normal range, so that the compiler runs the lanes in vector
/// registers. False if μ is infinite at one of the first `live` lanes (the
/// others are not looked at).
#[inline(always)]
fn distortion_lanes<const D: usize, const L: usize>(
    f: &MatLanes<L>,
    delta: f64,
    live: usize,
    mu: &mut [f64; L],
    g: &mut MatLanes<L>,
) -> bool {
    // Each statement is one loop over the lanes, with no branch in it: the
    // form the compiler's vectoriser takes. The expressions are those of
    // `linalg::det` and `linalg::cofactor`, in the same order.
    let m = |i: usize, k: usize| &f[i][k];
    let j = if D == 2 {
        let (a, b, c, e) = (m(0, 0), m(1, 1), m(0, 1), m(1, 0));
        lanes::<L>(|l| a[l] * b[l] - c[l] * e[l])
    } else {
        let minor = |r: usize, c0: usize, c1: usize| {
            let (a, b, c, e) = (m(r, c0), m(r + 1, c1), m(r, c1), m(r + 1, c0));
            lanes::<L>(|l| a[l] * b[l] - c[l] * e[l])
        };
        let (m12_12, m12_02, m12_01) = (minor(1, 1, 2), minor(1, 0, 2), minor(1, 0, 1));
        let (a, b, c) = (m(0, 0), m(0, 1), m(0, 2));
        lanes::<L>(|l| a[l] * m12_12[l] - b[l] * m12_02[l] + c[l] * m12_01[l])
    };
    let s = lanes::<L>(|l| (j[l] * j[l] + 4.0 * delta * delta).sqrt());
    let sigma = lanes::<L>(|l| 0.5 * (j[l] + s[l]));
    // σ^(2/d) without powf (a tenth of the optimisation's time when it was
    // powf), nor Rust's correctly rounded cbrt (as much again).
    let scale = if D == 3 {
        let c = linalg::cbrt_positive_lanes(&sigma);
        lanes::<L>(|l| c[l] * c[l])
    } else {
        sigma
    };
    let d = D as f64;
    let mut ff = [0.0; L];
    for row in &f[..D] {
        for v in &row[..D] {
            for l in 0..L {
                ff[l] += v[l] * v[l];
            }
        }
    }
    let shape = lanes::<L>(|l| ff[l] / (d * scale[l]));
    let size = lanes::<L>(|l| (j[l] * j[l] + 1.0) / (2.0 * sigma[l]) - 1.0);
    *mu = lanes::<L>(|l| shape[l] + SIZE_WEIGHT * size[l]);
    // dσ/dJ = σ / s (s > 0 where σ > 0).
    let dmu_dj = lanes::<L>(|l| {
        let dsigma = sigma[l] / s[l];
        let dmu_dsigma =
            -(2.0 / d) * shape[l] / sigma[l] - SIZE_WEIGHT * (j[l] * j[l] + 1.0) / (2.0 * sigma[l] * sigma[l]);
        SIZE_WEIGHT * j[l] / sigma[l] + dmu_dsigma * dsigma
    });
    for i in 0..D {
        for k in 0..D {
            // The cofactor of entry (i, k).
            let cof = if D == 2 {
                let (v, sign) = (m(1 - i, 1 - k), if i == k { 1.0 } else { -1.0 });
                lanes::<L>(|l| if sign > 0.0 { v[l] } else { -v[l] })
            } else {
                let (i1, i2, k1, k2) = ((i + 1) % 3, (i + 2) % 3, (k + 1) % 3, (k + 2) % 3);
                let (a, b, c, e) = (m(i1, k1), m(i2, k2), m(i1, k2), m(i2, k1));
                lanes::<L>(|l| a[l] * b[l] - c[l] * e[l])
            };
            let fik = m(i, k);
            g[i][k] = lanes::<L>(|l| 2.0 * fik[l] / (d * scale[l]) + dmu_dj[l] * cof[l]);
        }
    }
    // σ ≤ 0 (J ≤ 0 with δ = 0), or a non-finite F.
    let bad = lanes::<L>(|l| f64::from(!(sigma[l] > 0.0 && sigma[l].is_finite() && mu[l].is_finite())));
    bad[..live].iter().all(|&b| b == 0.0)
}

/// `[op(0), .., op(L - 1)]`.
#[inline(always)]
fn lanes<const L: usize>(op: impl Fn(usize) -> f64) -> [f64; L] {
    std::array::from_fn(op)
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

/// Sample points whose μ and ∂μ/∂F [`SampleRule::energy_grad`] computes at
/// once, one per vector lane.
const POINT_LANES: usize = 4;

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
    /// ∂N_a/∂ξ_k at the points, the points innermost.
    grads: PointGradients,
}

impl SampleRule {
    /// The rule of `weights` with the reference gradients `grads`, laid out
    /// as [`crate::reference::Tabulation::grads`] (`(q * n_basis + a) * dim + k`).
    pub fn new(dim: usize, n_basis: usize, weights: Vec<f64>, grads: &[f64]) -> SampleRule {
        SampleRule { dim, n_basis, weights, grads: PointGradients::new(dim, n_basis, grads) }
    }

    pub fn n_points(&self) -> usize {
        self.weights.len()
    }

    /// The straight element whose vertices are the first dim + 1 nodes of
    /// `xs`; None if it is degenerate.
    pub fn element(&self, xs: &[f64]) -> Option<ElementSamples> {
        let (w_inv, det) = mapping::straight_inverse(self.dim, xs);
        (det != 0.0 && det.is_finite()).then_some(ElementSamples { w_inv })
    }

    /// F at point q of an element with node coordinates `xe`.
    #[cfg(test)]
    pub fn deformation(&self, e: &ElementSamples, xe: &[f64], q: usize) -> Mat3 {
        let dim = self.dim;
        let mut f = [[0.0; 3]; 3];
        for a in 0..self.n_basis {
            for i in 0..dim {
                for k in 0..dim {
                    for j in 0..dim {
                        f[i][k] += xe[a * dim + i] * self.grads.of(a, j)[q] * e.w_inv[j][k];
                    }
                }
            }
        }
        f
    }

    /// F = F_ref W⁻¹ at point q, F_ref out of [`PointGradients::jacobians_into`].
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
            self.grads.jacobians_into::<D>(xe, fq);
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
                    2 => self.energy_grad_in::<2, POINT_LANES>(e, xe, delta, grad, fq),
                    _ => self.energy_grad_in::<3, POINT_LANES>(e, xe, delta, grad, fq),
                },
            )
        })
    }

    /// [`Self::energy_grad`] in dimension `D`, with `fq` for the values at
    /// the points: F at every point (sums over the nodes, in SIMD lanes over
    /// the points), μ and P = ∂μ/∂F L points at a time, then
    /// ∂/∂x_a,i = Σ_q w_q Σ_j (P W⁻ᵀ)_ij ∂N_a/∂ξ_j (sums over the points, in
    /// [`LANES`] partial sums).
    #[inline(always)]
    fn energy_grad_in<const D: usize, const L: usize>(
        &self,
        e: &ElementSamples,
        xe: &[f64],
        delta: f64,
        grad: &mut [f64],
        fq: &mut Vec<f64>,
    ) -> Option<f64> {
        let (nq, w_inv) = (self.n_points(), &e.w_inv);
        self.grads.jacobians_into::<D>(xe, fq);
        let mut total = 0.0;
        for q0 in (0..nq).step_by(L) {
            let live = L.min(nq - q0);
            // F = F_ref W⁻¹ at the live lanes; the others the identity.
            let mut f: MatLanes<L> = std::array::from_fn(|i| std::array::from_fn(|k| [f64::from(i == k); L]));
            for i in 0..D {
                for k in 0..D {
                    for (l, v) in f[i][k][..live].iter_mut().enumerate() {
                        *v = 0.0;
                        for (j, w) in w_inv.iter().enumerate().take(D) {
                            *v += fq[(i * D + j) * nq + q0 + l] * w[k];
                        }
                    }
                }
            }
            let (mut mu, mut p) = ([0.0; L], [[[0.0; L]; 3]; 3]);
            if !distortion_lanes::<D, L>(&f, delta, live, &mut mu, &mut p) {
                return None;
            }
            for (l, m) in mu[..live].iter().enumerate() {
                total += self.weights[q0 + l] * m;
            }
            for i in 0..D {
                for (j, wj) in w_inv.iter().enumerate().take(D) {
                    for l in 0..live {
                        let v: f64 = (0..D).map(|k| p[i][k][l] * wj[k]).sum();
                        fq[(i * D + j) * nq + q0 + l] = self.weights[q0 + l] * v;
                    }
                }
            }
        }
        // The D components of node a together, so that each gradient chunk
        // is loaded once for all of them.
        for (a, out) in grad[..self.n_basis * D].chunks_exact_mut(D).enumerate() {
            let mut lanes = [[0.0f64; LANES]; D];
            let mut tail = [0.0; D];
            for j in 0..D {
                let g = self.grads.of(a, j);
                let gc = g.chunks_exact(LANES);
                for i in 0..D {
                    let pw = &fq[(i * D + j) * nq..][..nq];
                    tail[i] += pw[nq - gc.remainder().len()..].iter().zip(gc.remainder()).map(|(x, y)| x * y).sum::<f64>();
                }
                for (c, y) in gc.enumerate() {
                    for (i, lanes) in lanes.iter_mut().enumerate() {
                        let x = &fq[(i * D + j) * nq + c * LANES..][..LANES];
                        for l in 0..LANES {
                            lanes[l] += x[l] * y[l];
                        }
                    }
                }
            }
            for ((o, lanes), tail) in out.iter_mut().zip(&lanes).zip(tail) {
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
    fn the_avx2_copy_and_one_point_at_a_time_give_bitwise_the_same_energy_and_gradient() {
        use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};
        // 55 and 364 sample points: a last batch of 3 points and a full one,
        // and 7 and 4 points past the last chunk of LANES in the sums over the nodes.
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
            for delta in [0.0, 0.1] {
                let mut dispatched = vec![0.0; xe.len()];
                let v = rule.energy_grad(&e, &xe, delta, &mut dispatched).unwrap();
                let (mut lanes, mut single) = (vec![0.0; xe.len()], vec![0.0; xe.len()]);
                let (w, u) = match dim {
                    2 => (
                        rule.energy_grad_in::<2, POINT_LANES>(&e, &xe, delta, &mut lanes, &mut Vec::new()),
                        rule.energy_grad_in::<2, 1>(&e, &xe, delta, &mut single, &mut Vec::new()),
                    ),
                    _ => (
                        rule.energy_grad_in::<3, POINT_LANES>(&e, &xe, delta, &mut lanes, &mut Vec::new()),
                        rule.energy_grad_in::<3, 1>(&e, &xe, delta, &mut single, &mut Vec::new()),
                    ),
                };
                let (w, u) = (w.unwrap(), u.unwrap());
                assert_eq!(v.to_bits(), w.to_bits(), "{simplex:?}: {v} vs {w}");
                assert_eq!(v.to_bits(), u.to_bits(), "{simplex:?}: {v} vs {u}");
                let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
                assert!(same(&dispatched, &lanes) && same(&dispatched, &single), "{simplex:?}");
                assert!(dispatched.iter().any(|&g| g != 0.0));
                // And the same energy as the point-by-point definition.
                let reference = rule.energy(&e, &xe, delta).unwrap();
                assert!((v - reference).abs() <= 1e-12 * reference, "{v} vs {reference}");
            }
        }
    }

    #[test]
    fn an_inverted_point_in_any_batch_makes_the_unregularised_energy_infinite() {
        use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tri, 2, NodeSpacing::Optimal));
        let xs: Vec<f64> = basis.nodes().coords.iter().flat_map(|c| c[..2].to_vec()).collect();
        let e = SampleRule::new(2, 6, vec![1.0], &basis.tabulate(&[[0.0; 3]]).grads).element(&xs).unwrap();
        // The mid-edge node of edge (1, 2) pulled far past vertex 0: det J < 0
        // near vertex 0 only. One sample point of nine, in each of its places.
        let mut xe = xs.clone();
        let far = (0..6).find(|&a| (xs[2 * a] - 0.5).abs() < 1e-12 && (xs[2 * a + 1] - 0.5).abs() < 1e-12).unwrap();
        xe[2 * far] = -1.5;
        xe[2 * far + 1] = -1.5;
        for place in 0..9 {
            let mut coords = vec![[0.3, 0.3, 0.0]; 9];
            coords[place] = [0.0, 0.0, 0.0];
            let rule = SampleRule::new(2, 6, vec![1.0 / 9.0; 9], &basis.tabulate(&coords).grads);
            let mut g = vec![0.0; 12];
            assert!(rule.min_det(&e, &xe) < 0.0);
            assert!(rule.energy_grad(&e, &xe, 0.0, &mut g).is_none(), "inverted point {place}");
            assert!(rule.energy_grad(&e, &xe, 0.1, &mut g).is_some());
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
