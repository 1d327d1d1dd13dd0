//! Node orderings of the Lagrange simplices in gmsh and VTK, as lists of
//! barycentric multi-indices.
//!
//! A node of an order-`p` element is named by its multi-index
//! `a = [a_0, .., a_dim]` with `Σ a_i = p` (slots past `dim` are 0); its
//! equispaced reference position is `λ_i = a_i / p`. An ordering is the list of
//! multi-indices in a file format's local node order, and [`permutation`]
//! converts between two orderings. No coordinates and no I/O here.
//!
//! Both families are recursive: vertices, then the interior nodes of each edge
//! (from its first vertex to its second), then the interior nodes of each face
//! (ordered as an order-`p − 3` triangle of the same family whose vertices are
//! the face's, in the listed order), then the interior (an order-`p − 3`
//! triangle or order-`p − 4` tetrahedron of the same family, shifted by one).
//! They differ only in the tetrahedron's edges and faces:
//!
//! | family | tet edges | tet faces |
//! |---|---|---|
//! | gmsh | 01 12 20 30 32 31 | 021 013 032 312 |
//! | VTK  | 01 12 20 03 13 23 | 013 231 032 021 |
//!
//! Triangles are ordered identically by both (edges 01 12 20). These tables
//! were read off `gmsh.model.mesh.getElementProperties` and VTK's
//! `vtkLagrangeTetra::GetParametricCoords` (see
//! `scripts/gen_reference_orderings.py`) and are tested against both for
//! p = 1..10 in `tests/orderings.rs`.
//!
//! ```
//! use hocurve::reference::ordering::{gmsh_multi_indices, permutation, vtk_multi_indices};
//! use hocurve::reference::Simplex;
//! let gmsh = gmsh_multi_indices(Simplex::Tet, 2);
//! let vtk = vtk_multi_indices(Simplex::Tet, 2);
//! // VTK's node k is gmsh's node perm[k]: VTK's 9th node (edge 2-3) is gmsh's 9th (edge 3-2).
//! let perm = permutation(&gmsh, &vtk).unwrap();
//! assert_eq!(perm, vec![0, 1, 2, 3, 4, 5, 6, 7, 9, 8]);
//! ```

use super::simplex::Simplex;
use std::collections::HashMap;

/// How a family orders the sub-entities of the tetrahedron.
struct Family {
    tet_edges: [[usize; 2]; 6],
    tet_faces: [[usize; 3]; 4],
}

const TRI_EDGES: [[usize; 2]; 3] = [[0, 1], [1, 2], [2, 0]];

const GMSH: Family = Family {
    tet_edges: [[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]],
    tet_faces: [[0, 2, 1], [0, 1, 3], [0, 3, 2], [3, 1, 2]],
};

const VTK: Family = Family {
    tet_edges: [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]],
    tet_faces: [[0, 1, 3], [2, 3, 1], [0, 3, 2], [0, 2, 1]],
};

/// Multi-indices of an order-`order` element in gmsh's node order (element
/// types 2/9/21/23/25/42/43/44/45/46 for the triangle of order 1..10 and
/// 4/11/29/30/31/71/72/73/74/75 for the tetrahedron). Order 0 gives the single
/// node `[0; 4]`.
pub fn gmsh_multi_indices(simplex: Simplex, order: usize) -> Vec<[usize; 4]> {
    recursive(&GMSH, simplex, order)
}

/// Multi-indices of an order-`order` VTK Lagrange cell (`VTK_LAGRANGE_TRIANGLE`
/// = 69, `VTK_LAGRANGE_TETRAHEDRON` = 71) in VTK's node order.
pub fn vtk_multi_indices(simplex: Simplex, order: usize) -> Vec<[usize; 4]> {
    recursive(&VTK, simplex, order)
}

/// VTK cell type of a Lagrange simplex: 69 (triangle) or 71 (tetrahedron).
pub fn vtk_cell_type(simplex: Simplex) -> u8 {
    match simplex {
        Simplex::Tri => 69,
        Simplex::Tet => 71,
    }
}

