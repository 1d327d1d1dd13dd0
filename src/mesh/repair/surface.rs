//! Surface edges flipped where a smooth surface folds a facet once curved.
//!
//! A boundary facet (a, b, c) whose chord ab cuts deep under a curved
//! surface can look fat as a straight triangle and still be a sliver on the
//! surface: curving moves the midpoint of ab onto the surface, and when that
//! motion, measured in the facet's plane, carries it most of the way to c,
//! the curved facet nearly folds, and every cell on it with it. Neither the
//! interior nodes nor the boundary nodes sliding on the surface open it: the
//! triangle is thin where it lives. (A crankshaft meshed by gmsh has one: a
//! 27-long chord across a 43° cylinder patch of radius 36.5 whose midpoint
//! moves 2.6 outward, 0.94 of the way to the third vertex, which stands 0.65
//! from the chord on the cylinder.)
//!
//! The *squeeze* of a facet is the largest, over its edges whose midpoint
//! goes onto the facet's own surface ([`super::bulge`]), of the midpoint's
//! displacement toward the opposite vertex, in the facet's plane, over that
//! vertex's distance from the edge. A facet whose squeeze passes
//! [`SQUEEZE_FRACTION`] has that edge ab flipped to the other diagonal cd of
//! the facets (a, b, c) and (a, b, d) on its two sides, which carry the same
//! tag: the tets around ab are replaced by the best triangulation of their
//! ring closed by cd, coned to a and to b ([`super::flips`]). The new tets
//! must be valid and not bad ([`super::detect`]). The flipped facets are then
//! measured: a flip is kept only when the squeeze of (a, c, d) and (b, c, d)
//! is below that of (a, b, c) and (a, b, d); otherwise the round is done
//! again without it. The boundary's vertices and tags are kept; the straight
//! domain gains or loses the tet (a, b, c, d), which the curved boundary
//! covers either way.

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use super::bulge::BulgeSamples;
use super::detect::Criteria;
use super::flips::Work;
use super::geom::{dot, facet_key, norm, sub, FacetKey};
use crate::mesh::LinearMesh;

/// A facet whose squeeze passes this fraction has its edge flipped.
pub const SQUEEZE_FRACTION: f64 = 0.5;

/// The squeeze of a facet and the edge that gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Squeeze {
    pub value: f64,
    pub edge: [usize; 2],
}

/// The squeeze (module docs) of every tagged facet with a sample on its
/// surface, by facet key, from the projections of the samples of `mesh`.
pub fn squeezes(mesh: &LinearMesh, samples: &BulgeSamples, projected: &[[f64; 3]]) -> HashMap<FacetKey, Squeeze> {
    let mut out: HashMap<FacetKey, Squeeze> = HashMap::default();
    if mesh.dim != 3 {
        return out;
    }
    for (i, &k) in samples.facets.iter().enumerate() {
        let (Some(e), Some(y)) = (samples.edges[i], projected.get(i)) else { continue };
        if samples.entities[i] != (2, mesh.facet_tags[k]) {
            continue;
        }
        let f = &mesh.facets[3 * k..3 * k + 3];
        let Some(&o) = f.iter().find(|&&v| v != e[0] && v != e[1]) else { continue };
        let (a, b, c) = (mesh.vertex(e[0]), mesh.vertex(e[1]), mesh.vertex(o));
        // In the facet's plane, normal to ab, from ab to c (length h).
        let t = sub(b, a);
        let ac = sub(c, a);
        let s = dot(ac, t) / dot(t, t);
        let w = [ac[0] - s * t[0], ac[1] - s * t[1], ac[2] - s * t[2]];
        let h = norm(w);
        if h.is_nan() || h <= 0.0 {
            continue;
        }
        let value = dot(sub(*y, samples.points[i]), w) / (h * h);
        let key = facet_key(f);
        if out.get(&key).is_none_or(|q| value > q.value) {
            out.insert(key, Squeeze { value, edge: e });
        }
    }
    out
}

/// A surface edge flipped: ab became cd.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceFlip {
    pub ab: [usize; 2],
    pub cd: [usize; 2],
    /// The larger squeeze of (a, b, c) and (a, b, d).
    pub squeeze: f64,
}

