//! Quadrature rules on the reference simplices and on the unit interval.
//!
//! [`simplex_rule`] takes the fully symmetric rules of Witherden & Vincent
//! (2015), tabulated in `symmetric_data.rs`, up to the degree they are tabulated
//! with positive weights and interior points (20 on the triangle, 18 on the
//! tetrahedron): 24 points against 64 for degree 6 on the tetrahedron, 81
//! against 216 for degree 10. Above, and in [`collapsed_rule`], the rules are
//! collapsed (Stroud conical) products of Gauss–Jacobi rules: the Duffy map
//! from the cube [−1, 1]^d onto the simplex puts a factor (1 − b) (triangle)
//! or (1 − b)(1 − c)² (tetrahedron) in the Jacobian, which is absorbed into the
//! Jacobi weight of the collapsed directions. Both kinds are exact, have
//! positive weights and all their points strictly inside.

use super::symmetric_data::{TET, TRI};
use super::QuadratureRule;
use crate::jacobi::gauss_jacobi;
use crate::reference::Simplex;

/// Number of Gauss points per direction for exactness to `degree`: n = ⌈(degree + 1)/2⌉ (at least 1).
fn points_for_degree(degree: usize) -> usize {
    (degree + 2) / 2
}

/// Gauss–Legendre rule on [0, 1] exact for polynomials of degree ≤ `degree`;
/// points are stored as [t, 0, 0] and the weights sum to 1.
///
/// ```
/// let r = hocurve::quadrature::line_rule(3);
/// let i: f64 = r.points.iter().zip(&r.weights).map(|(p, w)| w * p[0].powi(3)).sum();
/// assert!((i - 0.25).abs() < 1e-15);
/// ```
pub fn line_rule(degree: usize) -> QuadratureRule {
    let n = points_for_degree(degree);
    let (x, w) = gauss_jacobi(n, 0.0, 0.0);
    QuadratureRule {
        points: x.iter().map(|&xi| [0.5 * (1.0 + xi), 0.0, 0.0]).collect(),
        weights: w.iter().map(|&wi| 0.5 * wi).collect(),
    }
}

/// A rule on the reference simplex exact for polynomials of total degree ≤
/// `degree`, with positive weights summing to the reference volume and all
/// points strictly inside: the smallest tabulated symmetric rule of degree ≥
/// `degree`, or [`collapsed_rule`] where that has fewer points (degree 3 on
/// the triangle) and above the table.
///
/// ```
/// use hocurve::{quadrature::simplex_rule, reference::Simplex};
/// let r = simplex_rule(Simplex::Tet, 6);
/// assert_eq!(r.len(), 24);
/// let volume: f64 = r.weights.iter().sum();
/// assert!((volume - 1.0 / 6.0).abs() < 1e-15);
/// ```
pub fn simplex_rule(simplex: Simplex, degree: usize) -> QuadratureRule {
    let table = match simplex {
        Simplex::Tri => TRI,
        Simplex::Tet => TET,
    };
    let collapsed_points = points_for_degree(degree).pow(simplex.dim() as u32);
    match table.get(degree.max(1) - 1).filter(|v| v.len() / 4 <= collapsed_points) {
        Some(values) => QuadratureRule {
            points: values.chunks_exact(4).map(|v| [v[0], v[1], v[2]]).collect(),
            weights: values.chunks_exact(4).map(|v| v[3]).collect(),
        },
        None => collapsed_rule(simplex, degree),
    }
}

