//! Topology of a linear simplex mesh: validation, orientation, edges, faces
//! and boundary facets.
//!
//! Edges and faces are identified by their sorted global vertex tuples; the
//! numbering is deterministic (first appearance while scanning the cells).

use rustc_hash::FxHashMap as HashMap;
use std::fmt::Debug;
use std::hash::Hash;

use super::LinearMesh;
use crate::reference::simplex::{Simplex, TET_FACES};
use crate::{Error, Result};

/// Edges, faces and the boundary of a linear mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Topology {
    pub simplex: Simplex,
    /// Global edges as sorted vertex pairs.
    pub edges: Vec<[usize; 2]>,
    /// `cell_edges[c * n_local_edges + e]`: global edge of local edge `e` of cell `c`.
    pub cell_edges: Vec<usize>,
    /// 3D only: global faces as sorted vertex triples.
    pub faces: Vec<[usize; 3]>,
    /// 3D only: `cell_faces[c * 4 + f]`: global face of local face `f` of cell `c`.
    pub cell_faces: Vec<usize>,
    /// Boundary facets: global edge ids (2D) or face ids (3D) with one adjacent cell.
    pub boundary_facets: Vec<usize>,
    /// Per vertex: does it lie on the boundary?
    pub boundary_vertex: Vec<bool>,
    /// Global edge id of each sorted edge ([`Topology::edge_lookup`]).
    edge_ids: HashMap<[usize; 2], usize>,
    /// 3D only: global face id of each sorted face ([`Topology::face_lookup`]).
    face_ids: HashMap<[usize; 3], usize>,
}

/// Signed measure of a simplex times dim! (2× area, 6× volume).
pub fn signed_measure(dim: usize, x: &[[f64; 3]]) -> f64 {
    let d = |i: usize, k: usize| x[i][k] - x[0][k];
    if dim == 2 {
        d(1, 0) * d(2, 1) - d(1, 1) * d(2, 0)
    } else {
        d(1, 0) * (d(2, 1) * d(3, 2) - d(2, 2) * d(3, 1)) - d(1, 1) * (d(2, 0) * d(3, 2) - d(2, 2) * d(3, 0))
            + d(1, 2) * (d(2, 0) * d(3, 1) - d(2, 1) * d(3, 0))
    }
}

/// Check a linear mesh and return a copy whose cells are positively oriented.
///
/// Rejects: dimension other than 2 or 3, inconsistent array lengths,
/// non-finite coordinates, no cells, out-of-range or repeated vertex indices,
/// duplicate cells, degenerate cells (|measure| ≤ 1e-12 · h^dim with h the
/// longest edge of the cell), cells so large that their size or measure
/// overflows, tags count mismatch.
/// Cells with negative orientation are reoriented by swapping their last two vertices.
pub fn validate_and_orient(mesh: &LinearMesh) -> Result<(LinearMesh, usize)> {
    check_shape(mesh)?;
    let dim = mesh.dim;
    let nv = mesh.n_vertices();
    let npc = dim + 1;
    let mut out = mesh.clone();
    let mut reoriented = 0;
    let mut seen: HashMap<[usize; 4], usize> = HashMap::with_capacity_and_hasher(mesh.n_cells(), Default::default());
    for (c, cell) in out.cells.chunks_exact_mut(npc).enumerate() {
        if orient_cell(mesh, c, cell, &mut seen)? {
            reoriented += 1;
        }
    }
    check_vertex_refs(&out.facets, dim, "boundary facet", nv)?;
    check_vertex_refs(&out.feature_edges, 2, "feature edge", nv)?;
    Ok((out, reoriented))
}

