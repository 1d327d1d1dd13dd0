//! Certified validity: bounds on the Jacobian determinant between the nodes.
//!
//! On a simplex of order p in dimension d, det J(ξ) = det(Σ_a x_a ⊗ ∇N_a(ξ))
//! is a polynomial of degree q = d(p − 1). Written in the Bernstein basis of
//! degree q, det J = Σ_α b_α B^q_α(λ) with B_α ≥ 0 and Σ B_α = 1, so
//! min_α b_α ≤ det J ≤ max_α b_α everywhere on the element, and the vertex
//! coefficients are the values there (Johnen, Remacle & Geuzaine, J. Comput.
//! Phys. 2013).
//!
//! The coefficients are built exactly, with no sampling and no inverse of a
//! degree-q matrix:
//!
//! 1. the geometry in the Bernstein basis of degree p, x(λ) = Σ_α P_α B^p_α(λ),
//!    its control points P = C x from the node coordinates through the
//!    Lagrange → Bernstein matrix C (the inverse of the degree-p
//!    Bernstein–Vandermonde matrix at the basis's nodes, built once per order);
//! 2. the columns of ∂x/∂ξ, ∂x/∂ξ_i = p Σ_β (P_{β+e_i} − P_{β+e_0}) B^{p−1}_β
//!    (λ_0 = 1 − Σ ξ, λ_i = ξ_i);
//! 3. det J as the sum of products of d such polynomials, by the Bernstein
//!    product B^m_α B^n_β = [C(m,α) C(n,β) / C(m+n,α+β)] B^{m+n}_{α+β}
//!    (C multinomial): scaled coefficients b̃_α = C(m,α) b_α multiply like
//!    monomials, so a product is a convolution over precomputed index pairs
//!    (α, β) → α + β, and one division by C(q,γ) at the end. In 3D,
//!    det J = ∂_1x · (∂_2x × ∂_3x): the cross product first (degree
//!    2(p − 1)), then the dot product.
//!
//! Where the bound cannot decide the sign (some b_α ≤ 0 while no value found
//! is), the element is bisected along its longest edge: the coefficients of
//! each half come from those of the whole by de Casteljau's algorithm along
//! the lines of the edge (exact; the restriction of det J to a sub-simplex is
//! a polynomial of the same degree), down to [`MAX_DEPTH`] levels.
//!
//! An element is certified valid when every coefficient of every leaf is
//! positive, and certified invalid when det J ≤ 0 at some point evaluated:
//! the vertices of the leaves (their vertex coefficients) and, on every leaf
//! whose coefficients are not all positive, the points of the equispaced
//! lattice of order [`PROBE_ORDER`] (at most).

use faer::linalg::solvers::DenseSolveCore;
use faer::Mat;

use crate::reference::LagrangeBasis;

/// Largest subdivision depth (2^MAX_DEPTH leaves at most).
pub const MAX_DEPTH: usize = 10;

/// Order of the lattice at which det J is evaluated on an undecided leaf
/// (min(q, PROBE_ORDER); the leaf's vertices are always looked at).
pub const PROBE_ORDER: usize = 4;

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

/// The Bernstein expansion of det J for one basis: the conversion matrix,
/// product and subdivision tables, built once per (simplex, order, node set)
/// and used for every element.
#[derive(Debug, Clone)]
pub struct JacobianBernstein {
    dim: usize,
    /// Lagrange → Bernstein of degree p, row-major (n × n): P_α = Σ_a c[α n + a] x_a.
    to_bernstein: Vec<f64>,
    n_basis: usize,
    /// Index among the degree-p multi-indices of β + e_k, for β of degree
    /// p − 1: raise[β (d + 1) + k].
    raise: Vec<u32>,
    /// p C(p − 1, β): the scale of the derivative control points.
    deriv_scale: Vec<f64>,
    /// Degree-2(p − 1) index of β + γ, β and γ of degree p − 1: pair1[β n1 + γ].
    pair1: Vec<u32>,
    /// 3D: degree-q index of δ + β, δ of degree 2(p − 1): pair2[δ n1 + β].
    pair2: Vec<u32>,
    /// 1 / C(q, γ).
    unscale: Vec<f64>,
    /// The degree-q multi-indices (b_α is coefficient α of this list).
    alphas: Vec<[usize; 4]>,
    /// Index of q e_k (the coefficient that is the value at vertex k).
    corners: Vec<usize>,
    /// For each edge (k, l), k < l, in pair order: the lines of degree-q
    /// indices along it, each from α_l = 0 to α_l = s (consecutive in
    /// `line_index`, starting at `line_start[i]`).
    edges: Vec<EdgeLines>,
    /// B^q_α at the probe lattice: probe[i n_q + α].
    probe: Vec<f64>,
}

