//! Interior edges split where a smooth boundary would squeeze a cell flat.
//!
//! The Jacobian of a curved cell at one of its vertices x is the product of
//! the tangents of the cell's edges there. Take a triangle (x, y, z) of the
//! mesh that is not a boundary facet but whose edges xy and xz are boundary
//! edges (edges of boundary facets), with the boundary smooth at x. Curved,
//! xy and xz start in the boundary's tangent plane at x, so the triangle
//! starts in that plane too; and the cells on one side of it lie between it
//! and the boundary. Those cells need their third edge at x to leave x on
//! the outer side of the tangent plane, out of the domain: det J at x tends
//! to 0 or below, whatever the interior nodes do, at every order. The
//! typical case is a tet with two boundary faces on a fillet and on the
//! plane it meets tangentially (its two other faces are such triangles, at
//! both ends of the common edge); neither cap removal (the faces are on two
//! surfaces, and the curve between them stays) nor a flip removes it, and a
//! split at its centroid only moves the triangle into a piece.
//!
//! Such a triangle is *squeezed* when the boundary facets through xy and xz
//! have outward normals less than [`SMOOTH_ANGLE_DEG`] apart (at a corner or
//! a crease of the geometry they are far apart, and det J keeps its sign),
//! and yz is not a boundary edge. Its edge yz is split at its midpoint m, a
//! new interior vertex: every cell around yz becomes two, and the triangle
//! becomes (x, y, m) and (x, m, z), each with one boundary edge at x. The
//! cells made have m as a vertex, whose edges are interior, so they are
//! never squeezed themselves; rounds repeat until no triangle is squeezed.
//! In 2D the triangle is a cell with two boundary edges at a vertex. The
//! boundary facets are unchanged and the pieces cover each cell exactly.

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use super::detect::Criteria;
use super::geom::{cross, dot, facet_of, norm, sub};
use crate::mesh::LinearMesh;

/// The boundary facets through two boundary edges at a vertex whose outward
/// normals are all less than this apart make the boundary smooth there.
pub const SMOOTH_ANGLE_DEG: f64 = 60.0;

/// Rounds of splits at most ([`split_squeezed`]).
pub const MAX_SPLIT_ROUNDS: usize = 8;

type Edge = [usize; 2];

fn edge(a: usize, b: usize) -> Edge {
    [a.min(b), a.max(b)]
}

/// Per boundary edge, the unit outward normals of the boundary facets through it.
fn boundary_edges(mesh: &LinearMesh, crit: &Criteria) -> HashMap<Edge, Vec<[f64; 3]>> {
    use rayon::prelude::*;
    let d = mesh.dim;
    let facets: Vec<([usize; 3], [f64; 3])> = mesh
        .cells
        .par_chunks_exact(d + 1)
        .flat_map_iter(|cell| {
            (0..=d).filter_map(move |k| {
                let key = facet_of(cell, k);
                crit.is_boundary(&key).then(|| (key, outward_normal(mesh, cell, k)))
            })
        })
        .collect();
    let mut normals: HashMap<Edge, Vec<[f64; 3]>> = HashMap::default();
    for (key, n) in facets {
        let f = &key[..d];
        for i in 0..d {
            for j in i + 1..d {
                normals.entry(edge(f[i], f[j])).or_default().push(n);
            }
        }
    }
    normals
}

/// Unit normal of the facet of `cell` opposite its vertex `k`, pointing away from that vertex.
fn outward_normal(mesh: &LinearMesh, cell: &[usize], k: usize) -> [f64; 3] {
    let x: Vec<[f64; 3]> = cell.iter().map(|&v| mesh.vertex(v)).collect();
    let f: Vec<[f64; 3]> = (0..x.len()).filter(|&j| j != k).map(|j| x[j]).collect();
    let mut n = if mesh.dim == 2 {
        let t = sub(f[1], f[0]);
        [t[1], -t[0], 0.0]
    } else {
        cross(sub(f[1], f[0]), sub(f[2], f[0]))
    };
    let s = if dot(n, sub(x[k], f[0])) > 0.0 { -1.0 } else { 1.0 } / norm(n);
    for c in &mut n {
        *c *= s;
    }
    n
}