/// Check the dimension, the array lengths against it and each other, and that coordinates are finite.
fn check_shape(mesh: &LinearMesh) -> Result<()> {
    let dim = mesh.dim;
    if dim != 2 && dim != 3 {
        return Err(Error::InvalidInput(format!("dimension must be 2 or 3, got {dim}")));
    }
    if !mesh.coords.len().is_multiple_of(dim) {
        return Err(Error::InvalidInput(format!(
            "coordinate array length {} is not a multiple of the dimension {dim}",
            mesh.coords.len()
        )));
    }
    if let Some(i) = mesh.coords.iter().position(|c| !c.is_finite()) {
        return Err(Error::InvalidInput(format!("vertex {} has a non-finite coordinate", i / dim)));
    }
    let npc = dim + 1;
    if mesh.cells.is_empty() {
        return Err(Error::InvalidInput("the mesh has no cells".into()));
    }
    if !mesh.cells.len().is_multiple_of(npc) {
        return Err(Error::InvalidInput(format!("cell array length {} is not a multiple of {npc}", mesh.cells.len())));
    }
    if !mesh.facets.len().is_multiple_of(dim) || mesh.facets.len() / dim != mesh.facet_tags.len() {
        return Err(Error::InvalidInput(format!(
            "{} facet vertex indices and {} facet tags do not match ({} vertices per facet)",
            mesh.facets.len(),
            mesh.facet_tags.len(),
            dim
        )));
    }
    if !mesh.feature_edges.len().is_multiple_of(2) || mesh.feature_edges.len() / 2 != mesh.feature_edge_tags.len() {
        return Err(Error::InvalidInput(format!(
            "{} feature edge vertex indices and {} curve tags do not match",
            mesh.feature_edges.len(),
            mesh.feature_edge_tags.len()
        )));
    }
    if dim == 2 && !mesh.feature_edges.is_empty() {
        return Err(Error::InvalidInput("feature edges are for 3D meshes; in 2D tag the boundary edges".into()));
    }
    Ok(())
}

/// Check one cell and swap its last two vertices if negatively oriented; returns whether it did.
fn orient_cell(mesh: &LinearMesh, c: usize, cell: &mut [usize], seen: &mut HashMap<[usize; 4], usize>) -> Result<bool> {
    let dim = mesh.dim;
    let nv = mesh.n_vertices();
    let npc = dim + 1;
    for &v in cell.iter() {
        if v >= nv {
            return Err(Error::InvalidInput(format!("cell {c} refers to vertex {v}, but there are {nv} vertices")));
        }
    }
    let mut key = [usize::MAX; 4];
    key[..npc].copy_from_slice(cell);
    key[..npc].sort_unstable();
    if key[..npc].windows(2).any(|w| w[0] == w[1]) {
        return Err(Error::InvalidInput(format!("cell {c} repeats a vertex: {cell:?}")));
    }
    if let Some(first) = seen.insert(key, c) {
        return Err(Error::InvalidInput(format!("cells {first} and {c} have the same vertices")));
    }
    let x: Vec<[f64; 3]> = cell.iter().map(|&v| mesh.vertex(v)).collect();
    let mut h2: f64 = 0.0;
    for i in 0..npc {
        for j in i + 1..npc {
            h2 = h2.max((0..3).map(|k| (x[i][k] - x[j][k]).powi(2)).sum());
        }
    }
    let m = signed_measure(dim, &x);
    if !(h2.is_finite() && m.is_finite()) {
        return Err(Error::InvalidInput(format!(
            "cell {c} is too large: its size or measure overflows double precision (scale the mesh down)"
        )));
    }
    if m.abs() <= 1e-12 * h2.sqrt().powi(dim as i32) {
        return Err(Error::InvalidInput(format!("cell {c} is degenerate (zero measure)")));
    }
    if m < 0.0 {
        cell.swap(dim - 1, dim);
        return Ok(true);
    }
    Ok(false)
}

