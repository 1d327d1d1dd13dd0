//! Nodal Lagrange bases on the reference simplices.
//!
//! With the orthonormal PKDO basis ψ_k and the generalised Vandermonde matrix
//! V_{ak} = ψ_k(x_a) of a node set, the Lagrange basis is
//! N_a(ξ) = Σ_k (V⁻¹)_{ka} ψ_k(ξ) (Hesthaven & Warburton, eq. (6.5)), so that
//! N_a(x_b) = δ_ab. V⁻¹ is formed once, by faer's LU with partial pivoting.

use super::nodes::NodeSet;
use super::orthonormal::OrthonormalBasis;
use super::simplex::Simplex;
use faer::linalg::matmul::matmul;
use faer::linalg::solvers::DenseSolveCore;
use faer::{Accum, Mat, MatMut, MatRef, Par};

/// The Lagrange basis on a node set, built from the orthonormal PKDO/Dubiner
/// basis and its Vandermonde matrix: N_a(ξ) = Σ_k (V⁻¹)_{ka} ψ_k(ξ).
///
/// ```
/// use hocurve::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};
/// let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tri, 3, NodeSpacing::Optimal));
/// let mut n = vec![0.0; basis.len()];
/// basis.eval_into(&[0.2, 0.3, 0.0], &mut n);
/// assert!((n.iter().sum::<f64>() - 1.0).abs() < 1e-13);
/// ```
#[derive(Debug, Clone)]
pub struct LagrangeBasis {
    nodes: NodeSet,
    ortho: OrthonormalBasis,
    /// V⁻¹ row-major: vinv[k * n + a] = (V⁻¹)_{ka}.
    vinv: Vec<f64>,
}

/// Values and reference gradients of a basis at a list of points.
#[derive(Debug, Clone)]
pub struct Tabulation {
    pub n_points: usize,
    pub n_basis: usize,
    pub dim: usize,
    /// values[q * n_basis + a]
    pub values: Vec<f64>,
    /// grads[(q * n_basis + a) * dim + i]
    pub grads: Vec<f64>,
}

impl LagrangeBasis {
    /// The Lagrange basis interpolating at `nodes`.
    pub fn new(nodes: &NodeSet) -> LagrangeBasis {
        let ortho = OrthonormalBasis::new(nodes.simplex, nodes.order);
        let n = nodes.len();
        debug_assert_eq!(n, ortho.len());
        let mut v = Mat::<f64>::zeros(n, n);
        let mut psi = vec![0.0; n];
        for (a, x) in nodes.coords.iter().enumerate() {
            ortho.eval_into(x, &mut psi);
            for (k, &p) in psi.iter().enumerate() {
                v[(a, k)] = p;
            }
        }
        let inv = v.partial_piv_lu().inverse();
        let mut vinv = vec![0.0; n * n];
        for k in 0..n {
            for a in 0..n {
                vinv[k * n + a] = inv[(k, a)];
            }
        }
        LagrangeBasis { nodes: nodes.clone(), ortho, vinv }
    }

    /// The reference simplex.
    pub fn simplex(&self) -> Simplex {
        self.nodes.simplex
    }

    /// The polynomial order p.
    pub fn order(&self) -> usize {
        self.nodes.order
    }

    /// Number of basis functions (= number of nodes).
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Always false: a node set has at least its vertices.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The node set the basis interpolates at.
    pub fn nodes(&self) -> &NodeSet {
        &self.nodes
    }

    /// values[a] = N_a(xi), values.len() == len()
    pub fn eval_into(&self, xi: &[f64; 3], values: &mut [f64]) {
        let n = self.len();
        let mut psi = vec![0.0; n];
        self.ortho.eval_into(xi, &mut psi);
        self.combine_values(&psi, &mut values[..n]);
    }

    /// grads[a * dim + i] = ∂N_a/∂ξ_i, dim = simplex.dim()
    pub fn eval_grad_into(&self, xi: &[f64; 3], grads: &mut [f64]) {
        let n = self.len();
        let dim = self.simplex().dim();
        let mut psi = vec![0.0; n];
        let mut dpsi = vec![0.0; n * dim];
        self.ortho.eval_grad_into(xi, &mut psi, &mut dpsi);
        self.combine_grads(&dpsi, &mut grads[..n * dim]);
    }