const GMSH_TRI_TYPES: [i32; 10] = [2, 9, 21, 23, 25, 42, 43, 44, 45, 46];
const GMSH_TET_TYPES: [i32; 10] = [4, 11, 29, 30, 31, 71, 72, 73, 74, 75];
const GMSH_LINE_TYPES: [i32; 10] = [1, 8, 26, 27, 28, 62, 63, 64, 65, 66];

/// gmsh element type of the complete Lagrange simplex of order 1..10.
pub fn gmsh_element_type(simplex: Simplex, order: usize) -> Option<i32> {
    let types = match simplex {
        Simplex::Tri => &GMSH_TRI_TYPES,
        Simplex::Tet => &GMSH_TET_TYPES,
    };
    order.checked_sub(1).and_then(|i| types.get(i)).copied()
}

/// gmsh element type of the order-`order` line (1..10): 1, 8, 26, 27, 28, 62..66.
pub fn gmsh_line_type(order: usize) -> Option<i32> {
    order.checked_sub(1).and_then(|i| GMSH_LINE_TYPES.get(i)).copied()
}

/// The simplex and order of a gmsh complete Lagrange triangle or tetrahedron
/// type; `None` for any other type (lines, quads, incomplete elements, ...).
pub fn gmsh_type_info(element_type: i32) -> Option<(Simplex, usize)> {
    if let Some(i) = GMSH_TRI_TYPES.iter().position(|&t| t == element_type) {
        return Some((Simplex::Tri, i + 1));
    }
    if let Some(i) = GMSH_TET_TYPES.iter().position(|&t| t == element_type) {
        return Some((Simplex::Tet, i + 1));
    }
    None
}

/// Order of a gmsh line type (1 → 1, 8 → 2, ...); `None` if not a line.
pub fn gmsh_line_order(element_type: i32) -> Option<usize> {
    GMSH_LINE_TYPES.iter().position(|&t| t == element_type).map(|i| i + 1)
}

/// `(type, dimension, nodes per element)` of every gmsh element type with a
/// fixed node count (gmsh 4.15 `getElementProperties`; checked against
/// `tests/data/gmsh_element_types.txt`).
const GMSH_SHAPES: [(i32, usize, usize); 110] = [
    (1, 1, 2),
    (2, 2, 3),
    (3, 2, 4),
    (4, 3, 4),
    (5, 3, 8),
    (6, 3, 6),
    (7, 3, 5),
    (8, 1, 3),
    (9, 2, 6),
    (10, 2, 9),
    (11, 3, 10),
    (12, 3, 27),
    (13, 3, 18),
    (14, 3, 14),
    (15, 0, 1),
    (16, 2, 8),
    (17, 3, 20),
    (18, 3, 15),
    (19, 3, 13),
    (20, 2, 9),
    (21, 2, 10),
    (22, 2, 12),
    (23, 2, 15),
    (24, 2, 15),
    (25, 2, 21),
    (26, 1, 4),
    (27, 1, 5),
    (28, 1, 6),
    (29, 3, 20),
    (30, 3, 35),
    (31, 3, 56),
    (32, 3, 22),
    (33, 3, 28),
    (36, 2, 16),
    (37, 2, 25),
    (38, 2, 36),
    (39, 2, 12),
    (40, 2, 16),
    (41, 2, 20),
    (42, 2, 28),
    (43, 2, 36),
    (44, 2, 45),
    (45, 2, 55),
    (46, 2, 66),
    (47, 2, 49),
    (48, 2, 64),
    (49, 2, 81),
    (50, 2, 100),
    (51, 2, 121),
    (52, 2, 18),
    (53, 2, 21),
    (54, 2, 24),
    (55, 2, 27),
    (56, 2, 30),
    (57, 2, 24),
    (58, 2, 28),
    (59, 2, 32),
    (60, 2, 36),
    (61, 2, 40),
    (62, 1, 7),
    (63, 1, 8),
    (64, 1, 9),
    (65, 1, 10),
    (66, 1, 11),
    (71, 3, 84),
    (72, 3, 120),
    (73, 3, 165),
    (74, 3, 220),
    (75, 3, 286),
    (79, 3, 34),
    (80, 3, 40),
    (81, 3, 46),
    (82, 3, 52),
    (83, 3, 58),
    (84, 1, 1),
    (85, 2, 1),
    (86, 2, 1),
    (87, 3, 1),
    (88, 3, 1),
    (89, 3, 1),
    (92, 3, 64),
    (93, 3, 125),
    (94, 3, 216),
    (95, 3, 343),
    (96, 3, 512),
    (97, 3, 729),
    (98, 3, 1000),
    (99, 3, 32),
    (100, 3, 44),
    (101, 3, 56),
    (102, 3, 68),
    (103, 3, 80),
    (104, 3, 92),
    (105, 3, 104),
    (118, 3, 30),
    (119, 3, 55),
    (120, 3, 91),
    (121, 3, 140),
    (122, 3, 204),
    (123, 3, 285),
    (124, 3, 385),
    (125, 3, 21),
    (126, 3, 29),
    (127, 3, 37),
    (128, 3, 45),
    (129, 3, 53),
    (130, 3, 61),
    (131, 3, 69),
    (132, 3, 1),
    (137, 3, 16),
];