/// Check that every vertex of `list` (items of `per` vertices, called `what`) is below `nv`.
fn check_vertex_refs(list: &[usize], per: usize, what: &str, nv: usize) -> Result<()> {
    for (k, item) in list.chunks_exact(per).enumerate() {
        if let Some(&v) = item.iter().find(|&&v| v >= nv) {
            return Err(Error::InvalidInput(format!("{what} {k} refers to vertex {v}, but there are {nv} vertices")));
        }
    }
    Ok(())
}

impl Topology {
    /// Build edges, faces and the boundary of a validated, oriented mesh.
    pub fn new(mesh: &LinearMesh) -> Result<Topology> {
        let simplex = Simplex::from_dim(mesh.dim)
            .ok_or_else(|| Error::InvalidInput(format!("dimension must be 2 or 3, got {}", mesh.dim)))?;
        let npc = mesh.dim + 1;
        let nc = mesh.n_cells();
        let local_edges = simplex.edges();
        let mut edge_id: HashMap<[usize; 2], usize> = HashMap::with_capacity_and_hasher(nc * 2, Default::default());
        let mut edges = Vec::new();
        let mut cell_edges = Vec::with_capacity(nc * local_edges.len());
        let mut edge_cells: Vec<u32> = Vec::new();
        for cell in mesh.cells.chunks_exact(npc) {
            for le in local_edges {
                let (a, b) = (cell[le[0]], cell[le[1]]);
                let key = [a.min(b), a.max(b)];
                cell_edges.push(intern(&mut edge_id, &mut edges, &mut edge_cells, key));
            }
        }
        let mut faces = Vec::new();
        let mut cell_faces = Vec::new();
        let mut face_id: HashMap<[usize; 3], usize> = HashMap::default();
        let boundary_facets: Vec<usize> = if simplex == Simplex::Tet {
            face_id.reserve(nc * 2);
            let mut face_cells: Vec<u32> = Vec::new();
            cell_faces.reserve(nc * 4);
            for cell in mesh.cells.chunks_exact(npc) {
                for lf in &TET_FACES {
                    let mut key = [cell[lf[0]], cell[lf[1]], cell[lf[2]]];
                    key.sort_unstable();
                    cell_faces.push(intern(&mut face_id, &mut faces, &mut face_cells, key));
                }
            }
            single_cell_entities(&faces, &face_cells, "face")?
        } else {
            single_cell_entities(&edges, &edge_cells, "edge")?
        };
        let mut boundary_vertex = vec![false; mesh.n_vertices()];
        for &f in &boundary_facets {
            let vs: &[usize] = if simplex == Simplex::Tet { &faces[f] } else { &edges[f] };
            for &v in vs {
                boundary_vertex[v] = true;
            }
        }
        Ok(Topology {
            simplex,
            edges,
            cell_edges,
            faces,
            cell_faces,
            boundary_facets,
            boundary_vertex,
            edge_ids: edge_id,
            face_ids: face_id,
        })
    }

    /// Map from sorted edge to global edge id (kept from the construction:
    /// each elevation and preparation asks for it).
    pub fn edge_lookup(&self) -> &HashMap<[usize; 2], usize> {
        &self.edge_ids
    }

    /// Map from sorted face to global face id (3D; empty in 2D).
    pub fn face_lookup(&self) -> &HashMap<[usize; 3], usize> {
        &self.face_ids
    }
}

/// The id of `key` (numbered at its first appearance, pushed onto `list`), with one more cell counted on it.
fn intern<K: Copy + Eq + Hash>(ids: &mut HashMap<K, usize>, list: &mut Vec<K>, cells: &mut Vec<u32>, key: K) -> usize {
    let id = *ids.entry(key).or_insert_with(|| {
        list.push(key);
        cells.push(0);
        list.len() - 1
    });
    cells[id] += 1;
    id
}