/// A collapsed rule on the reference simplex exact for polynomials of total
/// degree ≤ `degree`, with positive weights summing to the reference volume
/// and all points strictly inside. More points than [`simplex_rule`], on a
/// tensor pattern that reaches closer to the vertices: the quality measures
/// sample the Jacobian on it.
///
/// Triangle: ξ = (1+a)(1−b)/4, η = (1+b)/2, dξ dη = (1−b)/8 da db, so
/// w = w_a w_b / 8 with (a, w_a) Gauss–Legendre and (b, w_b) Gauss–Jacobi(1, 0).
///
/// Tetrahedron: ξ = (1+a)(1−b)(1−c)/8, η = (1+b)(1−c)/4, ζ = (1+c)/2,
/// dξ dη dζ = (1−b)(1−c)²/64 da db dc, so w = w_a w_b w_c / 64 with
/// Gauss–Jacobi(0,0), (1,0) and (2,0) rules in a, b, c.
///
/// Each direction uses n = ⌈(degree+1)/2⌉ points (n^d points in all).
///
/// ```
/// use hocurve::{quadrature::collapsed_rule, reference::Simplex};
/// let r = collapsed_rule(Simplex::Tri, 2);
/// let area: f64 = r.weights.iter().sum();
/// assert!((area - 0.5).abs() < 1e-15);
/// ```
pub fn collapsed_rule(simplex: Simplex, degree: usize) -> QuadratureRule {
    let n = points_for_degree(degree);
    let (xa, wa) = gauss_jacobi(n, 0.0, 0.0);
    let (xb, wb) = gauss_jacobi(n, 1.0, 0.0);
    match simplex {
        Simplex::Tri => {
            let mut points = Vec::with_capacity(n * n);
            let mut weights = Vec::with_capacity(n * n);
            for (b, wbj) in xb.iter().zip(&wb) {
                for (a, wai) in xa.iter().zip(&wa) {
                    points.push([0.25 * (1.0 + a) * (1.0 - b), 0.5 * (1.0 + b), 0.0]);
                    weights.push(wai * wbj / 8.0);
                }
            }
            QuadratureRule { points, weights }
        }
        Simplex::Tet => {
            let (xc, wc) = gauss_jacobi(n, 2.0, 0.0);
            let mut points = Vec::with_capacity(n * n * n);
            let mut weights = Vec::with_capacity(n * n * n);
            for (c, wck) in xc.iter().zip(&wc) {
                for (b, wbj) in xb.iter().zip(&wb) {
                    for (a, wai) in xa.iter().zip(&wa) {
                        points.push([
                            0.125 * (1.0 + a) * (1.0 - b) * (1.0 - c),
                            0.25 * (1.0 + b) * (1.0 - c),
                            0.5 * (1.0 + c),
                        ]);
                        weights.push(wai * wbj * wck / 64.0);
                    }
                }
            }
            QuadratureRule { points, weights }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn factorial(n: usize) -> f64 {
        (1..=n).map(|k| k as f64).product()
    }

    /// Checks every monomial ξ^a η^b ζ^c, a + b + c ≤ deg, against
    /// ∫ ξ^a η^b ζ^c = a! b! c! / (a + b + c + dim)!, for every degree up to
    /// 2p = 20 (both the symmetric table and the collapsed rules above it).
    fn check_exact_to_degree(simplex: Simplex, rule_of: fn(Simplex, usize) -> QuadratureRule) {
        let dim = simplex.dim();
        for deg in 1..=20 {
            let rule = rule_of(simplex, deg);
            assert!(!rule.is_empty());
            assert!(rule.weights.iter().all(|&w| w > 0.0));
            let vol: f64 = rule.weights.iter().sum();
            assert!((vol - simplex.volume()).abs() < 1e-15);
            for x in &rule.points {
                let l0 = 1.0 - x[..dim].iter().sum::<f64>();
                assert!(l0 > 0.0 && x[..dim].iter().all(|&c| c > 0.0));
                assert!(x[dim..].iter().all(|&c| c == 0.0));
            }
            let cmax = if dim == 3 { deg } else { 0 };
            for a in 0..=deg {
                for b in 0..=deg - a {
                    for c in 0..=cmax.min(deg - a - b) {
                        let q: f64 = rule
                            .points
                            .iter()
                            .zip(&rule.weights)
                            .map(|(x, w)| w * x[0].powi(a as i32) * x[1].powi(b as i32) * x[2].powi(c as i32))
                            .sum();
                        let e = factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + dim);
                        assert!((q - e).abs() <= 1e-13 * e, "{simplex:?} degree {deg} ({a},{b},{c}): {q} vs {e}");
                    }
                }
            }
        }
    }

    #[test]
    fn tri_quadrature_exact_to_degree() {
        check_exact_to_degree(Simplex::Tri, simplex_rule);
        check_exact_to_degree(Simplex::Tri, collapsed_rule);
    }

    #[test]
    fn tet_quadrature_exact_to_degree() {
        check_exact_to_degree(Simplex::Tet, simplex_rule);
        check_exact_to_degree(Simplex::Tet, collapsed_rule);
    }

    #[test]
    fn symmetric_rules_are_smaller_and_invariant_under_vertex_permutations() {
        for (simplex, table_len) in [(Simplex::Tri, 20), (Simplex::Tet, 18)] {
            let dim = simplex.dim();
            for deg in 1..=table_len {
                let (r, c) = (simplex_rule(simplex, deg), collapsed_rule(simplex, deg));
                assert!(r.len() <= c.len(), "{simplex:?} degree {deg}: {} > {}", r.len(), c.len());
                // Barycentric coordinates and weight: every point has an image
                // when the first and last vertex are swapped.
                let key = |x: &[f64; 3], w: f64, swap: bool| {
                    let mut l: Vec<f64> = x[..dim].to_vec();
                    l.push(1.0 - l.iter().sum::<f64>());
                    if swap {
                        l.swap(0, dim);
                    }
                    l.push(w);
                    l
                };
                let a: Vec<Vec<f64>> = r.points.iter().zip(&r.weights).map(|(x, &w)| key(x, w, false)).collect();
                let b: Vec<Vec<f64>> = r.points.iter().zip(&r.weights).map(|(x, &w)| key(x, w, true)).collect();
                for p in &a {
                    let matched = b.iter().any(|q| p.iter().zip(q).all(|(s, t)| (s - t).abs() < 1e-12));
                    assert!(matched, "{simplex:?} degree {deg}: {p:?} has no mirror image");
                }
            }
            assert_eq!(simplex_rule(simplex, table_len + 1).len(), collapsed_rule(simplex, table_len + 1).len());
        }
    }

    #[test]
    fn simplex_rule_low_degrees_are_valid() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for deg in 0..=3 {
                let r = simplex_rule(simplex, deg);
                let vol: f64 = r.weights.iter().sum();
                assert!((vol - simplex.volume()).abs() < 1e-15);
                assert!(r.weights.iter().all(|&w| w > 0.0));
            }
        }
    }

    #[test]
    fn line_rule_exact_to_degree() {
        for deg in 0..=21 {
            let r = line_rule(deg);
            assert!(r.weights.iter().all(|&w| w > 0.0));
            assert!(r.points.iter().all(|p| p[0] > 0.0 && p[0] < 1.0 && p[1] == 0.0));
            for k in 0..=deg {
                let q: f64 = r.points.iter().zip(&r.weights).map(|(p, w)| w * p[0].powi(k as i32)).sum();
                let e = 1.0 / (k + 1) as f64;
                assert!((q - e).abs() < 1e-14 * e, "deg={deg} k={k}");
            }
        }
    }
}