/// `(dimension, nodes per element)` of any gmsh element type with a fixed node
/// count (points, lines, triangles, quads, tets, hexes, prisms, pyramids, ...).
pub fn gmsh_element_shape(element_type: i32) -> Option<(usize, usize)> {
    GMSH_SHAPES.iter().find(|s| s.0 == element_type).map(|&(_, dim, n)| (dim, n))
}

/// `perm[k]` = index in `from` of the k-th multi-index of `to`, so that
/// `to_nodes[k] = from_nodes[perm[k]]`. `None` if the lists are not
/// permutations of each other (different lengths, repeats or missing entries).
pub fn permutation(from: &[[usize; 4]], to: &[[usize; 4]]) -> Option<Vec<usize>> {
    if from.len() != to.len() {
        return None;
    }
    let mut index = HashMap::with_capacity(from.len());
    for (i, m) in from.iter().enumerate() {
        if index.insert(*m, i).is_some() {
            return None;
        }
    }
    let mut used = vec![false; from.len()];
    let mut perm = Vec::with_capacity(to.len());
    for m in to {
        let i = *index.get(m)?;
        if std::mem::replace(&mut used[i], true) {
            return None;
        }
        perm.push(i);
    }
    Some(perm)
}

/// The recursive ordering of `family` (see the module docs).
fn recursive(family: &Family, simplex: Simplex, p: usize) -> Vec<[usize; 4]> {
    let mut out = Vec::with_capacity(simplex.n_nodes(p));
    if p == 0 {
        out.push([0; 4]);
        return out;
    }
    let nv = simplex.n_vertices();
    for v in 0..nv {
        let mut a = [0; 4];
        a[v] = p;
        out.push(a);
    }
    let edges: &[[usize; 2]] = match simplex {
        Simplex::Tri => &TRI_EDGES,
        Simplex::Tet => &family.tet_edges,
    };
    for &[v0, v1] in edges {
        for i in 1..p {
            let mut a = [0; 4];
            a[v0] = p - i;
            a[v1] = i;
            out.push(a);
        }
    }
    if p >= 3 {
        let face = recursive(family, Simplex::Tri, p - 3);
        match simplex {
            Simplex::Tri => place_shifted(&face, &[0, 1, 2], &mut out),
            Simplex::Tet => {
                for f in &family.tet_faces {
                    place_shifted(&face, f, &mut out);
                }
            }
        }
    }
    if simplex == Simplex::Tet && p >= 4 {
        let interior = recursive(family, Simplex::Tet, p - 4);
        place_shifted(&interior, &[0, 1, 2, 3], &mut out);
    }
    out
}