#[derive(Debug, Clone)]
struct EdgeLines {
    k: usize,
    l: usize,
    line_index: Vec<u32>,
    line_start: Vec<usize>,
}

/// Multi-indices (α_0, …, α_{n−1}) with |α| = q, in a fixed order.
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

/// Dense rank table of the multi-indices of degree q: index of α at
/// (α_1 (q + 1) + α_2) (q + 1) + α_3 (α_0 implied).
struct Ranks {
    q1: usize,
    rank: Vec<u32>,
}

impl Ranks {
    fn new(alphas: &[[usize; 4]], q: usize) -> Ranks {
        let q1 = q + 1;
        let mut rank = vec![u32::MAX; q1 * q1 * q1];
        for (i, a) in alphas.iter().enumerate() {
            rank[(a[1] * q1 + a[2]) * q1 + a[3]] = i as u32;
        }
        Ranks { q1, rank }
    }

    fn of(&self, a: &[usize; 4]) -> u32 {
        let r = self.rank[(a[1] * self.q1 + a[2]) * self.q1 + a[3]];
        debug_assert_ne!(r, u32::MAX);
        r
    }
}

fn factorial(n: usize) -> f64 {
    (1..=n).map(|k| k as f64).product()
}

/// The multinomial coefficient C(|α|, α) = |α|! / Π α_i!.
fn multinomial(alpha: &[usize; 4]) -> f64 {
    factorial(alpha.iter().sum()) / alpha.iter().map(|&a| factorial(a)).product::<f64>()
}

/// B^q_α(λ) = C(q, α) Π λ_i^α_i.
pub fn bernstein(alpha: &[usize; 4], lambda: &[f64; 4]) -> f64 {
    let mut v = multinomial(alpha);
    for i in 0..4 {
        v *= lambda[i].powi(alpha[i] as i32);
    }
    v
}

fn add(a: &[usize; 4], b: &[usize; 4]) -> [usize; 4] {
    std::array::from_fn(|i| a[i] + b[i])
}

/// Lagrange → Bernstein of degree p, row-major: the inverse of V_{aα} = B^p_α(node a).
fn lagrange_to_bernstein(basis: &LagrangeBasis, ap: &[[usize; 4]]) -> Vec<f64> {
    let n = basis.len();
    let nodes = basis.nodes();
    let mut v = Mat::<f64>::zeros(n, n);
    for a in 0..n {
        let l = nodes.barycentric(a);
        for (j, alpha) in ap.iter().enumerate() {
            v[(a, j)] = bernstein(alpha, &l);
        }
    }
    let inv = v.partial_piv_lu().inverse();
    (0..n * n).map(|k| inv[(k / n, k % n)]).collect()
}

/// For each β of degree p − 1 (`a1`) and k = 0..=d: the degree-p index of β + e_k.
fn raise_table(a1: &[[usize; 4]], rp: &Ranks, d: usize) -> Vec<u32> {
    let mut raise = vec![0u32; a1.len() * (d + 1)];
    for (b, beta) in a1.iter().enumerate() {
        for k in 0..=d {
            let mut e = [0; 4];
            e[k] = 1;
            raise[b * (d + 1) + k] = rp.of(&add(beta, &e));
        }
    }
    raise
}

