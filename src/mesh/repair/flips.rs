//! Local flips on a mutable simplex mesh. Every flip replaces a few cells by
//! others with no new vertex. All but the surface edge flip cover the same
//! region and touch no boundary facet: only interior faces and edges are
//! flipped.
//!
//! * **2-3** (3D): two tets abcd, abce sharing the interior face abc become
//!   abed, bced, caed around the new edge de. Valid when de crosses abc.
//! * **Edge removal** (3D, n to 2n − 4): the n tets around an interior edge
//!   ab, with ring r₀ … r_(n−1), become two tets per triangle of a
//!   triangulation of the ring, one with apex a and one with apex b. The
//!   triangulation maximising the smallest quality is found by dynamic
//!   programming over the ring (Klincsek's O(n³)); n = 3 is the 3-2 flip.
//! * **2-2** (2D): two triangles abc, bad sharing the interior edge ab become
//!   adc, bcd across the new edge cd. Valid when the quadrilateral is convex.
//!
//! * **Surface edge** (3D, n to 2n − 2): the n tets around a boundary edge
//!   ab between the boundary facets abc and abd, with the open ring c = r₀
//!   … r_n = d, become two tets per triangle of the best triangulation of
//!   the ring closed by the new edge cd; the boundary facets become acd and
//!   bcd. The only flip that changes the boundary ([`super::surface`]).
//!
//! A candidate is valid when every new cell is positively oriented and not
//! degenerate ([`super::detect::DEGENERATE`]) and every new edge is new to
//! the mesh.

use rustc_hash::FxHashMap as HashMap;

use super::detect::{Assessment, Criteria};
use super::geom::{facet_key, facet_of, orient, FacetKey};
use crate::mesh::LinearMesh;

/// Largest ring of tets around an edge that edge removal considers.
pub const MAX_RING: usize = 10;

/// The kind of a flip.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlipKind {
    /// 3D: two tets to three across an interior face.
    TwoThree,
    /// 3D: three tets around an interior edge to two.
    ThreeTwo,
    /// 3D: n ≥ 4 tets around an interior edge to 2n − 4.
    EdgeRemoval,
    /// 2D: two triangles to two across an interior edge.
    TwoTwo,
    /// 3D: the n tets around a boundary edge to 2n − 2, the edge flipped
    /// to the other diagonal of its two boundary facets.
    SurfaceEdge,
}

/// A candidate flip: cells to remove, cells to add, and the smallest quality
/// of the added cells.
#[derive(Debug, Clone)]
pub(crate) struct Flip {
    pub kind: FlipKind,
    pub remove: Vec<usize>,
    pub add: Vec<[usize; 4]>,
    pub min_quality: f64,
}

const NONE: usize = usize::MAX;

/// A simplex mesh under repair: cells are only ever added (new indices) or
/// marked dead, so an index names one cell for good.
pub(crate) struct Work<'a> {
    pub dim: usize,
    coords: &'a [f64],
    crit: &'a Criteria,
    /// Cell vertices (`dim + 1` used).
    pub cells: Vec<[usize; 4]>,
    pub alive: Vec<bool>,
    pub assessment: Vec<Assessment>,
    /// The cells of the reference mesh that each cell overlaps.
    pub origin: Vec<Vec<usize>>,
    /// Facet → the (one or two) cells on it.
    facets: HashMap<FacetKey, [usize; 2]>,
    /// 3D: edge → number of cells around it.
    edges: HashMap<[usize; 2], u32>,
    /// Cells of the mesh given (the first indices).
    n_given: usize,
}

