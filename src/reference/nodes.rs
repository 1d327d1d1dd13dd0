//! Lagrange node sets on the reference simplices.
//!
//! A node is named by its barycentric multi-index a = (a_0, …, a_dim),
//! Σ a_i = p: the equispaced node sits at λ = a / p. The optimal (warp &
//! blend) node of the same multi-index is the image of that equispaced point
//! under Warburton's warp & blend map (Warburton 2006; Hesthaven & Warburton,
//! *Nodal Discontinuous Galerkin Methods*, §6.1 `Nodes2D` and §10.1
//! `Nodes3D`), written here directly in barycentric coordinates, where it is
//! manifestly symmetric under vertex permutations.
//!
//! Native node order: the vertices (node i = vertex i); the edge-interior
//! nodes grouped by local edge in [`Simplex::edges`] order, each running from
//! the edge's first vertex to its second; for the tetrahedron the
//! face-interior nodes grouped by face in [`TET_FACES`] order; then the
//! cell-interior nodes. Inside a face group and the interior group the nodes
//! follow the lexicographic order of their multi-index.

use super::simplex::{Simplex, TET_FACES};
use crate::jacobi::gauss_lobatto_legendre;

/// How the nodes of a [`NodeSet`] are spaced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum NodeSpacing {
    /// λ = a / p.
    Equispaced,
    /// Warburton's warp & blend nodes: Gauss–Lobatto–Legendre points on the
    /// edges, interpolation-optimised (α_opt) in the faces and interior.
    #[default]
    Optimal,
}

/// The Lagrange nodes of order `order` on a reference simplex.
#[derive(Debug, Clone)]
pub struct NodeSet {
    pub simplex: Simplex,
    pub order: usize,
    /// Barycentric multi-index of each node: counts (a_0, .., a_dim) with sum = order,
    /// node at barycentric λ_i = a_i / order for the equispaced set. Unused slots are 0 (tri uses 3).
    pub multi: Vec<[usize; 4]>,
    /// Reference coordinates of each node (3 components, z = 0 for the triangle).
    pub coords: Vec<[f64; 3]>,
}

/// Optimised blending parameter α of `Nodes2D` for N = 1..15 (5/3 beyond).
const ALPHA_TRI: [f64; 15] =
    [0.0, 0.0, 1.4152, 0.1001, 0.2751, 0.9800, 1.0999, 1.2832, 1.3648, 1.4773, 1.4959, 1.5743, 1.5770, 1.6223, 1.6258];
/// Optimised blending parameter α of `Nodes3D` for N = 1..15 (1 beyond).
const ALPHA_TET: [f64; 15] =
    [0.0, 0.0, 0.0, 0.1002, 1.1332, 1.5608, 1.3413, 1.2577, 1.1603, 1.10153, 0.6080, 0.4523, 0.8856, 0.8717, 0.9655];

/// The blending parameter α of the warp & blend nodes of `simplex` at order `p`.
pub fn warp_blend_alpha(simplex: Simplex, p: usize) -> f64 {
    match simplex {
        Simplex::Tri => ALPHA_TRI.get(p.wrapping_sub(1)).copied().unwrap_or(5.0 / 3.0),
        Simplex::Tet => ALPHA_TET.get(p.wrapping_sub(1)).copied().unwrap_or(1.0),
    }
}

impl NodeSet {
    /// The nodes of order `order` ≥ 1 on `simplex`, in native order.
    ///
    /// ```
    /// use hocurve::reference::{NodeSet, NodeSpacing, Simplex};
    /// let n = NodeSet::new(Simplex::Tri, 2, NodeSpacing::Equispaced);
    /// assert_eq!(n.len(), 6);
    /// assert_eq!(n.coords[3], [0.5, 0.0, 0.0]); // midpoint of edge (0, 1)
    /// ```
    pub fn new(simplex: Simplex, order: usize, spacing: NodeSpacing) -> NodeSet {
        let face_alpha = warp_blend_alpha(simplex, order);
        Self::build(simplex, order, spacing, face_alpha)
    }