/// For each edge (k, l), k < l: the lines of the degree-q indices along it.
fn edge_lines(alphas: &[[usize; 4]], rq: &Ranks, d: usize) -> Vec<EdgeLines> {
    let mut edges = Vec::new();
    for k in 0..=d {
        for l in k + 1..=d {
            let mut e = EdgeLines { k, l, line_index: Vec::new(), line_start: Vec::new() };
            for a in alphas.iter().filter(|a| a[l] == 0) {
                e.line_start.push(e.line_index.len());
                for i in 0..=a[k] {
                    let mut b = *a;
                    b[k] -= i;
                    b[l] += i;
                    e.line_index.push(rq.of(&b));
                }
            }
            edges.push(e);
        }
    }
    edges
}

/// B^q_α at the equispaced lattice of order min(q, PROBE_ORDER), one row per lattice point.
fn probe_table(alphas: &[[usize; 4]], d: usize, q: usize) -> Vec<f64> {
    let r = q.clamp(1, PROBE_ORDER);
    multi_indices(d + 1, r)
        .iter()
        .flat_map(|m| {
            let l: [f64; 4] = std::array::from_fn(|i| m[i] as f64 / r as f64);
            alphas.iter().map(move |a| bernstein(a, &l))
        })
        .collect()
}

impl JacobianBernstein {
    /// The expansion for elements of `basis` (any order and node set).
    pub fn new(basis: &LagrangeBasis) -> JacobianBernstein {
        let simplex = basis.simplex();
        let d = simplex.dim();
        let p = basis.order().max(1);
        let q = d * (p - 1);
        let n = basis.len();

        // 1. Lagrange → Bernstein of degree p: the inverse of V_{aα} = B^p_α(node a).
        let ap = multi_indices(d + 1, p);
        let to_bernstein = lagrange_to_bernstein(basis, &ap);

        // 2. Derivative tables.
        let rp = Ranks::new(&ap, p);
        let a1 = multi_indices(d + 1, p - 1);
        let raise = raise_table(&a1, &rp, d);
        let deriv_scale = a1.iter().map(|b| p as f64 * multinomial(b)).collect();

        // 3. Product tables.
        let a2 = multi_indices(d + 1, 2 * (p - 1));
        let r2 = Ranks::new(&a2, 2 * (p - 1));
        let pair1 = a1.iter().flat_map(|b| a1.iter().map(|g| r2.of(&add(b, g)))).collect();
        let alphas = multi_indices(d + 1, q);
        let rq = Ranks::new(&alphas, q);
        let pair2 =
            if d == 3 { a2.iter().flat_map(|dl| a1.iter().map(|b| rq.of(&add(dl, b)))).collect() } else { Vec::new() };
        let unscale = alphas.iter().map(|a| 1.0 / multinomial(a)).collect();

        // 4. Subdivision and probe tables.
        let corners = (0..=d)
            .map(|k| {
                let mut a = [0; 4];
                a[k] = q;
                rq.of(&a) as usize
            })
            .collect();
        let edges = edge_lines(&alphas, &rq, d);
        let probe = probe_table(&alphas, d, q);
        JacobianBernstein {
            dim: d,
            to_bernstein,
            n_basis: n,
            raise,
            deriv_scale,
            pair1,
            pair2,
            unscale,
            alphas,
            corners,
            edges,
            probe,
        }
    }

    /// The dimension d of the simplex.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of nodes of an element (of the basis).
    pub fn n_nodes(&self) -> usize {
        self.n_basis
    }

    /// The degree-q multi-indices, in the order of the coefficients.
    pub fn multi_indices(&self) -> &[[usize; 4]] {
        &self.alphas
    }

    /// Number of Bernstein coefficients, C(q + d, d).
    pub fn len(&self) -> usize {
        self.alphas.len()
    }

    /// Always false (a constant has one coefficient).
    pub fn is_empty(&self) -> bool {
        self.alphas.is_empty()
    }

