//! The orthonormal Proriol–Koornwinder–Dubiner–Owens (PKDO) basis on the unit
//! reference simplices, with exact gradients everywhere, vertices included.
//!
//! In collapsed coordinates (Hesthaven & Warburton, eqs. (6.6) and (10.4),
//! `Simplex2DP` / `Simplex3DP`) the basis reads
//! ψ_ij = √2 P̂_i(a) P̂_j^{(2i+1,0)}(b) (1−b)^i and
//! ψ_ijk = 2√2 P̂_i(a) P̂_j^{(2i+1,0)}(b) P̂_k^{(2i+2j+2,0)}(c) (1−b)^i (1−c)^{i+j}
//! on the bi-unit simplex, with P̂ the L²-normalised Jacobi polynomials. The
//! singular factors of the collapse cancel against the powers of (1 − b) and
//! (1 − c): with the homogeneous Jacobi polynomials H_n(x, t) = t^n P_n(x / t)
//! and the unit-simplex coordinates (ξ, η, ζ),
//!
//! triangle: P_i(a)(1−b)^i = 2^i H_i^{(0,0)}(2ξ+η−1, 1−η), P_j(b) = H_j^{(2i+1,0)}(2η−1, 1);
//!
//! tetrahedron: P_i(a)(1−b)^i P_j(b)(1−c)^{i+j}
//!   = 2^{2i+j} H_i^{(0,0)}(2ξ+η+ζ−1, 1−η−ζ) H_j^{(2i+1,0)}(2η+ζ−1, 1−ζ),
//!
//! polynomials in (ξ, η, ζ) computed by the homogeneous three-term recurrence
//! c_n H_n = (2n+α+β−1)[(2n+α+β)(2n+α+β−2) x + (α²−β²) t] H_{n−1}
//!         − 2(n+α−1)(n+β−1)(2n+α+β) t² H_{n−2},  c_n = 2n(n+α+β)(2n+α+β−2).
//! No division by (1 − η) or (1 − η − ζ) ever happens, and gradients come
//! from the same recurrence in forward-mode (dual-number) arithmetic, so they
//! are exact to round-off at every point of the closed simplex.
//!
//! The basis is scaled to be orthonormal on the *unit* simplex
//! (∫ ψ_k ψ_l = δ_kl over the triangle of area 1/2 or the tet of volume 1/6).

use super::simplex::Simplex;
use std::ops::{Add, Mul, Sub};

/// A value with its gradient with respect to (ξ, η, ζ).
#[derive(Debug, Clone, Copy)]
struct Dual {
    v: f64,
    d: [f64; 3],
}

impl From<f64> for Dual {
    fn from(v: f64) -> Dual {
        Dual { v, d: [0.0; 3] }
    }
}
impl Add for Dual {
    type Output = Dual;
    fn add(self, o: Dual) -> Dual {
        Dual { v: self.v + o.v, d: [self.d[0] + o.d[0], self.d[1] + o.d[1], self.d[2] + o.d[2]] }
    }
}
impl Sub for Dual {
    type Output = Dual;
    fn sub(self, o: Dual) -> Dual {
        Dual { v: self.v - o.v, d: [self.d[0] - o.d[0], self.d[1] - o.d[1], self.d[2] - o.d[2]] }
    }
}
impl Mul for Dual {
    type Output = Dual;
    fn mul(self, o: Dual) -> Dual {
        Dual {
            v: self.v * o.v,
            d: [
                self.d[0] * o.v + self.v * o.d[0],
                self.d[1] * o.v + self.v * o.d[1],
                self.d[2] * o.v + self.v * o.d[2],
            ],
        }
    }
}
impl Mul<f64> for Dual {
    type Output = Dual;
    fn mul(self, s: f64) -> Dual {
        Dual { v: self.v * s, d: [self.d[0] * s, self.d[1] * s, self.d[2] * s] }
    }
}

/// The arithmetic the recurrences need: plain values (f64) or values with gradients (Dual).
trait Num:
    Copy + From<f64> + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Mul<f64, Output = Self>
{
}
impl Num for f64 {}
impl Num for Dual {}