    /// The triangle node set that is the trace of the tetrahedron's node set
    /// of the same order and spacing on a face: face node (b, c, d) of
    /// `NodeSet::new(Simplex::Tet, ..)` sits, bit for bit, at the barycentric
    /// point of node (b, c, d) of this set.
    ///
    /// It differs from `NodeSet::new(Simplex::Tri, ..)` for the optimal
    /// spacing at p ≥ 3, because `Nodes3D` blends the faces with its own α.
    pub fn tet_face_trace(order: usize, spacing: NodeSpacing) -> NodeSet {
        Self::build(Simplex::Tri, order, spacing, warp_blend_alpha(Simplex::Tet, order))
    }

    fn build(simplex: Simplex, order: usize, spacing: NodeSpacing, face_alpha: f64) -> NodeSet {
        assert!(order >= 1, "NodeSet: order must be at least 1");
        let multi = native_multi_indices(simplex, order);
        let nv = simplex.n_vertices();
        let warp = WarpBlend::new(order, face_alpha, warp_blend_alpha(Simplex::Tet, order));
        let coords = multi
            .iter()
            .map(|a| {
                let lam = match spacing {
                    NodeSpacing::Equispaced => {
                        let mut l = [0.0; 4];
                        for i in 0..nv {
                            l[i] = a[i] as f64 / order as f64;
                        }
                        l
                    }
                    NodeSpacing::Optimal => warp.barycentric(&a[..nv]),
                };
                let mut x = [0.0; 3];
                x[..nv - 1].copy_from_slice(&lam[1..nv]);
                x
            })
            .collect();
        NodeSet { simplex, order, multi, coords }
    }

    /// Number of nodes, (p+1)(p+2)/2 or (p+1)(p+2)(p+3)/6.
    pub fn len(&self) -> usize {
        self.coords.len()
    }

    /// True if the set has no nodes (never, for a set built by [`NodeSet::new`]).
    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }

    /// Barycentric coordinates of node `i`: λ_0 = 1 − Σ ξ_j, λ_j = ξ_j
    /// (unused slots 0).
    pub fn barycentric(&self, i: usize) -> [f64; 4] {
        let dim = self.simplex.dim();
        let x = &self.coords[i];
        let mut l = [0.0; 4];
        l[0] = 1.0 - x[..dim].iter().sum::<f64>();
        l[1..=dim].copy_from_slice(&x[..dim]);
        l
    }

    /// Index of the node with multi-index `a` (linear search).
    pub fn index_of(&self, a: &[usize; 4]) -> Option<usize> {
        self.multi.iter().position(|m| m == a)
    }
}

/// Multi-indices of the order-`p` nodes of `simplex` in native order.
fn native_multi_indices(simplex: Simplex, p: usize) -> Vec<[usize; 4]> {
    let nv = simplex.n_vertices();
    let mut out = Vec::with_capacity(simplex.n_nodes(p));
    for v in 0..nv {
        let mut a = [0; 4];
        a[v] = p;
        out.push(a);
    }
    for &[v0, v1] in simplex.edges() {
        for k in 1..p {
            let mut a = [0; 4];
            a[v0] = p - k;
            a[v1] = k;
            out.push(a);
        }
    }
    if simplex == Simplex::Tet {
        for face in &TET_FACES {
            out.extend(positive_multi_indices(face, p));
        }
    }
    let all: Vec<usize> = (0..nv).collect();
    out.extend(positive_multi_indices(&all, p));
    out
}

/// All multi-indices of sum `p` that are ≥ 1 exactly on the vertices
/// `verts` (0 elsewhere), in lexicographic order of the full 4-array.
fn positive_multi_indices(verts: &[usize], p: usize) -> Vec<[usize; 4]> {
    fn rec(verts: &[usize], left: usize, a: &mut [usize; 4], out: &mut Vec<[usize; 4]>) {
        match verts {
            [] => {}
            [v] => {
                if left >= 1 {
                    a[*v] = left;
                    out.push(*a);
                    a[*v] = 0;
                }
            }
            [v, rest @ ..] => {
                for c in 1..left.saturating_sub(rest.len() - 1) {
                    a[*v] = c;
                    rec(rest, left - c, a, out);
                }
                a[*v] = 0;
            }
        }
    }
    let mut out = Vec::new();
    rec(verts, p, &mut [0; 4], &mut out);
    out.sort_unstable();
    out
}

