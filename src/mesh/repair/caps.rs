//! Boundary caps: tetrahedra that no curving can keep valid.
//!
//! A cap is a tet with two faces on the same smooth boundary surface (same
//! entity tag, nearly parallel normals) that share an edge ab, while its other
//! two faces and its chord edge cd are interior. Once the boundary is curved,
//! the tangents of both boundary faces along ab lie in the surface's tangent
//! plane, so the Jacobian determinant vanishes along ab as the surface is
//! resolved and its sign is left to the interpolation error: such tets come
//! out inverted whatever the interior does (the boundary alone fixes all
//! their nodes but one at p = 2). Mesh generators that fill thin regions with
//! few interior points make them routinely (CGAL's Mesh_3 on a solid torus:
//! 102 caps among 3,963 tets, 77 of them inverted after curving at p = 2).
//!
//! [`remove_boundary_caps`] removes each cap, which flips the surface edge ab
//! to the chord cd: the faces acd and bcd become boundary faces with the
//! cap's tag. All four vertices stay on the surface, so the curved mesh covers
//! the same curved domain; it only has fewer cells. Splitting a cap at its
//! centroid instead was tried and is worse (its sub-cells are as flat as the
//! cap: 239 inverted cells on the same torus). Repeated until no cap is left.

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use crate::mesh::LinearMesh;

/// Largest angle between the outward normals of a cap's two boundary faces:
/// beyond it the shared edge is a crease of the surface and is kept.
pub const CAP_MAX_NORMAL_ANGLE_DEG: f64 = 45.0;

fn sorted3(a: usize, b: usize, c: usize) -> [usize; 3] {
    let mut f = [a, b, c];
    f.sort_unstable();
    f
}

fn sub(x: &[f64], a: usize, b: usize) -> [f64; 3] {
    [x[3 * a] - x[3 * b], x[3 * a + 1] - x[3 * b + 1], x[3 * a + 2] - x[3 * b + 2]]
}

fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
}

fn dot(u: [f64; 3], v: [f64; 3]) -> f64 {
    u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
}

/// Unit normal of face (a, b, c) pointing away from vertex `opposite`.
fn outward_normal(x: &[f64], a: usize, b: usize, c: usize, opposite: usize) -> [f64; 3] {
    let n = cross(sub(x, b, a), sub(x, c, a));
    let s = if dot(n, sub(x, opposite, a)) > 0.0 { -1.0 } else { 1.0 };
    let l = dot(n, n).sqrt();
    [s * n[0] / l, s * n[1] / l, s * n[2] / l]
}

/// Remove the boundary caps of a 3D mesh (module docs). Returns the new mesh
/// and, for each of its cells, the index of that cell in `mesh` (cells keep
/// their order). A 2D mesh is returned unchanged.
pub fn remove_boundary_caps(mesh: &LinearMesh) -> (LinearMesh, Vec<usize>) {
    let mut out = mesh.clone();
    let mut kept: Vec<usize> = (0..mesh.cells.len() / (mesh.dim + 1)).collect();
    let cos_max = CAP_MAX_NORMAL_ANGLE_DEG.to_radians().cos();
    while let Some((next, k)) = sweep(&out, |_, cos| cos >= cos_max) {
        kept = k.iter().map(|&i| kept[i]).collect();
        out = next;
    }
    (out, kept)
}