    /// The Bernstein coefficients b_α of det J for the element with node
    /// coordinates `xe` (`dim` components per node, in the basis's node
    /// order), written into `coef` (length [`len`](Self::len)).
    pub fn coefficients_into(&self, xe: &[f64], coef: &mut [f64]) {
        let (d, n) = (self.dim, self.n_basis);
        debug_assert_eq!(xe.len(), n * d);
        // Control points of x, degree p.
        let ctrl: Vec<[f64; 3]> = (0..n)
            .map(|alpha| {
                let row = &self.to_bernstein[alpha * n..(alpha + 1) * n];
                let mut x = [0.0; 3];
                for (a, &c) in row.iter().enumerate() {
                    for k in 0..d {
                        x[k] += c * xe[a * d + k];
                    }
                }
                x
            })
            .collect();
        // Scaled control points of ∂x/∂ξ_i, degree p − 1: da[β][i][component].
        let n1 = self.deriv_scale.len();
        let da: Vec<[[f64; 3]; 3]> = (0..n1)
            .map(|b| {
                let r = &self.raise[b * (d + 1)..(b + 1) * (d + 1)];
                let s = self.deriv_scale[b];
                let x0 = ctrl[r[0] as usize];
                std::array::from_fn(|i| {
                    if i < d {
                        let xi = ctrl[r[i + 1] as usize];
                        std::array::from_fn(|c| s * (xi[c] - x0[c]))
                    } else {
                        [0.0; 3]
                    }
                })
            })
            .collect();
        coef.fill(0.0);
        if d == 2 {
            // det = ∂_1x ∂_2y − ∂_1y ∂_2x.
            for (b, u) in da.iter().enumerate() {
                let pairs = &self.pair1[b * n1..(b + 1) * n1];
                for (v, &t) in da.iter().zip(pairs) {
                    coef[t as usize] += u[0][0] * v[1][1] - u[0][1] * v[1][0];
                }
            }
        } else {
            // cross = ∂_2x × ∂_3x (degree 2(p − 1)), then det = ∂_1x · cross.
            let n2 = self.pair2.len() / n1;
            let mut cross = vec![[0.0f64; 3]; n2];
            for (b, u) in da.iter().enumerate() {
                let pairs = &self.pair1[b * n1..(b + 1) * n1];
                let u = u[1];
                for (v, &t) in da.iter().zip(pairs) {
                    let v = v[2];
                    let c = &mut cross[t as usize];
                    c[0] += u[1] * v[2] - u[2] * v[1];
                    c[1] += u[2] * v[0] - u[0] * v[2];
                    c[2] += u[0] * v[1] - u[1] * v[0];
                }
            }
            for (dl, c) in cross.iter().enumerate() {
                let pairs = &self.pair2[dl * n1..(dl + 1) * n1];
                for (u, &t) in da.iter().zip(pairs) {
                    let u = u[0];
                    coef[t as usize] += u[0] * c[0] + u[1] * c[1] + u[2] * c[2];
                }
            }
        }
        for (c, s) in coef.iter_mut().zip(&self.unscale) {
            *c *= s;
        }
    }

    /// Σ_α coef_α B^q_α(λ): the value of the expansion at barycentric `lambda`.
    pub fn eval(&self, coef: &[f64], lambda: &[f64; 4]) -> f64 {
        self.alphas.iter().zip(coef).map(|(a, c)| c * bernstein(a, lambda)).sum()
    }

    /// The coefficients of the two halves of the (sub-)simplex whose
    /// coefficients are `coef`, bisected at the midpoint of its edge
    /// (`k`, `l`): `left` has vertex l replaced by the midpoint, `right`
    /// vertex k (de Casteljau at t = 1/2 along each line of the edge).
    fn bisect_into(&self, edge: &EdgeLines, coef: &[f64], left: &mut [f64], right: &mut [f64], w: &mut Vec<f64>) {
        let starts = edge.line_start.iter().copied().chain(std::iter::once(edge.line_index.len()));
        let mut prev = None;
        for end in starts {
            if let Some(start) = prev {
                let line = &edge.line_index[start..end];
                let s = line.len() - 1;
                w.clear();
                w.extend(line.iter().map(|&i| coef[i as usize]));
                left[line[0] as usize] = w[0];
                right[line[s] as usize] = w[s];
                for r in 1..=s {
                    for j in 0..=s - r {
                        w[j] = 0.5 * (w[j] + w[j + 1]);
                    }
                    left[line[r] as usize] = w[0];
                    right[line[s - r] as usize] = w[s - r];
                }
            }
            prev = Some(end);
        }
    }