/// The edge yz of triangle `t` to split because of its vertex x (module docs), if any.
fn squeezed_edge(t: [usize; 3], normals: &HashMap<Edge, Vec<[f64; 3]>>) -> Option<Edge> {
    let cos_max = SMOOTH_ANGLE_DEG.to_radians().cos();
    (0..3).find_map(|i| {
        let (x, y, z) = (t[i], t[(i + 1) % 3], t[(i + 2) % 3]);
        let (a, b) = (normals.get(&edge(x, y))?, normals.get(&edge(x, z))?);
        if normals.contains_key(&edge(y, z)) {
            return None;
        }
        let all: Vec<&[f64; 3]> = a.iter().chain(b).collect();
        let smooth = all.iter().enumerate().all(|(i, &&u)| all[i + 1..].iter().all(|&&w| dot(u, w) > cos_max));
        smooth.then(|| edge(y, z))
    })
}

/// The interior edges of `mesh` to split (module docs), sorted; `crit` made for `mesh`.
pub fn squeezed_edges(mesh: &LinearMesh, crit: &Criteria) -> Vec<Edge> {
    let d = mesh.dim;
    let normals = boundary_edges(mesh, crit);
    let mut out: HashSet<Edge> = HashSet::default();
    let on_boundary = |v: &usize| crit.is_boundary_vertex(*v);
    for cell in mesh.cells.chunks_exact(d + 1).filter(|c| c.iter().filter(|v| on_boundary(v)).count() >= 3) {
        let triangles: Vec<[usize; 3]> = if d == 2 {
            vec![[cell[0], cell[1], cell[2]]]
        } else {
            let interior = (0..4).map(|k| facet_of(cell, k)).filter(|f| !crit.is_boundary(f));
            interior.filter(|f| f.iter().all(on_boundary)).map(|f| [f[0], f[1], f[2]]).collect()
        };
        out.extend(triangles.into_iter().filter_map(|t| squeezed_edge(t, &normals)));
    }
    let mut out: Vec<Edge> = out.into_iter().collect();
    out.sort_unstable();
    out
}

/// A mesh with some edges split.
#[derive(Debug, Clone)]
pub struct Split {
    pub mesh: LinearMesh,
    /// For each cell of `mesh`, the cell of the mesh given it is or is part of.
    pub parent: Vec<usize>,
    /// For each cell of `mesh`, whether it is its parent, unchanged.
    pub whole: Vec<bool>,
    /// Edges split.
    pub edges: usize,
}

/// Split `edges` (sorted) of `mesh` at their midpoints, each in all its
/// cells, skipping an edge that shares a cell with one split before it.
/// The cells no split touched keep their order, then come the halves, in
/// pairs.
pub fn split_edges(mesh: &LinearMesh, edges: &[Edge]) -> Split {
    let d = mesh.dim;
    let wanted: HashSet<Edge> = edges.iter().copied().collect();
    let mut around: HashMap<Edge, Vec<usize>> = HashMap::default();
    for (c, cell) in mesh.cells.chunks_exact(d + 1).enumerate() {
        for i in 0..=d {
            for j in i + 1..=d {
                let e = edge(cell[i], cell[j]);
                if wanted.contains(&e) {
                    around.entry(e).or_default().push(c);
                }
            }
        }
    }
    let mut taken = vec![false; mesh.n_cells()];
    let mut chosen: Vec<(Edge, &[usize])> = Vec::new();
    for e in edges {
        let Some(cells) = around.get(e) else { continue };
        if cells.iter().all(|&c| !taken[c]) {
            cells.iter().for_each(|&c| taken[c] = true);
            chosen.push((*e, cells));
        }
    }
    let mut out = mesh.clone();
    out.cells.clear();
    let mut from = Vec::with_capacity(mesh.n_cells() + chosen.iter().map(|(_, c)| c.len()).sum::<usize>());
    for (c, cell) in mesh.cells.chunks_exact(d + 1).enumerate().filter(|&(c, _)| !taken[c]) {
        out.cells.extend_from_slice(cell);
        from.push(c);
    }
    for &([y, z], cells) in &chosen {
        let m = out.n_vertices();
        for i in 0..d {
            out.coords.push(0.5 * (mesh.coords[y * d + i] + mesh.coords[z * d + i]));
        }
        for &c in cells {
            let cell = &mesh.cells[c * (d + 1)..(c + 1) * (d + 1)];
            // A vertex replaced by a point of an edge from it: the orientation is kept.
            for gone in [z, y] {
                out.cells.extend(cell.iter().map(|&v| if v == gone { m } else { v }));
                from.push(c);
            }
        }
    }
    let whole =
        (0..from.len()).map(|i| i < mesh.n_cells() - chosen.iter().map(|(_, c)| c.len()).sum::<usize>()).collect();
    Split { mesh: out, parent: from, whole, edges: chosen.len() }
}

