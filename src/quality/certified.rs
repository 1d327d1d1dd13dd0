//! Certified validity: bounds on the Jacobian determinant between the nodes.
//!
//! On a simplex of order p in dimension d, det J(ξ) = det(Σ_a x_a ⊗ ∇N_a(ξ))
//! is a polynomial of degree q = d(p − 1). Written in the Bernstein basis of
//! degree q, det J = Σ_α b_α B_α(λ) with B_α ≥ 0 and Σ B_α = 1, so
//! min_α b_α ≤ det J ≤ max_α b_α everywhere on the element, and the vertex
//! coefficients are the values there (Johnen, Remacle & Geuzaine, J. Comput.
//! Phys. 2013). The coefficients come from the values at the order-q
//! equispaced lattice through the inverse Bernstein–Vandermonde matrix.
//! Where the bound cannot decide the sign (some b_α ≤ 0 while every value is
//! positive), the element is bisected along its longest edge and each half
//! expanded again (the restriction of det J to a sub-simplex is a polynomial
//! of the same degree), down to [`MAX_DEPTH`] levels.
//!
//! An element is certified valid when every coefficient of every leaf is
//! positive, and certified invalid when det J ≤ 0 at some point evaluated.

use faer::linalg::solvers::DenseSolveCore;
use faer::Mat;

use crate::mapping;
use crate::reference::{LagrangeBasis, Simplex};

/// Largest subdivision depth (2^MAX_DEPTH leaves at most).
pub const MAX_DEPTH: usize = 10;

/// Largest Bernstein expansion computed (lattice points): order 7 in 3D, 10 in 2D.
pub const MAX_LATTICE_POINTS: usize = 1400;

/// The verdict on one element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// det J > 0 everywhere (every Bernstein coefficient positive).
    Valid,
    /// det J ≤ 0 at a point.
    Invalid,
    /// Neither could be shown within [`MAX_DEPTH`] subdivisions.
    Uncertain,
}

/// Bounds on det J over one element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CertifiedJacobian {
    /// A lower bound of det J over the element.
    pub min_lower: f64,
    /// An upper bound of det J over the element.
    pub max_upper: f64,
    pub verdict: Verdict,
}

impl CertifiedJacobian {
    /// A lower bound of the scaled Jacobian Q3 = min det J / max det J: the
    /// ratio of the bounds if the element is certified valid, −1 if it is
    /// invalid, and min_lower / max_upper (≤ 0) if uncertain.
    pub fn q3_lower(&self) -> f64 {
        match self.verdict {
            Verdict::Valid => self.min_lower / self.max_upper,
            Verdict::Invalid => -1.0,
            Verdict::Uncertain => (self.min_lower / self.max_upper).clamp(-1.0, 0.0),
        }
    }
}

/// The Bernstein expansion of det J for one basis (built once, used for every
/// element of that order).
#[derive(Debug, Clone)]
pub struct JacobianBernstein {
    simplex: Simplex,
    /// Barycentric coordinates α/q of the lattice points.
    lattice: Vec<[f64; 4]>,
    /// Inverse Bernstein–Vandermonde matrix, row-major m×m.
    vinv: Vec<f64>,
    /// Reference gradients of the basis at the lattice of the whole element
    /// (most elements need no subdivision): grads[(i * n_basis + a) * dim + c].
    root_grads: Vec<f64>,
}

fn multi_indices(n_bary: usize, q: usize) -> Vec<[usize; 4]> {
    let mut out = Vec::new();
    let mut a = [0usize; 4];
    fn rec(k: usize, left: usize, n: usize, a: &mut [usize; 4], out: &mut Vec<[usize; 4]>) {
        if k == n - 1 {
            a[k] = left;
            out.push(*a);
            return;
        }
        for v in (0..=left).rev() {
            a[k] = v;
            rec(k + 1, left - v, n, a, out);
        }
    }
    rec(0, q, n_bary, &mut a, &mut out);
    out
}

fn bernstein(alpha: &[usize; 4], lambda: &[f64; 4], n_bary: usize, q: usize) -> f64 {
    let mut v = (1..=q).map(|k| k as f64).product::<f64>();
    for i in 0..n_bary {
        v /= (1..=alpha[i]).map(|k| k as f64).product::<f64>();
        v *= lambda[i].powi(alpha[i] as i32);
    }
    v
}