    /// Whether det J ≤ 0 (or is not finite) at a vertex or a probe point of
    /// the leaf with coefficients `coef`.
    fn finds_nonpositive(&self, coef: &[f64]) -> bool {
        let bad = |v: f64| v.is_nan() || v <= 0.0;
        self.corners.iter().any(|&i| bad(coef[i]))
            || self.probe.chunks_exact(coef.len()).any(|row| bad(row.iter().zip(coef).map(|(b, c)| b * c).sum()))
    }

    /// Bounds and verdict for the element with node coordinates `xe`
    /// (`dim` components per node, in the basis's node order).
    pub fn certify(&self, xe: &[f64]) -> CertifiedJacobian {
        let d = self.dim;
        let m = self.alphas.len();
        let mut root = vec![0.0; m];
        self.coefficients_into(xe, &mut root);
        if root.iter().any(|c| !c.is_finite()) {
            return CertifiedJacobian { min_lower: f64::NAN, max_upper: f64::NAN, verdict: Verdict::Invalid };
        }
        // Leaves: coefficients, d + 1 vertices in reference coordinates, depth.
        let mut verts = [[0.0; 3]; 4];
        for k in 1..=d {
            verts[k][k - 1] = 1.0;
        }
        let mut stack = vec![(root, verts, 0usize)];
        let mut w = Vec::new();
        let (mut lower, mut upper) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut found_nonpositive = false;
        let mut uncertain = false;
        while let Some((coef, verts, depth)) = stack.pop() {
            let min_b = coef.iter().copied().fold(f64::INFINITY, f64::min);
            let max_b = coef.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if min_b <= 0.0 && !found_nonpositive {
                found_nonpositive = self.finds_nonpositive(&coef);
                if !found_nonpositive && depth < MAX_DEPTH {
                    let e = longest_edge(&verts[..=d], d);
                    let edge = &self.edges[e];
                    let (mut left, mut right) = (vec![0.0; m], vec![0.0; m]);
                    self.bisect_into(edge, &coef, &mut left, &mut right, &mut w);
                    let mid: [f64; 3] = std::array::from_fn(|c| 0.5 * (verts[edge.k][c] + verts[edge.l][c]));
                    let (mut vl, mut vr) = (verts, verts);
                    vl[edge.l] = mid;
                    vr[edge.k] = mid;
                    stack.push((left, vl, depth + 1));
                    stack.push((right, vr, depth + 1));
                    continue;
                }
                if !found_nonpositive {
                    uncertain = true;
                }
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

/// The index, in [`JacobianBernstein`]'s edge order ((0,1), (0,2), …), of
/// the longest edge of the sub-simplex with vertices `verts` (reference coordinates).
fn longest_edge(verts: &[[f64; 3]], d: usize) -> usize {
    let mut best = (0, -1.0);
    let mut e = 0;
    for a in 0..verts.len() {
        for b in a + 1..verts.len() {
            let l: f64 = (0..d).map(|c| (verts[a][c] - verts[b][c]).powi(2)).sum();
            if l > best.1 {
                best = (e, l);
            }
            e += 1;
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{NodeSet, NodeSpacing, Simplex};
    use crate::{linalg, mapping};

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

    fn random_lambda(d: usize, seed: &mut u64) -> [f64; 4] {
        let mut l = [0.0; 4];
        for x in l.iter_mut().take(d + 1) {
            *x = -lcg(seed).ln();
        }
        let s: f64 = l.iter().sum();
        l.map(|x| x / s)
    }

    fn det_at(basis: &LagrangeBasis, xe: &[f64], l: &[f64; 4]) -> f64 {
        let d = basis.simplex().dim();
        let mut g = vec![0.0; basis.len() * d];
        basis.eval_grad_into(&[l[1], l[2], l[3]], &mut g);
        linalg::det(d, &mapping::jacobian(d, xe, &g))
    }

    #[test]
    fn bernstein_coefficients_reproduce_det_j_and_bound_it() {
        for (simplex, p) in [(Simplex::Tri, 2), (Simplex::Tri, 4), (Simplex::Tet, 2), (Simplex::Tet, 3)] {
            let basis = LagrangeBasis::new(&NodeSet::new(simplex, p, NodeSpacing::Optimal));
            let jb = JacobianBernstein::new(&basis);
            let mut seed = 7;
            let xe = perturbed(&basis, 0.05, &mut seed);
            let c = jb.certify(&xe);
            assert_eq!(c.verdict, Verdict::Valid, "{simplex:?} p={p}");
            // det J at random points lies within the bounds.
            let d = simplex.dim();
            for _ in 0..500 {
                let dj = det_at(&basis, &xe, &random_lambda(d, &mut seed));
                assert!(c.min_lower <= dj + 1e-12 && dj <= c.max_upper + 1e-12, "{dj} outside bounds");
            }
        }
    }

    #[test]
    fn bisection_halves_reproduce_det_j_on_each_half() {
        // The de Casteljau halves of a p = 5 tet's expansion, evaluated at a
        // point of each half in the half's own barycentric coordinates.
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tet, 5, NodeSpacing::Optimal));
        let jb = JacobianBernstein::new(&basis);
        let mut seed = 3;
        let xe = perturbed(&basis, 0.1, &mut seed);
        let mut coef = vec![0.0; jb.len()];
        jb.coefficients_into(&xe, &mut coef);
        let verts: [[f64; 3]; 4] = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for edge in &jb.edges {
            let (mut left, mut right) = (vec![0.0; jb.len()], vec![0.0; jb.len()]);
            jb.bisect_into(edge, &coef, &mut left, &mut right, &mut Vec::new());
            let mid: [f64; 3] = std::array::from_fn(|c| 0.5 * (verts[edge.k][c] + verts[edge.l][c]));
            for (half, replaced) in [(&left, edge.l), (&right, edge.k)] {
                let mut v = verts;
                v[replaced] = mid;
                for _ in 0..20 {
                    let mu = random_lambda(3, &mut seed);
                    let xi: [f64; 3] = std::array::from_fn(|c| (0..4).map(|k| mu[k] * v[k][c]).sum());
                    let l = [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]];
                    let (got, want) = (jb.eval(half, &mu), det_at(&basis, &xe, &l));
                    assert!(
                        (got - want).abs() < 1e-11 * want.abs().max(1.0),
                        "edge ({}, {}): {got} vs {want}",
                        edge.k,
                        edge.l
                    );
                }
            }
        }
    }

    #[test]
    fn an_affine_element_has_exact_bounds() {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tet, 3, NodeSpacing::Optimal));
        let jb = JacobianBernstein::new(&basis);
        // x = 2ξ: det J = 8 everywhere.
        let xe: Vec<f64> = basis.nodes().coords.iter().flat_map(|x| x.iter().map(|v| 2.0 * v)).collect();
        let c = jb.certify(&xe);
        assert_eq!(c.verdict, Verdict::Valid);
        assert!((c.min_lower - 8.0).abs() < 1e-9 && (c.max_upper - 8.0).abs() < 1e-9, "{c:?}");
        assert!((c.q3_lower() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn an_element_folded_at_a_node_is_invalid() {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tri, 2, NodeSpacing::Optimal));
        let jb = JacobianBernstein::new(&basis);
        let mut xe: Vec<f64> = basis.nodes().coords.iter().flat_map(|x| [x[0], x[1]]).collect();
        // Pull the mid-node of edge (1, 2) past the opposite vertex.
        let k = (3..6).find(|&i| (xe[2 * i] - 0.5).abs() < 1e-12 && (xe[2 * i + 1] - 0.5).abs() < 1e-12).unwrap();
        xe[2 * k] = -0.3;
        xe[2 * k + 1] = -0.3;
        assert_eq!(jb.certify(&xe).verdict, Verdict::Invalid);
    }

    #[test]
    fn non_finite_coordinates_are_invalid() {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tet, 2, NodeSpacing::Optimal));
        let jb = JacobianBernstein::new(&basis);
        let mut xe: Vec<f64> = basis.nodes().coords.iter().flat_map(|x| *x).collect();
        xe[13] = f64::NAN;
        assert_eq!(jb.certify(&xe).verdict, Verdict::Invalid);
    }
}