/// Split the squeezed triangles' edges of `mesh` (module docs), round after
/// round, at most [`MAX_SPLIT_ROUNDS`]; `bulge` as for [`Criteria::new`]
/// (splits keep the facets).
pub fn split_squeezed(mesh: &LinearMesh, bulge: &[f64]) -> Split {
    split_squeezed_with(mesh, Criteria::new(mesh, bulge))
}

/// [`split_squeezed`] with the criteria `crit` of `mesh` already made.
pub fn split_squeezed_with(mesh: &LinearMesh, mut crit: Criteria) -> Split {
    let n = mesh.n_cells();
    let mut done = Split { mesh: mesh.clone(), parent: (0..n).collect(), whole: vec![true; n], edges: 0 };
    for _ in 0..MAX_SPLIT_ROUNDS {
        let edges = squeezed_edges(&done.mesh, &crit);
        if edges.is_empty() {
            break;
        }
        let next = split_edges(&done.mesh, &edges);
        crit = crit.after_split(next.mesh.n_vertices());
        done = Split {
            parent: next.parent.iter().map(|&c| done.parent[c]).collect(),
            whole: next.parent.iter().zip(&next.whole).map(|(&c, &w)| w && done.whole[c]).collect(),
            edges: done.edges + next.edges,
            mesh: next.mesh,
        };
    }
    done
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::repair::geom::orient;

    /// A 2D mesh whose boundary turns smoothly at O = (0, 0): the line y = 0
    /// (facet A–O, tag 1) meets the circle of radius 2 about (0, 2) (facet
    /// O–B, tag 2) tangentially. Triangle (A, O, B) has both its boundary
    /// edges at O, 15° apart; its edge A–B is interior.
    fn smooth_hinge_2d() -> LinearMesh {
        let b = 2.0 - 3f64.sqrt();
        LinearMesh {
            dim: 2,
            coords: vec![-1.0, 0.0, 0.0, 0.0, 1.0, b, 1.0, 1.5, -1.0, 1.5],
            cells: vec![0, 1, 2, 0, 2, 3, 0, 3, 4],
            facets: vec![0, 1, 1, 2, 2, 3, 3, 4, 4, 0],
            facet_tags: vec![1, 2, 3, 4, 5],
            feature_edges: vec![],
            feature_edge_tags: vec![],
        }
    }

    /// The same region turned at a corner: B moved so that O–B leaves O at 70°.
    fn corner_2d() -> LinearMesh {
        let mut m = smooth_hinge_2d();
        let a = 70f64.to_radians();
        m.coords[4..6].copy_from_slice(&[a.cos(), a.sin()]);
        m
    }

    fn area(m: &LinearMesh) -> f64 {
        m.cells.chunks(m.dim + 1).map(|c| orient(m.dim, &c.iter().map(|&v| m.vertex(v)).collect::<Vec<_>>())).sum()
    }

    fn no_bulge(m: &LinearMesh) -> Vec<f64> {
        vec![0.0; m.n_facets()]
    }

    #[test]
    fn a_triangle_with_two_boundary_edges_at_a_smooth_vertex_has_its_third_edge_split() {
        let m = smooth_hinge_2d();
        assert_eq!(squeezed_edges(&m, &Criteria::new(&m, &no_bulge(&m))), vec![[0, 2]]);
        let s = split_squeezed(&m, &no_bulge(&m));
        assert_eq!(s.edges, 1);
        // The midpoint of A–B is the new vertex 5; the cell untouched comes first.
        assert_eq!(s.mesh.vertex(5), [0.0, (2.0 - 3f64.sqrt()) / 2.0, 0.0]);
        assert_eq!(s.mesh.cells, vec![0, 3, 4, 0, 1, 5, 5, 1, 2, 0, 5, 3, 5, 2, 3]);
        assert_eq!((s.parent, s.whole), (vec![2, 0, 0, 1, 1], vec![true, false, false, false, false]));
        assert_eq!((&s.mesh.facets, &s.mesh.facet_tags), (&m.facets, &m.facet_tags));
        assert!((area(&s.mesh) - area(&m)).abs() < 1e-14);
        let after = Criteria::new(&m, &no_bulge(&m)).after_split(s.mesh.n_vertices());
        assert_eq!(after, Criteria::new(&s.mesh, &no_bulge(&s.mesh)));
        // Nothing left to split: each half has one boundary edge at O.
        assert!(squeezed_edges(&s.mesh, &Criteria::new(&s.mesh, &no_bulge(&s.mesh))).is_empty());
    }

    #[test]
    fn a_corner_of_the_boundary_is_left_alone() {
        let m = corner_2d();
        assert!(squeezed_edges(&m, &Criteria::new(&m, &no_bulge(&m))).is_empty());
        assert_eq!(split_squeezed(&m, &no_bulge(&m)).edges, 0);
    }

    #[test]
    fn an_edge_split_halves_every_tet_around_it_and_keeps_the_orientation() {
        // Three tets around the edge 0–1 (the z axis from 0 to 1), and one apart.
        let s3 = 3f64.sqrt() / 2.0;
        let coords = vec![
            0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.5, -0.5, s3, 0.5, -0.5, -s3, 0.5, 2.0, 0.0, 0.5, 1.0, 1.0, 0.5,
        ];
        let mut cells = vec![0, 1, 2, 3, 0, 1, 3, 4, 0, 1, 4, 2, 2, 5, 6, 1];
        for c in cells.chunks_mut(4) {
            let x: Vec<[f64; 3]> = c.iter().map(|&v| [coords[3 * v], coords[3 * v + 1], coords[3 * v + 2]]).collect();
            if orient(3, &x) < 0.0 {
                c.swap(0, 1);
            }
        }
        let m = LinearMesh {
            dim: 3,
            coords,
            cells,
            facets: vec![],
            facet_tags: vec![],
            feature_edges: vec![],
            feature_edge_tags: vec![],
        };
        let s = split_edges(&m, &[[0, 1], [1, 2]]);
        // 1–2 shares cell 0 with 0–1, split first: it waits for a later round.
        assert_eq!((s.edges, s.mesh.n_cells(), s.mesh.n_vertices()), (1, 7, 8));
        assert_eq!(
            (&s.parent[..], &s.whole[..]),
            (&[3, 0, 0, 1, 1, 2, 2][..], &[true, false, false, false, false, false, false][..])
        );
        assert_eq!(s.mesh.vertex(7), [0.0, 0.0, 0.5]);
        // The edge split is interior: the criteria of the split mesh are those of the mesh given.
        assert_eq!(Criteria::new(&m, &[]).after_split(s.mesh.n_vertices()), Criteria::new(&s.mesh, &[]));
        let volume = |m: &LinearMesh, c: &[usize]| orient(3, &c.iter().map(|&v| m.vertex(v)).collect::<Vec<_>>());
        for (i, c) in s.mesh.cells.chunks(4).enumerate() {
            assert!(volume(&s.mesh, c) > 0.0, "cell {i}");
        }
        for p in 0..3 {
            let halves: f64 =
                s.mesh.cells.chunks(4).zip(&s.parent).filter(|(_, &q)| q == p).map(|(c, _)| volume(&s.mesh, c)).sum();
            assert!((halves - volume(&m, &m.cells[4 * p..4 * p + 4])).abs() < 1e-14);
        }
    }
}