/// Warburton's warp & blend map in barycentric form.
///
/// 1D warp: with equispaced points r_m = −1 + 2m/p and GLL points g_m,
/// warp(r) = Σ_{m=1}^{p−1} (g_m − r_m) ℓ_m(r) / (1 − r²), evaluated as
/// Σ_m (g_m − r_m) Π_{j≠m, 0<j<p} (r − r_j)/(r_m − r_j) / (1 − r_m²) — no
/// division by 1 − r² (the `evalwarp` of `Nodes3D`).
///
/// Triangle (λ_0, λ_1, λ_2), edge (i, j) with opposite vertex k:
/// w_ij = 4 λ_i λ_j warp(λ_j − λ_i) (1 + (α λ_k)²), and
/// λ ← λ + Σ_edges (w_ij / 2)(e_j − e_i) (a displacement of w_ij along the
/// unit edge vector of the equilateral triangle of side 2).
///
/// Tetrahedron: each face f (opposite vertex a, vertices b, c, d) contributes
/// its triangle shift, evaluated on the unnormalised (λ_b, λ_c, λ_d), times
/// blend_f = (1 + (α λ_a)²) λ_b λ_c λ_d / ((λ_b + λ_a/2)(λ_c + λ_a/2)(λ_d + λ_a/2)).
///
/// Points on the boundary are placed by the lower-dimensional formula (the
/// limit of the above): edges at the GLL points, tet faces by the triangle
/// formula with the tet's α. To make the map equivariant bit for bit, each
/// point is computed from its multi-index sorted in decreasing order and
/// permuted back, with tied entries averaged.
struct WarpBlend {
    p: usize,
    /// GLL points on [−1, 1], ascending.
    gll: Vec<f64>,
    /// Equispaced points on [−1, 1], ascending.
    eq: Vec<f64>,
    /// α for triangle-like (2-simplex) point sets: the triangle or the tet faces.
    alpha_face: f64,
    alpha_tet: f64,
}

impl WarpBlend {
    fn new(p: usize, alpha_face: f64, alpha_tet: f64) -> WarpBlend {
        WarpBlend {
            p,
            gll: gauss_lobatto_legendre(p + 1),
            eq: (0..=p).map(|m| -1.0 + 2.0 * m as f64 / p as f64).collect(),
            alpha_face,
            alpha_tet,
        }
    }

    /// warp(r) = (interpolant of g − r on the equispaced points)(r) / (1 − r²).
    fn warp(&self, r: f64) -> f64 {
        let p = self.p;
        let mut sum = 0.0;
        for m in 1..p {
            let mut d = (self.gll[m] - self.eq[m]) / (1.0 - self.eq[m] * self.eq[m]);
            for j in 1..p {
                if j != m {
                    d *= (r - self.eq[j]) / (self.eq[m] - self.eq[j]);
                }
            }
            sum += d;
        }
        sum
    }