/// Appends `local` (multi-indices of a sub-simplex whose k-th vertex is the
/// element's vertex `verts[k]`) shifted by one in each of `verts`' slots.
fn place_shifted(local: &[[usize; 4]], verts: &[usize], out: &mut Vec<[usize; 4]>) {
    for b in local {
        let mut a = [0; 4];
        for (k, &v) in verts.iter().enumerate() {
            a[v] = b[k] + 1;
        }
        out.push(a);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn is_complete(simplex: Simplex, p: usize, list: &[[usize; 4]]) -> bool {
        let d = simplex.dim();
        list.len() == simplex.n_nodes(p)
            && list.iter().all(|a| a[..=d].iter().sum::<usize>() == p && a[d + 1..].iter().all(|&x| x == 0))
            && permutation(list, list).is_some()
    }

    #[test]
    fn orderings_list_every_node_once() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in 0..=10 {
                assert!(is_complete(simplex, p, &gmsh_multi_indices(simplex, p)));
                assert!(is_complete(simplex, p, &vtk_multi_indices(simplex, p)));
            }
        }
    }

    #[test]
    fn quadratic_tet_edge_nodes_follow_gmsh_and_vtk_edges() {
        let g = gmsh_multi_indices(Simplex::Tet, 2);
        assert_eq!(g[7], [1, 0, 0, 1]); // gmsh edge 3-0
        assert_eq!(g[8], [0, 0, 1, 1]); // gmsh edge 3-2
        assert_eq!(g[9], [0, 1, 0, 1]); // gmsh edge 3-1
        let v = vtk_multi_indices(Simplex::Tet, 2);
        assert_eq!(v[8], [0, 1, 0, 1]); // VTK edge 1-3
        assert_eq!(v[9], [0, 0, 1, 1]); // VTK edge 2-3
    }

    #[test]
    fn permutation_maps_to_onto_from() {
        let from = gmsh_multi_indices(Simplex::Tet, 5);
        let to = vtk_multi_indices(Simplex::Tet, 5);
        let perm = permutation(&from, &to).unwrap();
        for (k, &i) in perm.iter().enumerate() {
            assert_eq!(from[i], to[k]);
        }
    }

    #[test]
    fn permutation_rejects_non_permutations() {
        let a = gmsh_multi_indices(Simplex::Tri, 2);
        assert!(permutation(&a, &a[..5]).is_none());
        let mut b = a.clone();
        b[5] = b[4];
        assert!(permutation(&a, &b).is_none());
        assert!(permutation(&b, &a).is_none());
        let c = gmsh_multi_indices(Simplex::Tri, 1);
        let d = vec![[3, 0, 0, 0], [0, 3, 0, 0], [0, 0, 3, 0]];
        assert!(permutation(&c, &d).is_none());
    }

    #[test]
    fn gmsh_types_round_trip() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in 1..=10 {
                let t = gmsh_element_type(simplex, p).unwrap();
                assert_eq!(gmsh_type_info(t), Some((simplex, p)));
                assert_eq!(gmsh_element_shape(t), Some((simplex.dim(), simplex.n_nodes(p))));
            }
            assert_eq!(gmsh_element_type(simplex, 0), None);
            assert_eq!(gmsh_element_type(simplex, 11), None);
        }
        for p in 1..=10 {
            let t = gmsh_line_type(p).unwrap();
            assert_eq!(gmsh_line_order(t), Some(p));
            assert_eq!(gmsh_element_shape(t), Some((1, p + 1)));
        }
        assert_eq!(gmsh_type_info(1), None);
        assert_eq!(gmsh_type_info(20), None); // incomplete triangle
        assert_eq!(gmsh_element_shape(15), Some((0, 1)));
    }
}