impl JacobianBernstein {
    /// The expansion for elements of `basis`; None if it would exceed
    /// [`MAX_LATTICE_POINTS`].
    pub fn new(basis: &LagrangeBasis) -> Option<JacobianBernstein> {
        let simplex = basis.simplex();
        let d = simplex.dim();
        let q = d * (basis.order().max(1) - 1);
        let alphas = multi_indices(d + 1, q);
        let m = alphas.len();
        if m > MAX_LATTICE_POINTS {
            return None;
        }
        let lattice: Vec<[f64; 4]> = alphas
            .iter()
            .map(|a| {
                let mut l = [0.0; 4];
                for i in 0..=d {
                    l[i] = if q == 0 { 1.0 / (d + 1) as f64 } else { a[i] as f64 / q as f64 };
                }
                l
            })
            .collect();
        let mut v = Mat::<f64>::zeros(m, m);
        for (i, l) in lattice.iter().enumerate() {
            for (j, a) in alphas.iter().enumerate() {
                v[(i, j)] = bernstein(a, l, d + 1, q);
            }
        }
        let inv = v.partial_piv_lu().inverse();
        let vinv = (0..m * m).map(|k| inv[(k / m, k % m)]).collect();
        let points: Vec<[f64; 3]> = lattice.iter().map(|l| [l[1], l[2], if d == 3 { l[3] } else { 0.0 }]).collect();
        let root_grads = basis.tabulate(&points).grads;
        Some(JacobianBernstein { simplex, lattice, vinv, root_grads })
    }

    /// Bounds and verdict for the element with node coordinates `xe`
    /// (`dim` components per node, in the basis's node order).
    pub fn certify(&self, basis: &LagrangeBasis, xe: &[f64]) -> CertifiedJacobian {
        let d = self.simplex.dim();
        let m = self.lattice.len();
        let mut grads = vec![0.0; basis.len() * d];
        let mut values = vec![0.0; m];
        let mut coef = vec![0.0; m];
        // Leaves: d + 1 vertices in reference coordinates, depth.
        let root: Vec<[f64; 3]> = self.simplex.vertex_coords().to_vec();
        let mut stack = vec![(root, 0usize)];
        let (mut lower, mut upper) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut found_nonpositive = false;
        let mut uncertain = false;
        while let Some((verts, depth)) = stack.pop() {
            let nd = basis.len() * d;
            for (i, l) in self.lattice.iter().enumerate() {
                let g = if depth == 0 {
                    &self.root_grads[i * nd..(i + 1) * nd]
                } else {
                    let mut xi = [0.0; 3];
                    for (k, v) in verts.iter().enumerate() {
                        for c in 0..d {
                            xi[c] += l[k] * v[c];
                        }
                    }
                    basis.eval_grad_into(&xi, &mut grads);
                    &grads[..]
                };
                values[i] = mapping::det(d, &mapping::jacobian(d, xe, g));
            }
            for (i, c) in coef.iter_mut().enumerate() {
                *c = self.vinv[i * m..(i + 1) * m].iter().zip(&values).map(|(a, b)| a * b).sum();
            }
            let min_b = coef.iter().copied().fold(f64::INFINITY, f64::min);
            let max_b = coef.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let min_v = values.iter().copied().fold(f64::INFINITY, f64::min);
            if min_v.is_nan() || min_v <= 0.0 {
                found_nonpositive = true;
            }
            if min_b <= 0.0 && !found_nonpositive && depth < MAX_DEPTH {
                let (a, b) = longest_edge(&verts, d);
                let mid: [f64; 3] = std::array::from_fn(|c| 0.5 * (verts[a][c] + verts[b][c]));
                let mut left = verts.clone();
                let mut right = verts;
                left[b] = mid;
                right[a] = mid;
                stack.push((left, depth + 1));
                stack.push((right, depth + 1));
                continue;
            }
            if min_b <= 0.0 && !found_nonpositive {
                uncertain = true;
            }
            lower = lower.min(min_b);
            upper = upper.max(max_b);
        }
        let verdict = if found_nonpositive {
            Verdict::Invalid
        } else if uncertain {
            Verdict::Uncertain
        } else {
            Verdict::Valid
        };
        CertifiedJacobian { min_lower: lower, max_upper: upper, verdict }
    }
}