    /// Values and gradients of every basis function at every point.
    ///
    /// Both are products with V⁻¹ of the orthonormal basis's table, formed
    /// by faer's matrix product: at p = 10 in 3D (286 functions, ~3000
    /// points) the table is a billion multiply-adds.
    pub fn tabulate(&self, points: &[[f64; 3]]) -> Tabulation {
        let n = self.len();
        let dim = self.simplex().dim();
        let m = points.len();
        // psi[q * n + k] and, per direction i, dpsi[i][q * n + k].
        let mut psi = vec![0.0; m * n];
        let mut dpsi = vec![vec![0.0; m * n]; dim];
        let (mut p1, mut d1) = (vec![0.0; n], vec![0.0; n * dim]);
        for (q, x) in points.iter().enumerate() {
            self.ortho.eval_grad_into(x, &mut p1, &mut d1);
            psi[q * n..(q + 1) * n].copy_from_slice(&p1);
            for (i, d) in dpsi.iter_mut().enumerate() {
                for k in 0..n {
                    d[q * n + k] = d1[k * dim + i];
                }
            }
        }
        let vinv = MatRef::from_row_major_slice(&self.vinv, n, n);
        let product = |table: &[f64], out: &mut [f64]| {
            let lhs = MatRef::from_row_major_slice(table, m, n);
            let dst = MatMut::from_row_major_slice_mut(out, m, n);
            matmul(dst, Accum::Replace, lhs, vinv, 1.0, Par::Seq);
        };
        let mut values = vec![0.0; m * n];
        product(&psi, &mut values);
        let mut grads = vec![0.0; m * n * dim];
        let mut g = psi; // reused as the product's output
        for (i, d) in dpsi.iter().enumerate() {
            product(d, &mut g);
            for (qa, &v) in g.iter().enumerate() {
                grads[qa * dim + i] = v;
            }
        }
        Tabulation { n_points: m, n_basis: n, dim, values, grads }
    }

    /// out[a] = Σ_k psi[k] (V⁻¹)_{ka}.
    fn combine_values(&self, psi: &[f64], out: &mut [f64]) {
        let n = self.len();
        out.fill(0.0);
        for (k, &pk) in psi.iter().enumerate() {
            let row = &self.vinv[k * n..(k + 1) * n];
            for (o, &r) in out.iter_mut().zip(row) {
                *o += pk * r;
            }
        }
    }