/// The ids of the entities (`what`: edge or face) with one cell, in order; an error if one has more than two.
fn single_cell_entities<K: Debug>(list: &[K], cells: &[u32], what: &str) -> Result<Vec<usize>> {
    if let Some(e) = cells.iter().position(|&n| n > 2) {
        return Err(Error::InvalidInput(format!(
            "the mesh is not manifold: {what} {:?} is shared by {} cells",
            list[e], cells[e]
        )));
    }
    Ok((0..list.len()).filter(|&e| cells[e] == 1).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_triangles() -> LinearMesh {
        LinearMesh {
            dim: 2,
            coords: vec![0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0],
            cells: vec![0, 1, 2, 0, 2, 3],
            ..Default::default()
        }
    }

    #[test]
    fn square_has_five_edges_four_on_boundary() {
        let (m, re) = validate_and_orient(&two_triangles()).unwrap();
        assert_eq!(re, 0);
        let t = Topology::new(&m).unwrap();
        assert_eq!(t.edges.len(), 5);
        assert_eq!(t.boundary_facets.len(), 4);
        assert!(t.boundary_vertex.iter().all(|&b| b));
    }

    #[test]
    fn negative_cells_are_reoriented() {
        let mut m = two_triangles();
        m.cells = vec![0, 2, 1, 0, 2, 3];
        let (o, re) = validate_and_orient(&m).unwrap();
        assert_eq!(re, 1);
        let x: Vec<[f64; 3]> = o.cells[..3].iter().map(|&v| o.vertex(v)).collect();
        assert!(signed_measure(2, &x) > 0.0);
    }

    #[test]
    fn bad_cells_are_rejected_with_a_message() {
        let mut m = two_triangles();
        m.cells = vec![0, 1, 7];
        assert!(matches!(validate_and_orient(&m), Err(Error::InvalidInput(s)) if s.contains("vertex 7")));
        m.cells = vec![0, 1, 1];
        assert!(validate_and_orient(&m).is_err());
        m.coords = vec![0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1.0];
        m.cells = vec![0, 1, 2];
        assert!(matches!(validate_and_orient(&m), Err(Error::InvalidInput(s)) if s.contains("degenerate")));
        m.cells = vec![];
        assert!(validate_and_orient(&m).is_err());
        let mut m = two_triangles();
        m.coords[3] = f64::NAN;
        assert!(validate_and_orient(&m).is_err());
        // Coordinates so large that the measure overflows (inf − inf = NaN here): not "valid".
        let mut m = two_triangles();
        m.coords = vec![0.0, 0.0, 1e300, 1e300, 1e300, 2e300, 0.0, 1.0];
        m.cells = vec![0, 1, 2];
        assert!(matches!(validate_and_orient(&m), Err(Error::InvalidInput(s)) if s.contains("too large")));
        let mut m = two_triangles();
        m.cells = vec![0, 1, 2, 2, 1, 0];
        assert!(matches!(validate_and_orient(&m), Err(Error::InvalidInput(s)) if s.contains("same vertices")));
    }

    #[test]
    fn single_tet_has_six_edges_four_boundary_faces() {
        let m = LinearMesh {
            dim: 3,
            coords: vec![0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.],
            cells: vec![0, 1, 2, 3],
            ..Default::default()
        };
        let t = Topology::new(&validate_and_orient(&m).unwrap().0).unwrap();
        assert_eq!(t.edges.len(), 6);
        assert_eq!(t.faces.len(), 4);
        assert_eq!(t.boundary_facets.len(), 4);
        assert_lookups_index(&t);
        assert_lookups_index(&Topology::new(&validate_and_orient(&two_triangles()).unwrap().0).unwrap());
    }

    /// The lookups give each edge and face its index, and nothing else.
    fn assert_lookups_index(t: &Topology) {
        assert_eq!(t.edge_lookup().len(), t.edges.len());
        assert!(t.edges.iter().enumerate().all(|(i, e)| t.edge_lookup()[e] == i));
        assert_eq!(t.face_lookup().len(), t.faces.len());
        assert!(t.faces.iter().enumerate().all(|(i, f)| t.face_lookup()[f] == i));
    }
}