impl SurfaceFlip {
    /// The larger squeeze of the new facets (a, c, d) and (b, c, d), −∞ when not measured.
    pub fn squeeze_after(&self, squeeze: &HashMap<FacetKey, Squeeze>) -> f64 {
        let [c, d] = self.cd;
        self.ab
            .iter()
            .filter_map(|&v| squeeze.get(&facet_key(&[v, c, d])))
            .map(|q| q.value)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// One round of surface flips.
pub struct Round {
    /// The new mesh: the cells no flip touched, in their order, then the new cells.
    pub mesh: LinearMesh,
    /// For each cell of `mesh`: its index in the mesh given, None for a new cell.
    pub old: Vec<Option<usize>>,
    /// For each cell of `mesh`: the cells of the reference mesh it overlaps.
    pub origin: Vec<Vec<usize>>,
    pub flips: Vec<SurfaceFlip>,
}

/// Flip the edges of the facets of `mesh` whose squeeze passes
/// [`SQUEEZE_FRACTION`] (module docs), worst first, at most one flip per
/// vertex, except the edges in `refused`. `bulge`: one value per facet;
/// `origin[c]`: the cells of some reference mesh that cell c overlaps.
/// None when nothing is flipped.
pub fn flip_round(
    mesh: &LinearMesh,
    bulge: &[f64],
    squeeze: &HashMap<FacetKey, Squeeze>,
    origin: &[Vec<usize>],
    refused: &HashSet<[usize; 2]>,
) -> Option<Round> {
    if mesh.dim != 3 {
        return None;
    }
    // Boundary facets at each edge, with their tags.
    let mut at_edge: HashMap<[usize; 2], Vec<(usize, i32)>> = HashMap::default();
    for (f, &tag) in mesh.facets.chunks_exact(3).zip(&mesh.facet_tags) {
        for (i, j, o) in [(0, 1, 2), (1, 2, 0), (0, 2, 1)] {
            at_edge.entry([f[i].min(f[j]), f[i].max(f[j])]).or_default().push((f[o], tag));
        }
    }
    let features: HashSet<[usize; 2]> =
        mesh.feature_edges.chunks_exact(2).map(|e| [e[0].min(e[1]), e[0].max(e[1])]).collect();
    let worst = worst_first(squeeze, &at_edge, refused);
    if worst.is_empty() {
        return None;
    }
    let crit = Criteria::new(mesh, bulge);
    let mut w = Work::new(mesh, &crit, origin.to_vec());
    let (mut facets, mut tags) = (mesh.facets.clone(), mesh.facet_tags.clone());
    let mut removed_facets = HashSet::default();
    let mut touched = HashSet::default();
    let mut flips = Vec::new();
    for (value, [a, b]) in worst {
        let Some(&[(c, tc), (d, td)]) = at_edge.get(&[a, b]).map(Vec::as_slice) else { continue };
        if tc != td || features.contains(&[a, b]) || [a, b, c, d].iter().any(|v| touched.contains(v)) {
            continue;
        }
        let Some(flip) = w.surface_edge_removal(a, b, c, d) else { continue };
        if flip.min_quality <= 0.0 {
            continue;
        }
        for &t in &flip.remove {
            touched.extend(w.cells[t]);
        }
        w.apply(&flip);
        removed_facets.insert(facet_key(&[a, b, c]));
        removed_facets.insert(facet_key(&[a, b, d]));
        for v in [a, b] {
            facets.extend_from_slice(&[v, c, d]);
            tags.push(tc);
        }
        flips.push(SurfaceFlip { ab: [a, b], cd: [c.min(d), c.max(d)], squeeze: value });
    }
    if flips.is_empty() {
        return None;
    }
    let (cells, old, origin) = w.into_cells();
    let mut out = mesh.clone();
    out.cells = cells;
    (out.facets, out.facet_tags) = (Vec::new(), Vec::new());
    for (f, &t) in facets.chunks_exact(3).zip(&tags) {
        if !removed_facets.contains(&facet_key(f)) {
            out.facets.extend_from_slice(f);
            out.facet_tags.push(t);
        }
    }
    Some(Round { mesh: out, old, origin, flips })
}

/// The edges of the facets whose squeeze passes [`SQUEEZE_FRACTION`], but
/// those in `refused`, with the larger squeeze of the facets on their two
/// sides (`at_edge`: each edge's facets by opposite vertex), worst first;
/// ties by edge, so the order is the same whatever the hash maps' order.
fn worst_first(
    squeeze: &HashMap<FacetKey, Squeeze>,
    at_edge: &HashMap<[usize; 2], Vec<(usize, i32)>>,
    refused: &HashSet<[usize; 2]>,
) -> Vec<(f64, [usize; 2])> {
    let candidates: HashSet<[usize; 2]> =
        squeeze.values().filter(|q| q.value > SQUEEZE_FRACTION && !refused.contains(&q.edge)).map(|q| q.edge).collect();
    let facet_squeeze = |f: FacetKey| squeeze.get(&f).map_or(f64::NEG_INFINITY, |q| q.value);
    let mut worst: Vec<(f64, [usize; 2])> = candidates
        .into_iter()
        .filter_map(|e| {
            let sides = at_edge.get(&e)?;
            let v = sides
                .iter()
                .map(|&(o, _)| facet_squeeze(facet_key(&[e[0], e[1], o])))
                .fold(f64::NEG_INFINITY, f64::max);
            Some((v, e))
        })
        .collect();
    worst.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    worst
}