fn longest_edge(verts: &[[f64; 3]], d: usize) -> (usize, usize) {
    let mut best = (0, 1, -1.0);
    for a in 0..verts.len() {
        for b in a + 1..verts.len() {
            let l: f64 = (0..d).map(|c| (verts[a][c] - verts[b][c]).powi(2)).sum();
            if l > best.2 {
                best = (a, b, l);
            }
        }
    }
    (best.0, best.1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{NodeSet, NodeSpacing};

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64) / ((1u64 << 53) as f64)
    }

    /// Straight element nodes of the reference simplex, plus `amp` times a random field.
    fn perturbed(basis: &LagrangeBasis, amp: f64, seed: &mut u64) -> Vec<f64> {
        let d = basis.simplex().dim();
        let nodes = basis.nodes();
        let mut xe = Vec::new();
        for (i, x) in nodes.coords.iter().enumerate() {
            for c in 0..d {
                // Vertices stay put, as in a curved mesh.
                let r = if i <= d { 0.0 } else { amp * (2.0 * lcg(seed) - 1.0) };
                xe.push(x[c] + r);
            }
        }
        xe
    }

    #[test]
    fn bernstein_coefficients_reproduce_det_j_and_bound_it() {
        for (simplex, p) in [(Simplex::Tri, 2), (Simplex::Tri, 4), (Simplex::Tet, 2), (Simplex::Tet, 3)] {
            let basis = LagrangeBasis::new(&NodeSet::new(simplex, p, NodeSpacing::Optimal));
            let jb = JacobianBernstein::new(&basis).unwrap();
            let mut seed = 7;
            let xe = perturbed(&basis, 0.05, &mut seed);
            let c = jb.certify(&basis, &xe);
            assert_eq!(c.verdict, Verdict::Valid, "{simplex:?} p={p}");
            // det J at random points lies within the bounds.
            let d = simplex.dim();
            let mut g = vec![0.0; basis.len() * d];
            for _ in 0..500 {
                let mut l: Vec<f64> = (0..=d).map(|_| -lcg(&mut seed).ln()).collect();
                let s: f64 = l.iter().sum();
                l.iter_mut().for_each(|x| *x /= s);
                let xi = [l[1], l[2], if d == 3 { l[3] } else { 0.0 }];
                basis.eval_grad_into(&xi, &mut g);
                let dj = mapping::det(d, &mapping::jacobian(d, &xe, &g));
                assert!(c.min_lower <= dj + 1e-12 && dj <= c.max_upper + 1e-12, "{dj} outside bounds");
            }
        }
    }

    #[test]
    fn an_affine_element_has_exact_bounds() {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tet, 3, NodeSpacing::Optimal));
        let jb = JacobianBernstein::new(&basis).unwrap();
        // x = 2ξ: det J = 8 everywhere.
        let xe: Vec<f64> = basis.nodes().coords.iter().flat_map(|x| x.iter().map(|v| 2.0 * v)).collect();
        let c = jb.certify(&basis, &xe);
        assert_eq!(c.verdict, Verdict::Valid);
        assert!((c.min_lower - 8.0).abs() < 1e-9 && (c.max_upper - 8.0).abs() < 1e-9, "{c:?}");
        assert!((c.q3_lower() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn an_element_folded_at_a_node_is_invalid() {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tri, 2, NodeSpacing::Optimal));
        let jb = JacobianBernstein::new(&basis).unwrap();
        let mut xe: Vec<f64> = basis.nodes().coords.iter().flat_map(|x| [x[0], x[1]]).collect();
        // Pull the mid-node of edge (1, 2) past the opposite vertex.
        let k = (3..6).find(|&i| (xe[2 * i] - 0.5).abs() < 1e-12 && (xe[2 * i + 1] - 0.5).abs() < 1e-12).unwrap();
        xe[2 * k] = -0.3;
        xe[2 * k + 1] = -0.3;
        assert_eq!(jb.certify(&basis, &xe).verdict, Verdict::Invalid);
    }
}