impl<'a> Work<'a> {
    /// `mesh`: validated, positively oriented, dim 2 or 3; `origin[c]`: the
    /// cells of some reference mesh that cell c overlaps.
    pub fn new(mesh: &'a LinearMesh, crit: &'a Criteria, origin: Vec<Vec<usize>>) -> Work<'a> {
        let d = mesh.dim;
        let cells: Vec<[usize; 4]> = mesh
            .cells
            .chunks_exact(d + 1)
            .map(|c| {
                let mut a = [NONE; 4];
                a[..=d].copy_from_slice(c);
                a
            })
            .collect();
        let n = cells.len();
        let mut w = Work {
            dim: d,
            coords: &mesh.coords,
            crit,
            cells: Vec::with_capacity(n),
            alive: Vec::with_capacity(n),
            assessment: Vec::with_capacity(n),
            origin: Vec::with_capacity(n),
            facets: HashMap::with_capacity_and_hasher(2 * n, Default::default()),
            edges: HashMap::default(),
            n_given: n,
        };
        for (c, o) in cells.into_iter().zip(origin) {
            w.insert(c, o, false);
        }
        w.assessment = w.cells.iter().map(|c| crit.assess(w.coords, &c[..=d])).collect();
        w
    }

    fn assess(&self, cell: &[usize]) -> Assessment {
        self.crit.assess(self.coords, cell)
    }

    fn local_facets(&self, c: [usize; 4]) -> impl Iterator<Item = (usize, FacetKey)> + '_ {
        let d = self.dim;
        (0..=d).map(move |k| (k, facet_of(&c[..=d], k)))
    }

    fn insert(&mut self, c: [usize; 4], origin: Vec<usize>, assess: bool) {
        let id = self.cells.len();
        let d = self.dim;
        let keys: Vec<FacetKey> = self.local_facets(c).map(|(_, f)| f).collect();
        for f in keys {
            let e = self.facets.entry(f).or_insert([NONE; 2]);
            if e[0] == NONE {
                e[0] = id;
            } else {
                e[1] = id;
            }
        }
        if d == 3 {
            for i in 0..4 {
                for j in i + 1..4 {
                    *self.edges.entry([c[i].min(c[j]), c[i].max(c[j])]).or_default() += 1;
                }
            }
        }
        if assess {
            let a = self.assess(&c[..=d]);
            self.assessment.push(a);
        }
        self.cells.push(c);
        self.alive.push(true);
        self.origin.push(origin);
    }

    fn remove(&mut self, id: usize) {
        let c = self.cells[id];
        let keys: Vec<FacetKey> = self.local_facets(c).map(|(_, f)| f).collect();
        for f in keys {
            let e = self.facets.get_mut(&f).expect("facet of a live cell");
            if e[0] == id {
                e[0] = e[1];
            }
            e[1] = NONE;
            if e[0] == NONE {
                self.facets.remove(&f);
            }
        }
        if self.dim == 3 {
            for i in 0..4 {
                for j in i + 1..4 {
                    let k = [c[i].min(c[j]), c[i].max(c[j])];
                    let n = self.edges.get_mut(&k).expect("edge of a live cell");
                    *n -= 1;
                    if *n == 0 {
                        self.edges.remove(&k);
                    }
                }
            }
        }
        self.alive[id] = false;
    }

    /// Replace `flip.remove` by `flip.add`; the new cells overlap the union
    /// of the removed cells' origins.
    pub fn apply(&mut self, flip: &Flip) {
        let mut origin: Vec<usize> = flip.remove.iter().flat_map(|&r| self.origin[r].iter().copied()).collect();
        origin.sort_unstable();
        origin.dedup();
        for &r in &flip.remove {
            self.remove(r);
        }
        for &c in &flip.add {
            self.insert(c, origin.clone(), true);
        }
    }

    /// The live cells (`dim + 1` vertices each): those of the mesh given,
    /// in their order, then the new ones; for each, its index in the mesh
    /// given (None for a new cell) and its origin.
    pub fn into_cells(mut self) -> (Vec<usize>, Vec<Option<usize>>, Vec<Vec<usize>>) {
        let d = self.dim;
        let (mut cells, mut old, mut origin) = (Vec::new(), Vec::new(), Vec::new());
        for c in (0..self.cells.len()).filter(|&c| self.alive[c]) {
            cells.extend_from_slice(&self.cells[c][..=d]);
            old.push((c < self.n_given).then_some(c));
            origin.push(std::mem::take(&mut self.origin[c]));
        }
        (cells, old, origin)
    }

    /// The other cell on facet `f` of cell `c`, if `f` is interior.
    fn neighbour(&self, c: usize, f: &FacetKey) -> Option<usize> {
        let e = self.facets.get(f)?;
        let o = if e[0] == c { e[1] } else { e[0] };
        (o != NONE && o != c).then_some(o)
    }

    fn point(&self, v: usize) -> [f64; 3] {
        let mut p = [0.0; 3];
        p[..self.dim].copy_from_slice(&self.coords[v * self.dim..(v + 1) * self.dim]);
        p
    }

    fn positive(&self, c: &[usize]) -> bool {
        let x: Vec<[f64; 3]> = c.iter().map(|&v| self.point(v)).collect();
        orient(self.dim, &x) > 0.0
    }

    /// Every valid candidate flip that removes cell `c`.
    pub fn candidates(&self, c: usize) -> Vec<Flip> {
        let mut out = Vec::new();
        let cell = self.cells[c];
        if self.dim == 2 {
            for (k, f) in self.local_facets(cell) {
                if let Some(n) = self.neighbour(c, &f) {
                    out.extend(self.flip22(c, k, n));
                }
            }
            return out;
        }
        for (k, f) in self.local_facets(cell) {
            if let Some(n) = self.neighbour(c, &f) {
                out.extend(self.flip23(c, k, n));
            }
        }
        for i in 0..4 {
            for j in i + 1..4 {
                out.extend(self.edge_removal(cell[i], cell[j], c));
            }
        }
        out
    }

    fn scored(&self, kind: FlipKind, remove: Vec<usize>, add: Vec<[usize; 4]>) -> Option<Flip> {
        let d = self.dim;
        let mut min_quality = f64::INFINITY;
        for c in &add {
            let q = self.assess(&c[..=d]).quality;
            if q == f64::NEG_INFINITY {
                return None;
            }
            min_quality = min_quality.min(q);
        }
        Some(Flip { kind, remove, add, min_quality })
    }

    /// 2D: flip the edge of triangle `c` opposite its local vertex `k`, shared with `n`.
    fn flip22(&self, c: usize, k: usize, n: usize) -> Option<Flip> {
        let t = self.cells[c];
        // Rotate so that t = (a, b, cv) with cv = t[k]: (a, b) is the shared edge, counter-clockwise.
        let (a, b, cv) = (t[(k + 1) % 3], t[(k + 2) % 3], t[k]);
        let dv = *self.cells[n][..3].iter().find(|&&v| v != a && v != b)?;
        if self.facets.contains_key(&facet_key(&[cv, dv])) {
            return None;
        }
        // (a, b, cv) positive and (b, a, dv) positive: new (a, dv, cv) and (b, cv, dv).
        let add = vec![[a, dv, cv, NONE], [b, cv, dv, NONE]];
        self.scored(FlipKind::TwoTwo, vec![c, n], add)
    }

    /// 3D: the 2-3 flip across the face of tet `c` opposite its local vertex `k`, shared with `n`.
    fn flip23(&self, c: usize, k: usize, n: usize) -> Option<Flip> {
        let t = self.cells[c];
        let d = t[k];
        let face: Vec<usize> = (0..4).filter(|&j| j != k).map(|j| t[j]).collect();
        let e = *self.cells[n].iter().find(|v| !face.contains(v))?;
        if self.edges.contains_key(&[d.min(e), d.max(e)]) {
            return None;
        }
        // Order the face (a, b, c) so that (a, b, c, d) is positive.
        let (a, mut b, mut cc) = (face[0], face[1], face[2]);
        if !self.positive(&[a, b, cc, d]) {
            std::mem::swap(&mut b, &mut cc);
        }
        let add = vec![[a, b, e, d], [b, cc, e, d], [cc, a, e, d]];
        self.scored(FlipKind::TwoThree, vec![c, n], add)
    }

    /// The tets around edge (a, b) of tet `c` with the ring of their other
    /// vertices, ordered so that (a, b, r_i, r_(i+1)) is positive; None when
    /// the edge is on the boundary or its ring is larger than [`MAX_RING`].
    fn ring(&self, a: usize, b: usize, c: usize) -> Option<(Vec<usize>, Vec<usize>)> {
        let t = self.cells[c];
        let others: Vec<usize> = t.iter().copied().filter(|&v| v != a && v != b).collect();
        let (mut x, mut y) = (others[0], others[1]);
        if !self.positive(&[a, b, x, y]) {
            std::mem::swap(&mut x, &mut y);
        }
        let (mut tets, mut ring) = (vec![c], vec![x]);
        let mut cur = c;
        loop {
            // Cross the face (a, b, y) into the next tet.
            let next = self.neighbour(cur, &facet_key(&[a, b, y]))?;
            if next == c {
                return Some((tets, ring));
            }
            if tets.len() >= MAX_RING {
                return None;
            }
            let z = *self.cells[next].iter().find(|&&v| v != a && v != b && v != y)?;
            ring.push(y);
            tets.push(next);
            cur = next;
            y = z;
        }
    }

    /// 3D: remove edge (a, b) of tet `c` (module docs).
    fn edge_removal(&self, a: usize, b: usize, c: usize) -> Option<Flip> {
        let (tets, ring) = self.ring(a, b, c)?;
        let n = ring.len();
        if n < 3 {
            return None;
        }
        let kind = if n == 3 { FlipKind::ThreeTwo } else { FlipKind::EdgeRemoval };
        self.remove_edge(kind, a, b, tets, &ring, true)
    }

    /// 3D: remove the boundary edge (a, b) between the boundary facets (a,
    /// b, c) and (a, b, d), which become (a, c, d) and (b, c, d): the tets
    /// around ab, whose ring runs open from c to d, become two tets per
    /// triangle of a triangulation of the ring closed by the new edge cd.
    /// None when ab is not such an edge, its ring has fewer than three
    /// vertices (one tet: a cap, see [`super::caps`]) or more than
    /// [`MAX_RING`], cd is already an edge, or no triangulation is valid.
    pub fn surface_edge_removal(&self, a: usize, b: usize, c: usize, d: usize) -> Option<Flip> {
        if self.dim != 3 || self.edges.contains_key(&[c.min(d), c.max(d)]) {
            return None;
        }
        let e = self.facets.get(&facet_key(&[a, b, c]))?;
        if e[1] != NONE {
            return None;
        }
        // Walk from c across the faces (a, b, y) to the other boundary facet.
        let (mut tets, mut ring) = (vec![], vec![c]);
        let (mut cur, mut y) = (e[0], c);
        loop {
            let z = *self.cells[cur].iter().find(|&&v| v != a && v != b && v != y)?;
            tets.push(cur);
            ring.push(z);
            if tets.len() > MAX_RING {
                return None;
            }
            match self.neighbour(cur, &facet_key(&[a, b, z])) {
                Some(next) => (cur, y) = (next, z),
                None => break,
            }
        }
        if *ring.last()? != d || ring.len() < 3 {
            return None;
        }
        // (a, b, r_i, r_(i+1)) positive, as `remove_edge` wants.
        let (a, b) = if self.positive(&[a, b, ring[0], ring[1]]) { (a, b) } else { (b, a) };
        self.remove_edge(FlipKind::SurfaceEdge, a, b, tets, &ring, false)
    }

    /// Replace the tets around edge (a, b), whose other vertices form the
    /// ring r₀ … r_(n−1) with (a, b, r_i, r_(i+1)) positive, by two tets per
    /// triangle of the triangulation of the ring maximising the smallest
    /// quality (Klincsek's dynamic programme, O(n³)). `closed`: the ring is
    /// closed (an interior edge), else r_(n−1) r₀ is a new edge.
    fn remove_edge(
        &self,
        kind: FlipKind,
        a: usize,
        b: usize,
        tets: Vec<usize>,
        ring: &[usize],
        closed: bool,
    ) -> Option<Flip> {
        let n = ring.len();
        let adjacent = |i: usize, j: usize| j == i + 1 || (closed && i == 0 && j == n - 1);
        let new_edge_ok = |i: usize, j: usize| {
            adjacent(i.min(j), i.max(j)) || !self.edges.contains_key(&[ring[i].min(ring[j]), ring[i].max(ring[j])])
        };
        // Quality of the two tets on ring triangle (i, j, k), i < j < k.
        let mut tri = HashMap::default();
        let mut tri_q = |i: usize, j: usize, k: usize| -> f64 {
            *tri.entry((i, j, k)).or_insert_with(|| {
                if !(new_edge_ok(i, j) && new_edge_ok(j, k) && new_edge_ok(i, k)) {
                    return f64::NEG_INFINITY;
                }
                let (ri, rj, rk) = (ring[i], ring[j], ring[k]);
                let qa = self.assess(&[ri, rk, rj, a]).quality;
                let qb = self.assess(&[ri, rj, rk, b]).quality;
                qa.min(qb)
            })
        };
        // best[i][j]: the best smallest quality of a triangulation of ring i..=j.
        let mut best = vec![vec![f64::INFINITY; n]; n];
        let mut split = vec![vec![NONE; n]; n];
        for len in 2..n {
            for i in 0..n - len {
                let j = i + len;
                best[i][j] = f64::NEG_INFINITY;
                for k in i + 1..j {
                    let q = best[i][k].min(best[k][j]).min(tri_q(i, k, j));
                    if q > best[i][j] {
                        best[i][j] = q;
                        split[i][j] = k;
                    }
                }
            }
        }
        if best[0][n - 1] == f64::NEG_INFINITY {
            return None;
        }
        let mut add = Vec::with_capacity(2 * (n - 2));
        let mut stack = vec![(0, n - 1)];
        while let Some((i, j)) = stack.pop() {
            if j < i + 2 {
                continue;
            }
            let k = split[i][j];
            let (ri, rk, rj) = (ring[i], ring[k], ring[j]);
            add.push([ri, rj, rk, a]);
            add.push([ri, rk, rj, b]);
            stack.push((i, k));
            stack.push((k, j));
        }
        self.scored(kind, tets, add)
    }
}
