//! How far the curved boundary bulges over each straight boundary facet.
//!
//! Before elevation, a few points of every tagged facet are projected onto
//! the geometry: in 3D its three edge midpoints and its centroid, in 2D its
//! midpoint. The bulge of the facet is the largest signed distance of a
//! projected point from the facet's plane (line), positive toward the cell on
//! the facet: the amount by which curving pushes the facet into its cell.
//!
//! Each point goes where the elevation will put the nodes there
//! ([`crate::mesh::HighOrderMesh::elevate`]): the centroid onto the facet's
//! surface; an edge midpoint onto the edge's feature curve, else onto the
//! surface when every boundary facet at the edge has the same tag, else
//! nowhere (the edge stays straight, no point).
//!
//! This module is pure: [`bulge_samples`] lists the points and their
//! entities, the caller projects them (one batched call per entity, see
//! [`crate::geometry::facet_bulges`]) and [`facet_bulges`] measures.

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use super::geom::{boundary_facets, cross, dot, facet_key, facet_of, norm, sub, FacetKey};
use crate::mesh::LinearMesh;

/// Points to project and where each goes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BulgeSamples {
    /// The straight points (z = 0 in 2D).
    pub points: Vec<[f64; 3]>,
    /// Entity (dimension, tag) each point is projected onto.
    pub entities: Vec<(usize, i32)>,
    /// The facet (index among `mesh.facets`) each point belongs to.
    pub facets: Vec<usize>,
    /// The edge (sorted vertices) each point is the midpoint of; None for
    /// a centroid.
    pub edges: Vec<Option<[usize; 2]>>,
}

/// The sample points of every tagged facet (module docs).
pub fn bulge_samples(mesh: &LinearMesh) -> BulgeSamples {
    bulge_samples_on(mesh, &boundary_facets(mesh))
}

/// [`bulge_samples`], the boundary facets of `mesh` known ([`boundary_facets`]).
pub fn bulge_samples_on(mesh: &LinearMesh, boundary: &[FacetKey]) -> BulgeSamples {
    let d = mesh.dim;
    let mut s = BulgeSamples::default();
    if d == 2 {
        for (k, (f, &tag)) in mesh.facets.chunks_exact(2).zip(&mesh.facet_tags).enumerate() {
            let (a, b) = (mesh.vertex(f[0]), mesh.vertex(f[1]));
            s.points.push(mid(a, b));
            s.entities.push((1, tag));
            s.facets.push(k);
            s.edges.push(Some([f[0].min(f[1]), f[0].max(f[1])]));
        }
        return s;
    }
    if d != 3 {
        return s;
    }
    // Tags of the boundary faces (None: untagged) at each boundary edge.
    let tagged: HashMap<FacetKey, i32> =
        mesh.facets.chunks_exact(3).zip(&mesh.facet_tags).map(|(f, &t)| (facet_key(f), t)).collect();
    let mut edge_tags: HashMap<[usize; 2], Option<Option<i32>>> = HashMap::default();
    for &f in boundary {
        let t = tagged.get(&f).copied();
        for e in [[f[0], f[1]], [f[1], f[2]], [f[0], f[2]]] {
            edge_tags
                .entry(e)
                .and_modify(|s| {
                    if *s != Some(t) {
                        *s = None
                    }
                })
                .or_insert(Some(t));
        }
    }
    let features: HashMap<[usize; 2], i32> = mesh
        .feature_edges
        .chunks_exact(2)
        .zip(&mesh.feature_edge_tags)
        .map(|(e, &t)| ([e[0].min(e[1]), e[0].max(e[1])], t))
        .collect();
    for (k, (f, &tag)) in mesh.facets.chunks_exact(3).zip(&mesh.facet_tags).enumerate() {
        let x = [mesh.vertex(f[0]), mesh.vertex(f[1]), mesh.vertex(f[2])];
        for (i, j) in [(0, 1), (1, 2), (0, 2)] {
            let e = [f[i].min(f[j]), f[i].max(f[j])];
            let entity = match (features.get(&e), edge_tags.get(&e)) {
                (Some(&curve), _) => Some((1, curve)),
                (None, Some(Some(Some(t)))) => Some((2, *t)),
                _ => None,
            };
            if let Some(entity) = entity {
                s.points.push(mid(x[i], x[j]));
                s.entities.push(entity);
                s.facets.push(k);
                s.edges.push(Some(e));
            }
        }
        s.points.push([0, 1, 2].map(|c| (x[0][c] + x[1][c] + x[2][c]) / 3.0));
        s.entities.push((2, tag));
        s.facets.push(k);
        s.edges.push(None);
    }
    s
}

/// The bulge of every tagged facet (module docs) from the projections of
/// its sample points (`projected[i]` of `samples.points[i]`): one value per
/// facet of `mesh`, 0 for a facet without a point or without a cell.
pub fn facet_bulges(mesh: &LinearMesh, samples: &BulgeSamples, projected: &[[f64; 3]]) -> Vec<f64> {
    let d = mesh.dim;
    let nf = mesh.n_facets();
    let mut bulge = vec![0.0; nf];
    if d != 2 && d != 3 {
        return bulge;
    }
    // Inward unit normal of each facet: toward the vertex opposite it in its cell.
    let index: HashMap<FacetKey, usize> =
        mesh.facets.chunks_exact(d).enumerate().map(|(k, f)| (facet_key(f), k)).collect();
    let mut normal: Vec<Option<[f64; 3]>> = vec![None; nf];
    let mut seen = HashSet::default();
    for c in mesh.cells.chunks_exact(d + 1) {
        for k in 0..=d {
            if let Some(&i) = index.get(&facet_of(c, k)) {
                let f: Vec<usize> = (0..=d).filter(|&j| j != k).map(|j| c[j]).collect();
                if !seen.insert(i) {
                    continue;
                }
                let x0 = mesh.vertex(f[0]);
                let t = sub(mesh.vertex(f[1]), x0);
                let n = if d == 2 { [-t[1], t[0], 0.0] } else { cross(t, sub(mesh.vertex(f[2]), x0)) };
                let l = norm(n);
                if l > 0.0 {
                    let s = if dot(n, sub(mesh.vertex(c[k]), x0)) < 0.0 { -1.0 / l } else { 1.0 / l };
                    normal[i] = Some(n.map(|v| v * s));
                }
            }
        }
    }
    let mut any = vec![false; nf];
    for ((&k, x), y) in samples.facets.iter().zip(&samples.points).zip(projected) {
        let Some(n) = normal.get(k).copied().flatten() else { continue };
        let b = dot(sub(*y, *x), n);
        if !b.is_finite() {
            continue;
        }
        bulge[k] = if any[k] { bulge[k].max(b) } else { b };
        any[k] = true;
    }
    bulge
}

fn mid(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])]
}