/// H_0 ..= H_n of the homogeneous Jacobi polynomials H_m(x, t) = t^m P_m^{(α,0)}(x/t),
/// each divided by √γ_m, γ_m = 2^{α+1} / (2m+α+1) (the L² norm² of P_m^{(α,0)}
/// for integer α ≥ 0), written into `out[..=n]`.
fn homogeneous_jacobi<T: Num>(n: usize, alpha: f64, x: T, t: T, out: &mut [T]) {
    let b = 0.0;
    out[0] = T::from(1.0);
    if n >= 1 {
        out[1] = (x * (alpha + b + 2.0) + t * (alpha - b)) * 0.5;
    }
    let t2 = t * t;
    for m in 2..=n {
        let mf = m as f64;
        let s = 2.0 * mf + alpha + b;
        let c = 2.0 * mf * (mf + alpha + b) * (s - 2.0);
        let c1 = (s - 1.0) * s * (s - 2.0) / c;
        let c2 = (s - 1.0) * (alpha * alpha - b * b) / c;
        let c3 = 2.0 * (mf + alpha - 1.0) * (mf + b - 1.0) * s / c;
        out[m] = (x * c1 + t * c2) * out[m - 1] - t2 * out[m - 2] * c3;
    }
    for (m, h) in out.iter_mut().enumerate().take(n + 1) {
        let gamma = 2f64.powf(alpha + 1.0) / (2.0 * m as f64 + alpha + 1.0);
        *h = *h * (1.0 / gamma.sqrt());
    }
}

/// The orthonormal PKDO basis of total degree ≤ `order` on a unit simplex.
///
/// Basis functions are numbered triangle: (i, j) with i ascending, then j;
/// tetrahedron: (i, j, k) likewise — the order of [`OrthonormalBasis::degrees`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OrthonormalBasis {
    pub simplex: Simplex,
    pub order: usize,
}

impl OrthonormalBasis {
    /// The basis of degree ≤ `order` on `simplex`.
    pub fn new(simplex: Simplex, order: usize) -> OrthonormalBasis {
        OrthonormalBasis { simplex, order }
    }

    /// Number of basis functions, equal to [`Simplex::n_nodes`].
    pub fn len(&self) -> usize {
        self.simplex.n_nodes(self.order)
    }

    /// Always false: there is at least the constant.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The (i, j, k) degrees of each basis function (k = 0 for the triangle);
    /// ψ has total degree i + j + k.
    pub fn degrees(&self) -> Vec<[usize; 3]> {
        let p = self.order;
        let mut out = Vec::with_capacity(self.len());
        for i in 0..=p {
            for j in 0..=p - i {
                match self.simplex {
                    Simplex::Tri => out.push([i, j, 0]),
                    Simplex::Tet => out.extend((0..=p - i - j).map(|k| [i, j, k])),
                }
            }
        }
        out
    }

    /// values[k] = ψ_k(ξ).
    pub fn eval_into(&self, xi: &[f64; 3], values: &mut [f64]) {
        let x = [xi[0], xi[1], xi[2]];
        self.eval_generic(x, values);
    }

    /// values[k] = ψ_k(ξ) and grads[k * dim + i] = ∂ψ_k/∂ξ_i, dim = simplex.dim().
    pub fn eval_grad_into(&self, xi: &[f64; 3], values: &mut [f64], grads: &mut [f64]) {
        let dim = self.simplex.dim();
        let mut x = [Dual::from(0.0); 3];
        for (i, xv) in x.iter_mut().enumerate() {
            *xv = Dual::from(xi[i]);
            if i < dim {
                xv.d[i] = 1.0;
            }
        }
        let n = self.len();
        let mut duals = vec![Dual::from(0.0); n];
        self.eval_generic(x, &mut duals);
        for (k, d) in duals.iter().enumerate() {
            values[k] = d.v;
            grads[k * dim..(k + 1) * dim].copy_from_slice(&d.d[..dim]);
        }
    }