    /// Triangle shift δλ for (possibly unnormalised) barycentrics `l`.
    fn tri_shift(&self, l: [f64; 3], alpha: f64) -> [f64; 3] {
        let mut d = [0.0; 3];
        for (i, j, k) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] {
            let ak = alpha * l[k];
            let w = 4.0 * l[i] * l[j] * self.warp(l[j] - l[i]) * (1.0 + ak * ak);
            d[j] += 0.5 * w;
            d[i] -= 0.5 * w;
        }
        d
    }

    /// Barycentric coordinates of the node with multi-index `a` (len 3 or 4).
    fn barycentric(&self, a: &[usize]) -> [f64; 4] {
        let p = self.p as f64;
        // sort vertex slots by decreasing count (stable)
        let mut perm: Vec<usize> = (0..a.len()).collect();
        perm.sort_by(|&x, &y| a[y].cmp(&a[x]));
        let s: Vec<usize> = perm.iter().map(|&v| a[v]).collect();
        let k = s.iter().filter(|&&c| c > 0).count();
        let mut l = [0.0; 4];
        match k {
            1 => l[0] = 1.0,
            2 => {
                l[0] = 0.5 * (1.0 + self.gll[s[0]]);
                l[1] = 0.5 * (1.0 + self.gll[s[1]]);
            }
            3 => {
                let l0 = [s[0] as f64 / p, s[1] as f64 / p, s[2] as f64 / p];
                let d = self.tri_shift(l0, self.alpha_face);
                for i in 0..3 {
                    l[i] = l0[i] + d[i];
                }
            }
            _ => {
                let l0 = [0, 1, 2, 3].map(|i| s[i] as f64 / p);
                let alpha = self.alpha_tet;
                l = l0;
                for f in 0..4 {
                    let face: Vec<usize> = (0..4).filter(|&v| v != f).collect();
                    let (la, lb, lc, ld) = (l0[f], l0[face[0]], l0[face[1]], l0[face[2]]);
                    let aa = alpha * la;
                    let blend = (1.0 + aa * aa) * lb * lc * ld / ((lb + 0.5 * la) * (lc + 0.5 * la) * (ld + 0.5 * la));
                    let d = self.tri_shift([lb, lc, ld], alpha);
                    for (t, &v) in face.iter().enumerate() {
                        l[v] += blend * d[t];
                    }
                }
            }
        }
        // average tied entries so that equal counts give bit-equal coordinates
        let mut start = 0;
        while start < s.len() {
            let mut end = start + 1;
            while end < s.len() && s[end] == s[start] {
                end += 1;
            }
            if end - start > 1 {
                let mean = l[start..end].iter().sum::<f64>() / (end - start) as f64;
                l[start..end].iter_mut().for_each(|x| *x = mean);
            }
            start = end;
        }
        let mut out = [0.0; 4];
        for (m, &v) in perm.iter().enumerate() {
            out[v] = l[m];
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    const SPACINGS: [NodeSpacing; 2] = [NodeSpacing::Equispaced, NodeSpacing::Optimal];
    const SIMPLICES: [Simplex; 2] = [Simplex::Tri, Simplex::Tet];

    /// All permutations of 0..n.
    fn permutations(n: usize) -> Vec<Vec<usize>> {
        if n == 0 {
            return vec![vec![]];
        }
        let mut out = Vec::new();
        for rest in permutations(n - 1) {
            for pos in 0..=rest.len() {
                let mut q = rest.clone();
                q.insert(pos, n - 1);
                out.push(q);
            }
        }
        out
    }

    #[test]
    fn node_count_and_multi_index_sums() {
        for simplex in SIMPLICES {
            for p in 1..=15 {
                for spacing in SPACINGS {
                    let n = NodeSet::new(simplex, p, spacing);
                    assert_eq!(n.len(), simplex.n_nodes(p));
                    assert_eq!(n.multi.len(), n.len());
                    let mut seen = std::collections::HashSet::new();
                    for a in &n.multi {
                        assert_eq!(a.iter().sum::<usize>(), p);
                        assert!(a[simplex.n_vertices()..].iter().all(|&c| c == 0));
                        assert!(seen.insert(*a), "duplicate multi-index {a:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn native_order_vertices_edges_faces_interior() {
        for simplex in SIMPLICES {
            let nv = simplex.n_vertices();
            for p in 1..=10 {
                let n = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                let mut i = 0;
                for v in 0..nv {
                    assert_eq!(n.multi[i][v], p);
                    assert_eq!(n.coords[i], simplex.vertex_coords()[v]);
                    i += 1;
                }
                for &[v0, v1] in simplex.edges() {
                    for k in 1..p {
                        let a = n.multi[i];
                        assert_eq!((a[v0], a[v1]), (p - k, k), "edge ({v0},{v1})");
                        i += 1;
                    }
                }
                let mut groups: Vec<Vec<usize>> = Vec::new();
                if simplex == Simplex::Tet {
                    groups.extend(TET_FACES.iter().map(|f| f.to_vec()));
                }
                groups.push((0..nv).collect());
                for g in groups {
                    // C(p − 1, |g| − 1) compositions of p into |g| positive parts
                    let k = g.len();
                    let count = if p < k { 0 } else { (1..k).fold(1, |acc, j| acc * (p - j) / j) };
                    for m in 0..count {
                        let a = n.multi[i + m];
                        for v in 0..nv {
                            assert_eq!(a[v] > 0, g.contains(&v), "group {g:?} p = {p}: {a:?}");
                        }
                    }
                    assert!(n.multi[i..i + count].windows(2).all(|w| w[0] < w[1]));
                    i += count;
                }
                assert_eq!(i, n.len());
            }
        }
    }

    #[test]
    fn equispaced_coords_are_multi_index_over_order() {
        for simplex in SIMPLICES {
            for p in 1..=10 {
                let n = NodeSet::new(simplex, p, NodeSpacing::Equispaced);
                for (a, x) in n.multi.iter().zip(&n.coords) {
                    for i in 0..3 {
                        let e = if i < simplex.dim() { a[i + 1] as f64 / p as f64 } else { 0.0 };
                        assert_eq!(x[i], e);
                    }
                }
            }
        }
    }

    #[test]
    fn warp_blend_is_equivariant_under_vertex_permutations() {
        for simplex in SIMPLICES {
            let nv = simplex.n_vertices();
            for p in 1..=15 {
                let n = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                let warp = WarpBlend::new(p, warp_blend_alpha(simplex, p), warp_blend_alpha(Simplex::Tet, p));
                let index: HashMap<[usize; 4], usize> = n.multi.iter().enumerate().map(|(i, a)| (*a, i)).collect();
                for sigma in permutations(nv) {
                    for (i, a) in n.multi.iter().enumerate() {
                        // vertex v of the element becomes vertex sigma[v]
                        let mut b = [0; 4];
                        for v in 0..nv {
                            b[sigma[v]] = a[v];
                        }
                        let j = index[&b];
                        let (la, lb) = (n.barycentric(i), n.barycentric(j));
                        let (ea, eb) = (warp.barycentric(&a[..nv]), warp.barycentric(&b[..nv]));
                        for v in 0..nv {
                            assert_eq!(ea[v], eb[sigma[v]], "exact barycentrics, p={p}");
                            assert!((la[v] - lb[sigma[v]]).abs() < 1e-15);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn edge_nodes_are_gauss_lobatto_legendre_points() {
        for simplex in SIMPLICES {
            for p in 2..=15 {
                let g = gauss_lobatto_legendre(p + 1);
                let n = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                for (i, a) in n.multi.iter().enumerate() {
                    let nz: Vec<usize> = (0..4).filter(|&v| a[v] > 0).collect();
                    if nz.len() != 2 {
                        continue;
                    }
                    let l = n.barycentric(i);
                    for &v in &nz {
                        let e = 0.5 * (1.0 + g[a[v]]);
                        assert!((l[v] - e).abs() < 1e-15, "p={p} {a:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn all_nodes_inside_closed_simplex_and_distinct() {
        for simplex in SIMPLICES {
            for p in 1..=15 {
                let n = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                for i in 0..n.len() {
                    let l = n.barycentric(i);
                    for (v, &lv) in l.iter().enumerate().take(simplex.n_vertices()) {
                        assert!(lv >= -1e-15, "p={p} node {i}");
                        // zero count ⇔ on the opposite facet
                        if n.multi[i][v] == 0 {
                            assert!(lv.abs() < 1e-15);
                        } else {
                            assert!(lv > 1e-3);
                        }
                    }
                }
                let min_dist = (0..n.len())
                    .flat_map(|i| (0..i).map(move |j| (i, j)))
                    .map(|(i, j)| (0..3).map(|c| (n.coords[i][c] - n.coords[j][c]).powi(2)).sum::<f64>().sqrt())
                    .fold(f64::INFINITY, f64::min);
                assert!(min_dist > 0.1 / (p * p) as f64, "p={p}: {min_dist}");
            }
        }
    }

    #[test]
    fn tet_face_nodes_depend_only_on_face_multi_index() {
        for p in 3..=12 {
            let tet = NodeSet::new(Simplex::Tet, p, NodeSpacing::Optimal);
            let trace = NodeSet::tet_face_trace(p, NodeSpacing::Optimal);
            for (i, a) in tet.multi.iter().enumerate() {
                let zero: Vec<usize> = (0..4).filter(|&v| a[v] == 0).collect();
                if zero.len() != 1 {
                    continue;
                }
                let face: Vec<usize> = (0..4).filter(|&v| v != zero[0]).collect();
                let fa = [a[face[0]], a[face[1]], a[face[2]], 0];
                let j = trace.index_of(&fa).unwrap();
                let (lt, lf) = (tet.barycentric(i), trace.barycentric(j));
                for t in 0..3 {
                    assert!((lt[face[t]] - lf[t]).abs() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn order_one_and_two_are_equispaced() {
        for simplex in SIMPLICES {
            for p in 1..=2 {
                let e = NodeSet::new(simplex, p, NodeSpacing::Equispaced);
                let o = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                for (x, y) in e.coords.iter().zip(&o.coords) {
                    for c in 0..3 {
                        assert!((x[c] - y[c]).abs() < 1e-15);
                    }
                }
            }
        }
    }
}

/// Literal transcriptions of Hesthaven & Warburton's `Nodes2D` and `Nodes3D`
/// (equilateral simplices, tolerance-based edge handling), to check that the
/// barycentric warp & blend above reproduces them.
#[cfg(test)]
mod hesthaven_reference {
    use super::*;
    use std::f64::consts::PI;

    type V3 = [f64; 3];

    fn sub(a: V3, b: V3) -> V3 {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    fn unit(a: V3) -> V3 {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        [a[0] / n, a[1] / n, a[2] / n]
    }
    fn mid(a: V3, b: V3) -> V3 {
        [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])]
    }

    /// `Warpfactor` (2D): interpolant of GLL − equispaced divided by 1 − r².
    fn warpfactor(p: usize, r: f64) -> f64 {
        let gll = gauss_lobatto_legendre(p + 1);
        let req: Vec<f64> = (0..=p).map(|m| -1.0 + 2.0 * m as f64 / p as f64).collect();
        let mut warp = 0.0;
        for m in 0..=p {
            let mut l = 1.0;
            for j in 0..=p {
                if j != m {
                    l *= (r - req[j]) / (req[m] - req[j]);
                }
            }
            warp += (gll[m] - req[m]) * l;
        }
        if r.abs() < 1.0 - 1e-10 {
            warp / (1.0 - r * r)
        } else {
            0.0
        }
    }

    /// `evalwarp` (3D), with the descending point lists of `Nodes3D`.
    fn evalwarp(p: usize, r: f64) -> f64 {
        let xnodes: Vec<f64> = gauss_lobatto_legendre(p + 1).into_iter().rev().collect();
        let xeq: Vec<f64> = (1..=p + 1).map(|i| -1.0 + 2.0 * (p + 1 - i) as f64 / p as f64).collect();
        let mut warp = 0.0;
        for i in 1..=p + 1 {
            let mut d = xnodes[i - 1] - xeq[i - 1];
            for j in 2..=p {
                if i != j {
                    d *= (r - xeq[j - 1]) / (xeq[i - 1] - xeq[j - 1]);
                }
            }
            if i != 1 {
                d = -d / (xeq[i - 1] - xeq[0]);
            }
            if i != p + 1 {
                d /= xeq[i - 1] - xeq[p];
            }
            warp += d;
        }
        warp
    }

    /// `evalshift`: the 2D warp & blend displacement in the face frame.
    fn evalshift(p: usize, alpha: f64, l1: f64, l2: f64, l3: f64) -> (f64, f64) {
        let w1 = l2 * l3 * 4.0 * evalwarp(p, l3 - l2) * (1.0 + (alpha * l1).powi(2));
        let w2 = l1 * l3 * 4.0 * evalwarp(p, l1 - l3) * (1.0 + (alpha * l2).powi(2));
        let w3 = l1 * l2 * 4.0 * evalwarp(p, l2 - l1) * (1.0 + (alpha * l3).powi(2));
        let (sin2, cos2) = (2.0 * PI / 3.0).sin_cos();
        let (sin4, cos4) = (4.0 * PI / 3.0).sin_cos();
        (w1 + cos2 * w2 + cos4 * w3, sin2 * w2 + sin4 * w3)
    }

    /// `Nodes2D` point (equilateral) of the node with L2 = a0/p, L3 = a1/p, L1 = a2/p.
    fn nodes2d(p: usize, a: &[usize; 4]) -> V3 {
        let alpha = warp_blend_alpha(Simplex::Tri, p);
        let n = p as f64;
        let (l2, l3, l1) = (a[0] as f64 / n, a[1] as f64 / n, a[2] as f64 / n);
        let mut x = -l2 + l3;
        let mut y = (-l2 - l3 + 2.0 * l1) / 3f64.sqrt();
        let w1 = 4.0 * l2 * l3 * warpfactor(p, l3 - l2) * (1.0 + (alpha * l1).powi(2));
        let w2 = 4.0 * l1 * l3 * warpfactor(p, l1 - l3) * (1.0 + (alpha * l2).powi(2));
        let w3 = 4.0 * l1 * l2 * warpfactor(p, l2 - l1) * (1.0 + (alpha * l3).powi(2));
        x += w1 + (2.0 * PI / 3.0).cos() * w2 + (4.0 * PI / 3.0).cos() * w3;
        y += (2.0 * PI / 3.0).sin() * w2 + (4.0 * PI / 3.0).sin() * w3;
        [x, y, 0.0]
    }

    /// `Nodes3D` point (equilateral) of the node with L3, L4, L2, L1 = a / p.
    fn nodes3d(p: usize, a: &[usize; 4], v: &[V3; 4]) -> V3 {
        let alpha = warp_blend_alpha(Simplex::Tet, p);
        let tol = 1e-10;
        let t1 = [unit(sub(v[1], v[0])), unit(sub(v[1], v[0])), unit(sub(v[2], v[1])), unit(sub(v[2], v[0]))];
        let t2 = [
            unit(sub(v[2], mid(v[0], v[1]))),
            unit(sub(v[3], mid(v[0], v[1]))),
            unit(sub(v[3], mid(v[1], v[2]))),
            unit(sub(v[3], mid(v[0], v[2]))),
        ];
        let n = p as f64;
        let (l3, l4, l2, l1) = (a[0] as f64 / n, a[1] as f64 / n, a[2] as f64 / n, a[3] as f64 / n);
        let mut shift = [0.0; 3];
        for face in 0..4 {
            let (la, lb, lc, ld) = match face {
                0 => (l1, l2, l3, l4),
                1 => (l2, l1, l3, l4),
                2 => (l3, l1, l4, l2),
                _ => (l4, l1, l3, l2),
            };
            let (w1, w2) = evalshift(p, alpha, lb, lc, ld);
            let mut blend = lb * lc * ld;
            let denom = (lb + 0.5 * la) * (lc + 0.5 * la) * (ld + 0.5 * la);
            if denom > tol {
                blend *= (1.0 + (alpha * la).powi(2)) / denom;
            }
            for c in 0..3 {
                shift[c] += blend * (w1 * t1[face][c] + w2 * t2[face][c]);
            }
            if la < tol && [lb, lc, ld].iter().filter(|&&l| l > tol).count() < 3 {
                for c in 0..3 {
                    shift[c] = w1 * t1[face][c] + w2 * t2[face][c];
                }
            }
        }
        let mut x = [0.0; 3];
        for c in 0..3 {
            x[c] = l3 * v[0][c] + l4 * v[1][c] + l2 * v[2][c] + l1 * v[3][c] + shift[c];
        }
        x
    }

    #[test]
    fn warp_blend_reproduces_hesthaven_nodes2d() {
        let s3 = 3f64.sqrt();
        let v = [[-1.0, -1.0 / s3, 0.0], [1.0, -1.0 / s3, 0.0], [0.0, 2.0 / s3, 0.0]];
        for p in 1..=15 {
            let n = NodeSet::new(Simplex::Tri, p, NodeSpacing::Optimal);
            for (i, a) in n.multi.iter().enumerate() {
                let l = n.barycentric(i);
                let e = nodes2d(p, a);
                for c in 0..2 {
                    let x: f64 = (0..3).map(|k| l[k] * v[k][c]).sum();
                    assert!((x - e[c]).abs() < 1e-13, "p={p} {a:?}: {x} vs {}", e[c]);
                }
            }
        }
    }

    #[test]
    fn warp_blend_reproduces_hesthaven_nodes3d() {
        let (s3, s6) = (3f64.sqrt(), 6f64.sqrt());
        let v = [
            [-1.0, -1.0 / s3, -1.0 / s6],
            [1.0, -1.0 / s3, -1.0 / s6],
            [0.0, 2.0 / s3, -1.0 / s6],
            [0.0, 0.0, 3.0 / s6],
        ];
        for p in 1..=15 {
            let n = NodeSet::new(Simplex::Tet, p, NodeSpacing::Optimal);
            for (i, a) in n.multi.iter().enumerate() {
                let l = n.barycentric(i);
                let e = nodes3d(p, a, &v);
                for c in 0..3 {
                    let x: f64 = (0..4).map(|k| l[k] * v[k][c]).sum();
                    assert!((x - e[c]).abs() < 1e-13, "p={p} {a:?}: {x} vs {}", e[c]);
                }
            }
        }
    }
}