    /// out[a * dim + i] = Σ_k dpsi[k * dim + i] (V⁻¹)_{ka}.
    fn combine_grads(&self, dpsi: &[f64], out: &mut [f64]) {
        let n = self.len();
        let dim = self.simplex().dim();
        out.fill(0.0);
        for k in 0..n {
            let row = &self.vinv[k * n..(k + 1) * n];
            let dk = &dpsi[k * dim..(k + 1) * dim];
            for (a, &r) in row.iter().enumerate() {
                for i in 0..dim {
                    out[a * dim + i] += dk[i] * r;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::NodeSpacing;

    const SPACINGS: [NodeSpacing; 2] = [NodeSpacing::Equispaced, NodeSpacing::Optimal];
    const SIMPLICES: [Simplex; 2] = [Simplex::Tri, Simplex::Tet];

    use crate::testing::Rng;

    /// A uniform-ish point of the closed simplex.
    fn point(rng: &mut Rng, simplex: Simplex) -> [f64; 3] {
        let dim = simplex.dim();
        loop {
            let mut x = [0.0; 3];
            for c in x.iter_mut().take(dim) {
                *c = rng.next();
            }
            if x.iter().sum::<f64>() <= 1.0 {
                return x;
            }
        }
    }

    /// A random polynomial of total degree p: Σ c_m ξ^a η^b ζ^c, with gradient.
    struct Poly {
        terms: Vec<([i32; 3], f64)>,
    }
    impl Poly {
        fn random(simplex: Simplex, p: usize, rng: &mut Rng) -> Poly {
            let cmax = if simplex == Simplex::Tet { p } else { 0 };
            let mut terms = Vec::new();
            for a in 0..=p {
                for b in 0..=p - a {
                    for c in 0..=cmax.min(p - a - b) {
                        terms.push(([a as i32, b as i32, c as i32], 2.0 * rng.next() - 1.0));
                    }
                }
            }
            Poly { terms }
        }
        fn value(&self, x: &[f64; 3]) -> f64 {
            self.terms.iter().map(|(e, c)| c * x[0].powi(e[0]) * x[1].powi(e[1]) * x[2].powi(e[2])).sum()
        }
        fn grad(&self, x: &[f64; 3]) -> [f64; 3] {
            let mut g = [0.0; 3];
            for (e, c) in &self.terms {
                for (i, gi) in g.iter_mut().enumerate() {
                    if e[i] > 0 {
                        let mut m = c * e[i] as f64;
                        for j in 0..3 {
                            m *= x[j].powi(if j == i { e[j] - 1 } else { e[j] });
                        }
                        *gi += m;
                    }
                }
            }
            g
        }
    }

    fn for_all_bases(orders: std::ops::RangeInclusive<usize>, mut f: impl FnMut(&LagrangeBasis)) {
        for simplex in SIMPLICES {
            for p in orders.clone() {
                for spacing in SPACINGS {
                    f(&LagrangeBasis::new(&NodeSet::new(simplex, p, spacing)));
                }
            }
        }
    }

    #[test]
    fn lagrange_basis_is_kronecker_at_nodes() {
        for_all_bases(1..=10, |b| {
            let t = b.tabulate(&b.nodes().coords);
            let n = b.len();
            for q in 0..n {
                for a in 0..n {
                    let e = if a == q { 1.0 } else { 0.0 };
                    assert!((t.values[q * n + a] - e).abs() < 1e-10, "{:?} p={}", b.simplex(), b.order());
                }
            }
        });
    }

    #[test]
    fn lagrange_basis_is_partition_of_unity_with_zero_gradient_sum() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for_all_bases(1..=10, |b| {
            let dim = b.simplex().dim();
            let mut pts: Vec<[f64; 3]> = (0..5).map(|_| point(&mut rng, b.simplex())).collect();
            pts.extend_from_slice(b.simplex().vertex_coords());
            let t = b.tabulate(&pts);
            for q in 0..t.n_points {
                let s: f64 = t.values[q * t.n_basis..(q + 1) * t.n_basis].iter().sum();
                assert!((s - 1.0).abs() < 1e-11);
                for i in 0..dim {
                    let g: f64 = (0..t.n_basis).map(|a| t.grads[(q * t.n_basis + a) * dim + i]).sum();
                    assert!(g.abs() < 1e-8, "{:?} p={} grad sum {g}", b.simplex(), b.order());
                }
            }
        });
    }

    #[test]
    fn interpolation_of_degree_p_polynomial_is_exact_with_gradient() {
        let mut rng = Rng(0x1234_5678_9abc_def1);
        for_all_bases(1..=10, |b| {
            let simplex = b.simplex();
            let dim = simplex.dim();
            let poly = Poly::random(simplex, b.order(), &mut rng);
            let coef: Vec<f64> = b.nodes().coords.iter().map(|x| poly.value(x)).collect();
            let mut pts: Vec<[f64; 3]> = (0..6).map(|_| point(&mut rng, simplex)).collect();
            pts.extend_from_slice(simplex.vertex_coords());
            pts.extend(b.nodes().coords.iter().step_by(7));
            let t = b.tabulate(&pts);
            let n = t.n_basis;
            for (q, x) in pts.iter().enumerate() {
                let u: f64 = (0..n).map(|a| coef[a] * t.values[q * n + a]).sum();
                assert!((u - poly.value(x)).abs() < 1e-10, "{simplex:?} p={} value", b.order());
                let g = poly.grad(x);
                for (i, &gi) in g.iter().enumerate().take(dim) {
                    let gu: f64 = (0..n).map(|a| coef[a] * t.grads[(q * n + a) * dim + i]).sum();
                    assert!(
                        (gu - gi).abs() < 1e-8 * (1.0 + gi.abs()),
                        "{simplex:?} p={} at {x:?}: {gu} vs {gi}",
                        b.order()
                    );
                }
            }
        });
    }

    #[test]
    fn lagrange_gradient_matches_central_differences() {
        let h = 1e-6;
        for_all_bases(1..=6, |b| {
            let dim = b.simplex().dim();
            let n = b.len();
            let (mut g, mut vp, mut vm) = (vec![0.0; n * dim], vec![0.0; n], vec![0.0; n]);
            for x in [[0.21, 0.33, 0.12], [0.1, 0.15, 0.6]] {
                let mut x = x;
                if dim == 2 {
                    x[2] = 0.0;
                }
                b.eval_grad_into(&x, &mut g);
                for i in 0..dim {
                    let (mut xp, mut xm) = (x, x);
                    xp[i] += h;
                    xm[i] -= h;
                    b.eval_into(&xp, &mut vp);
                    b.eval_into(&xm, &mut vm);
                    for a in 0..n {
                        let fd = (vp[a] - vm[a]) / (2.0 * h);
                        assert!((fd - g[a * dim + i]).abs() < 1e-6 * (1.0 + fd.abs()));
                    }
                }
            }
        });
    }

    #[test]
    fn tabulation_matches_pointwise_evaluation() {
        // The table is a matrix product, the pointwise path a plain sum: the
        // two agree to round-off, at low order and at the highest.
        for (simplex, p) in [(Simplex::Tri, 3), (Simplex::Tet, 3), (Simplex::Tri, 10), (Simplex::Tet, 10)] {
            let b = LagrangeBasis::new(&NodeSet::new(simplex, p, NodeSpacing::Optimal));
            let pts: [[f64; 3]; 4] = [[0.1, 0.2, 0.3], [0.0, 0.0, 1.0], [0.25, 0.5, 0.0], [1.0, 0.0, 0.0]];
            let pts: Vec<[f64; 3]> = pts
                .iter()
                .map(|x| if simplex == Simplex::Tri { [x[0], x[1].min(1.0 - x[0]), 0.0] } else { *x })
                .collect();
            let t = b.tabulate(&pts);
            let (n, dim) = (b.len(), simplex.dim());
            assert_eq!((t.n_points, t.n_basis, t.dim), (pts.len(), n, dim));
            let (mut v, mut g) = (vec![0.0; n], vec![0.0; n * dim]);
            let close = |a: &[f64], b: &[f64]| {
                let scale = 1.0 + b.iter().fold(0.0f64, |m: f64, x: &f64| m.max(x.abs()));
                a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * scale)
            };
            for (q, x) in pts.iter().enumerate() {
                b.eval_into(x, &mut v);
                b.eval_grad_into(x, &mut g);
                assert!(close(&t.values[q * n..(q + 1) * n], &v), "{simplex:?} p={p} values at {x:?}");
                assert!(close(&t.grads[q * n * dim..(q + 1) * n * dim], &g), "{simplex:?} p={p} gradients at {x:?}");
            }
        }
    }

    /// max over a fine lattice of Σ_a |N_a|.
    fn lebesgue_estimate(b: &LagrangeBasis, m: usize) -> f64 {
        let fine = NodeSet::new(b.simplex(), m, NodeSpacing::Equispaced);
        let t = b.tabulate(&fine.coords);
        (0..t.n_points)
            .map(|q| t.values[q * t.n_basis..(q + 1) * t.n_basis].iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    }

    #[test]
    fn optimal_nodes_have_smaller_lebesgue_constant_than_equispaced_at_p8() {
        for (simplex, m) in [(Simplex::Tri, 60), (Simplex::Tet, 24)] {
            let eq = LagrangeBasis::new(&NodeSet::new(simplex, 8, NodeSpacing::Equispaced));
            let opt = LagrangeBasis::new(&NodeSet::new(simplex, 8, NodeSpacing::Optimal));
            let (le, lo) = (lebesgue_estimate(&eq, m), lebesgue_estimate(&opt, m));
            assert!(lo < 0.5 * le, "{simplex:?}: optimal {lo} vs equispaced {le}");
        }
    }
}