    fn eval_generic<T: Num>(&self, x: [T; 3], out: &mut [T]) {
        let p = self.order;
        let one = T::from(1.0);
        let mut h1 = vec![T::from(0.0); p + 1];
        let mut h2 = vec![T::from(0.0); p + 1];
        let mut h3 = vec![T::from(0.0); p + 1];
        let (xi, eta, zeta) = (x[0], x[1], x[2]);
        let mut idx = 0;
        match self.simplex {
            Simplex::Tri => {
                // √2 (bi-unit normalisation) × 2 (unit-triangle area 1/2 vs 2).
                let scale = 2.0 * std::f64::consts::SQRT_2;
                homogeneous_jacobi(p, 0.0, xi * 2.0 + eta - one, one - eta, &mut h1);
                let b = eta * 2.0 - one;
                for i in 0..=p {
                    homogeneous_jacobi(p - i, (2 * i + 1) as f64, b, one, &mut h2);
                    let hi = h1[i] * (scale * 2f64.powi(i as i32));
                    for &hj in &h2[..=p - i] {
                        out[idx] = hi * hj;
                        idx += 1;
                    }
                }
            }
            Simplex::Tet => {
                // 2√2 (bi-unit normalisation) × 2√2 (unit-tet volume 1/6 vs 4/3).
                let scale = 8.0;
                let t1 = one - eta - zeta;
                homogeneous_jacobi(p, 0.0, xi * 2.0 + eta + zeta - one, t1, &mut h1);
                let (x2, t2) = (eta * 2.0 + zeta - one, one - zeta);
                let c = zeta * 2.0 - one;
                for i in 0..=p {
                    homogeneous_jacobi(p - i, (2 * i + 1) as f64, x2, t2, &mut h2);
                    for j in 0..=p - i {
                        let hij = h1[i] * h2[j] * (scale * 2f64.powi((2 * i + j) as i32));
                        homogeneous_jacobi(p - i - j, (2 * i + 2 * j + 2) as f64, c, one, &mut h3);
                        for &hk in &h3[..=p - i - j] {
                            out[idx] = hij * hk;
                            idx += 1;
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::simplex_rule;

    #[test]
    fn pkdo_basis_is_orthonormal_on_unit_simplex() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in [1, 4, 8] {
                let basis = OrthonormalBasis::new(simplex, p);
                let rule = simplex_rule(simplex, 2 * p);
                let n = basis.len();
                let mut gram = vec![0.0; n * n];
                let mut v = vec![0.0; n];
                for (x, w) in rule.points.iter().zip(&rule.weights) {
                    basis.eval_into(x, &mut v);
                    for k in 0..n {
                        for l in 0..n {
                            gram[k * n + l] += w * v[k] * v[l];
                        }
                    }
                }
                for k in 0..n {
                    for l in 0..n {
                        let e = if k == l { 1.0 } else { 0.0 };
                        assert!(
                            (gram[k * n + l] - e).abs() < 1e-12,
                            "{simplex:?} p={p} ({k},{l}): {}",
                            gram[k * n + l]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn pkdo_degrees_match_total_degree_count() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in 0..=10 {
                let b = OrthonormalBasis::new(simplex, p);
                let d = b.degrees();
                assert_eq!(d.len(), b.len());
                assert!(d.iter().all(|g| g.iter().sum::<usize>() <= p));
            }
        }
    }

    #[test]
    fn pkdo_gradient_matches_central_differences() {
        let h = 1e-6;
        for simplex in [Simplex::Tri, Simplex::Tet] {
            let dim = simplex.dim();
            let p = 7;
            let basis = OrthonormalBasis::new(simplex, p);
            let n = basis.len();
            let (mut v, mut g) = (vec![0.0; n], vec![0.0; n * dim]);
            let (mut vp, mut vm) = (vec![0.0; n], vec![0.0; n]);
            for x in [[0.2, 0.3, 0.1], [0.05, 0.6, 0.2], [0.31, 0.07, 0.5]] {
                let mut x = x;
                if dim == 2 {
                    x[2] = 0.0;
                }
                basis.eval_grad_into(&x, &mut v, &mut g);
                for i in 0..dim {
                    let (mut xp, mut xm) = (x, x);
                    xp[i] += h;
                    xm[i] -= h;
                    basis.eval_into(&xp, &mut vp);
                    basis.eval_into(&xm, &mut vm);
                    for k in 0..n {
                        let fd = (vp[k] - vm[k]) / (2.0 * h);
                        let scale = 1.0 + g[k * dim + i].abs();
                        assert!((fd - g[k * dim + i]).abs() < 1e-6 * scale, "{simplex:?} k={k}");
                    }
                }
            }
        }
    }

    #[test]
    fn pkdo_values_are_finite_at_the_collapsed_vertex() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            let basis = OrthonormalBasis::new(simplex, 6);
            let dim = simplex.dim();
            let (mut v, mut g) = (vec![0.0; basis.len()], vec![0.0; basis.len() * dim]);
            for x in simplex.vertex_coords() {
                basis.eval_grad_into(x, &mut v, &mut g);
                assert!(v.iter().chain(&g).all(|c| c.is_finite()));
            }
        }
    }
}