/// One sweep of cap removal over a 3D mesh: every cap (module docs) that
/// `accept(cell, cos)` takes, with cos the cosine of the angle between the
/// outward normals of its two boundary faces, is removed, except those that
/// share a vertex with one removed before in the sweep (their flips could
/// conflict). None when nothing is removed (always in 2D); else the new mesh
/// and, for each of its cells, its index in `mesh` (cells keep their order).
pub fn sweep(mesh: &LinearMesh, accept: impl Fn(usize, f64) -> bool) -> Option<(LinearMesh, Vec<usize>)> {
    if mesh.dim != 3 {
        return None;
    }
    let mut out = mesh.clone();
    let features: HashSet<[usize; 2]> =
        mesh.feature_edges.chunks_exact(2).map(|e| [e[0].min(e[1]), e[0].max(e[1])]).collect();
    let faces: HashMap<[usize; 3], usize> =
        out.facets.chunks_exact(3).enumerate().map(|(i, f)| (sorted3(f[0], f[1], f[2]), i)).collect();
    let boundary_edges: HashSet<[usize; 2]> = out
        .facets
        .chunks_exact(3)
        .flat_map(|f| [[f[0], f[1]], [f[1], f[2]], [f[0], f[2]]])
        .chain(features.iter().copied())
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    let mut remove_cell = vec![false; out.n_cells()];
    let mut remove_facet = vec![false; out.facet_tags.len()];
    let mut touched = HashSet::default();
    let (mut new_facets, mut new_tags) = (Vec::new(), Vec::new());
    for (ci, cell) in out.cells.chunks_exact(4).enumerate() {
        // Boundary faces as (opposite local vertex, facet index).
        let on: Vec<(usize, usize)> = (0..4)
            .filter_map(|k| {
                let f: Vec<usize> = (0..4).filter(|&j| j != k).map(|j| cell[j]).collect();
                faces.get(&sorted3(f[0], f[1], f[2])).map(|&i| (k, i))
            })
            .collect();
        let [(kc, fc), (kd, fd)] = on[..] else { continue };
        if out.facet_tags[fc] != out.facet_tags[fd] || cell.iter().any(|v| touched.contains(v)) {
            continue;
        }
        let (c, d) = (cell[kc], cell[kd]);
        let ab: Vec<usize> = cell.iter().copied().filter(|&v| v != c && v != d).collect();
        let (a, b) = (ab[0], ab[1]);
        if boundary_edges.contains(&[c.min(d), c.max(d)]) || features.contains(&[a.min(b), a.max(b)]) {
            continue;
        }
        // A new facet (o, c, d) whose edges oc and od both lie on feature
        // curves has all three vertices on a curve: its chord cd, once
        // curved onto the surface, lands on that curve at o, and the facet
        // folds whatever the interior does (a coarse arc meshed by gmsh on a
        // fillet's boundary). Keep such a cap for the optimisation stage.
        let on_curve = |o: usize, v: usize| features.contains(&[o.min(v), o.max(v)]);
        if [a, b].iter().any(|&o| on_curve(o, c) && on_curve(o, d)) {
            continue;
        }
        // Face opposite c is (a, b, d); opposite d is (a, b, c).
        let n1 = outward_normal(&out.coords, a, b, d, c);
        let n2 = outward_normal(&out.coords, a, b, c, d);
        if !accept(ci, dot(n1, n2)) {
            continue;
        }
        remove_cell[ci] = true;
        remove_facet[fc] = true;
        remove_facet[fd] = true;
        touched.extend(cell.iter().copied());
        for o in [a, b] {
            new_facets.extend_from_slice(&[o, c, d]);
            new_tags.push(out.facet_tags[fc]);
        }
    }
    if !remove_cell.contains(&true) {
        return None;
    }
    let kept: Vec<usize> = (0..remove_cell.len()).filter(|&i| !remove_cell[i]).collect();
    out.cells = kept.iter().flat_map(|&i| mesh.cells[4 * i..4 * i + 4].to_vec()).collect();
    let (mut facets, mut tags) = (Vec::new(), Vec::new());
    for (i, (f, &t)) in mesh.facets.chunks_exact(3).zip(&mesh.facet_tags).enumerate() {
        if !remove_facet[i] {
            facets.extend_from_slice(f);
            tags.push(t);
        }
    }
    facets.extend(new_facets);
    tags.extend(new_tags);
    out.facets = facets;
    out.facet_tags = tags;
    Some((out, kept))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn volume(m: &LinearMesh) -> f64 {
        m.cells
            .chunks(4)
            .map(|c| {
                dot(sub(&m.coords, c[1], c[0]), cross(sub(&m.coords, c[2], c[0]), sub(&m.coords, c[3], c[0]))).abs()
                    / 6.0
            })
            .sum()
    }

    /// A flat cap (a, b, c, d) under a ridge ab, on two tets sharing cde.
    /// Top faces tag 1, the sides towards c tag 2, towards d tag 3.
    pub(crate) fn ridge() -> LinearMesh {
        let (a, b, c, d, e) = (0, 1, 2, 3, 4);
        LinearMesh {
            dim: 3,
            coords: vec![0.0, 0.0, 0.05, 1.0, 0.0, 0.05, 0.5, 1.0, 0.0, 0.5, -1.0, 0.0, 0.5, 0.0, -1.0],
            cells: vec![a, b, c, d, a, c, d, e, b, c, d, e],
            facets: vec![a, b, c, a, b, d, a, c, e, b, c, e, a, d, e, b, d, e],
            facet_tags: vec![1, 1, 2, 2, 3, 3],
            feature_edges: vec![],
            feature_edge_tags: vec![],
        }
    }

    #[test]
    fn a_flat_cap_is_removed_and_its_ridge_flipped_to_the_chord() {
        let m = ridge();
        let (r, kept) = remove_boundary_caps(&m);
        assert_eq!(kept, vec![1, 2]);
        assert_eq!(r.cells, m.cells[4..].to_vec());
        let mut top: Vec<[usize; 3]> = r
            .facets
            .chunks(3)
            .zip(&r.facet_tags)
            .filter(|(_, &t)| t == 1)
            .map(|(f, _)| sorted3(f[0], f[1], f[2]))
            .collect();
        top.sort();
        assert_eq!(top, vec![[0, 2, 3], [1, 2, 3]]);
        assert_eq!(r.facets.len(), m.facets.len());
        let cap = volume(&LinearMesh { cells: m.cells[..4].to_vec(), ..m.clone() });
        assert!((volume(&m) - volume(&r) - cap).abs() < 1e-15);
        // Nothing left to remove.
        assert_eq!(remove_boundary_caps(&r).1.len(), 2);
    }

    #[test]
    fn a_cap_whose_faces_carry_different_tags_or_meet_at_a_crease_is_kept() {
        let mut m = ridge();
        m.facet_tags[1] = 4;
        assert_eq!(remove_boundary_caps(&m).1, vec![0, 1, 2]);
        // Raise the ridge: the top faces now meet at about 90 degrees.
        let mut m = ridge();
        m.coords[2] = 0.5;
        m.coords[5] = 0.5;
        assert_eq!(remove_boundary_caps(&m).1, vec![0, 1, 2]);
        // The ridge is a feature curve.
        let mut m = ridge();
        m.feature_edges = vec![0, 1];
        m.feature_edge_tags = vec![7];
        assert_eq!(remove_boundary_caps(&m).1, vec![0, 1, 2]);
    }

    #[test]
    fn a_cap_whose_new_facet_would_have_all_vertices_on_one_curve_is_kept() {
        // Edges ac and ad on a feature curve: the new facet acd would lie
        // with all three vertices on that curve.
        let mut m = ridge();
        m.feature_edges = vec![0, 2, 0, 3];
        m.feature_edge_tags = vec![7, 7];
        assert_eq!(remove_boundary_caps(&m).1, vec![0, 1, 2]);
        // One of them only: the cap goes.
        m.feature_edges = vec![0, 2];
        m.feature_edge_tags = vec![7];
        assert_eq!(remove_boundary_caps(&m).1, vec![1, 2]);
    }
}
