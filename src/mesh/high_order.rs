//! The order-p mesh: global numbering of edge, face and interior nodes shared
//! consistently between neighbours, straight-sided node positions, and the
//! classification of every node against the tagged boundary.
//!
//! Global numbering: the linear vertices keep their numbers `0..n_vertices`;
//! then `p − 1` nodes per edge, ordered from the edge's lower-numbered vertex;
//! then (3D) `(p − 1)(p − 2)/2` nodes per face, indexed by their barycentric
//! counts relative to the face's sorted vertices; then the interior nodes of
//! each cell. A node's place therefore depends only on the entity it lies on,
//! never on the cell that visits it.

use rustc_hash::FxHashMap as HashMap;
use std::borrow::Cow;

use super::topology::Topology;
use super::LinearMesh;
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};
use crate::{Error, Result};

/// What the boundary conditions say about a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeConstraint {
    /// Interior node: free to move.
    Free,
    /// Boundary node held at its straight position (vertices, untagged boundary,
    /// edges where differently tagged surfaces meet without a curve tag).
    Fixed,
    /// Projected onto the geometric entity of dimension `dim` and tag `tag`.
    OnEntity { dim: usize, tag: i32 },
}

/// An order-p simplex mesh with its boundary classification.
#[derive(Debug, Clone)]
pub struct HighOrderMesh {
    pub simplex: Simplex,
    pub order: usize,
    pub spacing: NodeSpacing,
    /// Node coordinates, `dim` interleaved components.
    pub coords: Vec<f64>,
    /// Cell connectivity in the native local order of [`NodeSet`].
    pub cells: Vec<usize>,
    /// Number of linear vertices (the first nodes).
    pub n_vertices: usize,
    /// Per node: its boundary condition.
    pub constraint: Vec<NodeConstraint>,
}

impl HighOrderMesh {
    pub fn dim(&self) -> usize {
        self.simplex.dim()
    }
    pub fn n_nodes(&self) -> usize {
        self.coords.len() / self.dim()
    }
    pub fn nodes_per_cell(&self) -> usize {
        self.simplex.n_nodes(self.order)
    }
    pub fn n_cells(&self) -> usize {
        self.cells.len() / self.nodes_per_cell()
    }
    /// Node connectivity of cell `c`.
    pub fn cell(&self, c: usize) -> &[usize] {
        let n = self.nodes_per_cell();
        &self.cells[c * n..(c + 1) * n]
    }
    /// Node `i` as a 3-vector (z = 0 in 2D).
    pub fn node(&self, i: usize) -> [f64; 3] {
        let d = self.dim();
        let mut x = [0.0; 3];
        x[..d].copy_from_slice(&self.coords[i * d..(i + 1) * d]);
        x
    }

    /// Coordinates of the same geometry with nodes moved to the reference
    /// positions of `target` (same order and multi-indices as this mesh's node
    /// set): each node is the element map evaluated at its target reference
    /// point. Exact, since both sets span the same polynomials; used to write
    /// equispaced files (gmsh, VTK) from an optimal-node mesh.
    pub fn coords_at_nodes(&self, basis: &LagrangeBasis, target: &NodeSet) -> Vec<f64> {
        use rayon::prelude::*;
        let dim = self.dim();
        let npc = self.nodes_per_cell();
        let tab = basis.tabulate(&target.coords);
        // Each node from the last cell that holds it (its neighbours give the
        // same values to round-off), the cells in parallel.
        let mut last = vec![usize::MAX; self.n_nodes()];
        for c in 0..self.n_cells() {
            for &g in self.cell(c) {
                last[g] = c;
            }
        }
        let moved: Vec<(usize, [f64; 3])> = (0..self.n_cells())
            .into_par_iter()
            .flat_map_iter(|c| {
                let (cell, tab, last) = (self.cell(c), &tab, &last);
                cell.iter().enumerate().skip(dim + 1).filter(move |&(_, &g)| last[g] == c).map(move |(a, &g)| {
                    let mut x = [0.0; 3];
                    for (d, x) in x.iter_mut().enumerate().take(dim) {
                        *x = (0..npc).map(|b| tab.values[a * npc + b] * self.coords[cell[b] * dim + d]).sum();
                    }
                    (g, x)
                })
            })
            .collect();
        let mut out = self.coords.clone();
        for (g, x) in moved {
            out[g * dim..(g + 1) * dim].copy_from_slice(&x[..dim]);
        }
        out
    }

    /// The coordinates at the equispaced node set, the one gmsh and VTK
    /// cells interpolate at: this mesh's own when its nodes are equispaced,
    /// else resampled by [`HighOrderMesh::coords_at_nodes`].
    pub fn equispaced_coords(&self) -> Cow<'_, [f64]> {
        if self.spacing == NodeSpacing::Equispaced {
            return Cow::Borrowed(&self.coords);
        }
        let native = NodeSet::new(self.simplex, self.order, self.spacing);
        let equi = NodeSet::new(self.simplex, self.order, NodeSpacing::Equispaced);
        Cow::Owned(self.coords_at_nodes(&LagrangeBasis::new(&native), &equi))
    }

    /// Elevate a validated, positively oriented linear mesh to order `order`
    /// with straight sides, and classify its nodes.
    ///
    /// Boundary facets listed in `linear.facets` are tagged; a listed facet
    /// that is not on the boundary, or listed twice, is an error. In 3D,
    /// feature edges must be edges of boundary facets.
    pub fn elevate(
        linear: &LinearMesh,
        topo: &Topology,
        nodes: &NodeSet,
        spacing: NodeSpacing,
    ) -> Result<HighOrderMesh> {
        let simplex = topo.simplex;
        let p = nodes.order;
        let dim = simplex.dim();
        let nv = linear.n_vertices();
        let nc = linear.n_cells();
        let npc_lin = dim + 1;
        let numbering = Numbering::new(topo, nodes, nv, nc);
        let local = local_entities(simplex, nodes, numbering.n_interior);
        let npc = nodes.len();
        let mut cells = vec![0usize; nc * npc];
        let mut coords = vec![0.0; numbering.n_nodes * dim];
        for c in 0..nc {
            let lv = &linear.cells[c * npc_lin..(c + 1) * npc_lin];
            let xv: Vec<[f64; 3]> = lv.iter().map(|&v| linear.vertex(v)).collect();
            for (a, (m, loc)) in nodes.multi.iter().zip(&local).enumerate() {
                let g = numbering.global(topo, c, lv, m, *loc);
                cells[c * npc + a] = g;
                straight_position(dim, &nodes.coords[a], &xv, &mut coords[g * dim..(g + 1) * dim]);
            }
        }

        let constraint = classify(linear, topo, &numbering)?;
        Ok(HighOrderMesh { simplex, order: p, spacing, coords, cells, n_vertices: nv, constraint })
    }
}

/// The entity of the reference simplex that a local node lies on, by local
/// index (interior nodes counted in node order).
#[derive(Clone, Copy)]
enum Local {
    Vertex(usize),
    Edge(usize),
    Face(usize),
    Interior(usize),
}

/// The entity of every node of `nodes`, computed once for all cells.
fn local_entities(simplex: Simplex, nodes: &NodeSet, n_interior: usize) -> Vec<Local> {
    let dim = simplex.dim();
    let local_edges = simplex.edges();
    let mut interior_count = 0;
    let local: Vec<Local> = nodes
        .multi
        .iter()
        .map(|m| {
            let support: Vec<usize> = (0..=dim).filter(|&i| m[i] > 0).collect();
            match support.len() {
                1 => Local::Vertex(support[0]),
                2 => Local::Edge(
                    local_edges
                        .iter()
                        .position(|e| {
                            (e[0] == support[0] && e[1] == support[1]) || (e[1] == support[0] && e[0] == support[1])
                        })
                        .expect("every vertex pair is an edge of a simplex"),
                ),
                3 if dim == 3 => Local::Face(
                    crate::reference::simplex::TET_FACES
                        .iter()
                        .position(|f| {
                            let mut s = *f;
                            s.sort_unstable();
                            s[..] == support[..]
                        })
                        .expect("every vertex triple is a face of a tet"),
                ),
                _ => {
                    interior_count += 1;
                    Local::Interior(interior_count - 1)
                }
            }
        })
        .collect();
    debug_assert_eq!(interior_count, n_interior);
    local
}

/// Place a node on the straight cell with vertices `xv`: x = Σ λ_i x_i at reference point `xi`.
fn straight_position(dim: usize, xi: &[f64; 3], xv: &[[f64; 3]], x_out: &mut [f64]) {
    let lam0 = 1.0 - xi[..dim].iter().sum::<f64>();
    for d in 0..dim {
        let mut x = lam0 * xv[0][d];
        for i in 0..dim {
            x += xi[i] * xv[i + 1][d];
        }
        x_out[d] = x;
    }
}

/// Where the global numbering puts the nodes of each kind of entity (see the
/// module documentation).
struct Numbering {
    p: usize,
    /// Nodes per edge, p − 1.
    per_edge: usize,
    /// Nodes per face (3D), (p − 1)(p − 2)/2.
    per_face: usize,
    /// Interior nodes per cell.
    n_interior: usize,
    edge_base: usize,
    face_base: usize,
    interior_base: usize,
    n_nodes: usize,
}

impl Numbering {
    /// The numbering of the order-`nodes.order` mesh over `topo` with `nv` vertices and `nc` cells.
    fn new(topo: &Topology, nodes: &NodeSet, nv: usize, nc: usize) -> Numbering {
        let simplex = topo.simplex;
        let p = nodes.order;
        let npc_lin = simplex.dim() + 1;
        let per_edge = p.saturating_sub(1);
        let per_face = if p >= 3 { (p - 1) * (p - 2) / 2 } else { 0 };
        let n_face_entities = if simplex == Simplex::Tet { topo.faces.len() } else { 0 };
        let npc = nodes.len();
        let n_interior =
            npc - npc_lin - simplex.edges().len() * per_edge - if simplex == Simplex::Tet { 4 * per_face } else { 0 };
        let edge_base = nv;
        let face_base = edge_base + topo.edges.len() * per_edge;
        let interior_base = face_base + n_face_entities * per_face;
        let n_nodes = interior_base + nc * n_interior;
        Numbering { p, per_edge, per_face, n_interior, edge_base, face_base, interior_base, n_nodes }
    }

    /// Global number of the node with multi-index `m` on local entity `loc` of cell `c` (vertices `lv`).
    fn global(&self, topo: &Topology, c: usize, lv: &[usize], m: &[usize; 4], loc: Local) -> usize {
        match loc {
            Local::Vertex(i) => lv[i],
            Local::Edge(le) => self.edge_node(topo, c, lv, m, le),
            Local::Face(lf) => self.face_node(topo, c, lv, m, lf),
            Local::Interior(k) => self.interior_base + c * self.n_interior + k,
        }
    }

    /// Number an edge node: its place along the global edge from the edge's lower-numbered vertex.
    fn edge_node(&self, topo: &Topology, c: usize, lv: &[usize], m: &[usize; 4], le: usize) -> usize {
        let local_edges = topo.simplex.edges();
        let [i, j] = local_edges[le];
        let (gi, gj) = (lv[i], lv[j]);
        let count_at_min = if gi < gj { m[i] } else { m[j] };
        self.edge_base + topo.cell_edges[c * local_edges.len() + le] * self.per_edge + (self.p - count_at_min - 1)
    }

    /// Number a face node: its place on the global face from its counts at the face's sorted vertices.
    fn face_node(&self, topo: &Topology, c: usize, lv: &[usize], m: &[usize; 4], lf: usize) -> usize {
        let tet_faces = crate::reference::simplex::TET_FACES;
        let mut vs: [(usize, usize); 3] = [0, 1, 2].map(|k| {
            let i = tet_faces[lf][k];
            (lv[i], m[i])
        });
        vs.sort_unstable();
        // counts minus one at the sorted vertices sum to q = p − 3
        let (c0, c1) = (vs[0].1 - 1, vs[1].1 - 1);
        let q = self.p - 3;
        let offset: usize = (0..c0).map(|j| q - j + 1).sum();
        self.face_base + topo.cell_faces[c * 4 + lf] * self.per_face + offset + c1
    }

    /// Give every node of global edge `e` the constraint `c`.
    fn constrain_edge(&self, constraint: &mut [NodeConstraint], e: usize, c: NodeConstraint) {
        for k in 0..self.per_edge {
            constraint[self.edge_base + e * self.per_edge + k] = c;
        }
    }

    /// Give every node of global face `f` the constraint `c`.
    fn constrain_face(&self, constraint: &mut [NodeConstraint], f: usize, c: NodeConstraint) {
        for k in 0..self.per_face {
            constraint[self.face_base + f * self.per_face + k] = c;
        }
    }
}

/// Per-edge (or per-face) state while gathering the tags of adjacent boundary facets.
#[derive(Clone, Copy, PartialEq)]
enum Tagging {
    None,
    Untagged,
    Tag(i32),
    Mixed,
}

impl Tagging {
    fn add(self, t: Option<i32>) -> Tagging {
        match (self, t) {
            (Tagging::None, None) => Tagging::Untagged,
            (Tagging::None, Some(t)) => Tagging::Tag(t),
            (Tagging::Tag(a), Some(b)) if a == b => Tagging::Tag(a),
            (Tagging::Untagged, None) => Tagging::Untagged,
            _ => Tagging::Mixed,
        }
    }
}

/// The constraint inside a boundary facet of dimension `dim`: on its entity if tagged, else fixed.
fn facet_constraint(tag: Option<i32>, dim: usize) -> NodeConstraint {
    match tag {
        Some(tag) => NodeConstraint::OnEntity { dim, tag },
        None => NodeConstraint::Fixed,
    }
}

/// The boundary condition of every node of the mesh numbered by `num`.
fn classify(linear: &LinearMesh, topo: &Topology, num: &Numbering) -> Result<Vec<NodeConstraint>> {
    let dim = linear.dim;
    let mut constraint = vec![NodeConstraint::Free; num.n_nodes];
    for (v, &b) in topo.boundary_vertex.iter().enumerate() {
        if b {
            constraint[v] = NodeConstraint::Fixed;
        }
    }
    let edge_lookup = topo.edge_lookup();
    let facet_tag = facet_tags(linear, topo, edge_lookup)?;

    if dim == 2 {
        for &e in &topo.boundary_facets {
            num.constrain_edge(&mut constraint, e, facet_constraint(facet_tag[e], 1));
        }
        return Ok(constraint);
    }

    // 3D: faces, then edges of boundary faces, then feature edges (which win).
    let edge_tagging = constrain_boundary_faces(topo, num, &facet_tag, edge_lookup, &mut constraint);
    constrain_face_edges(num, &edge_tagging, &mut constraint);
    constrain_feature_edges(linear, num, &edge_tagging, edge_lookup, &mut constraint)?;
    Ok(constraint)
}

/// Tag of every facet (None = untagged); each tagged facet must be a boundary facet, listed once.
fn facet_tags(
    linear: &LinearMesh,
    topo: &Topology,
    edge_lookup: &HashMap<[usize; 2], usize>,
) -> Result<Vec<Option<i32>>> {
    let dim = linear.dim;
    let n_facets = if dim == 3 { topo.faces.len() } else { topo.edges.len() };
    let mut is_boundary = vec![false; n_facets];
    for &f in &topo.boundary_facets {
        is_boundary[f] = true;
    }
    let mut facet_tag: Vec<Option<i32>> = vec![None; n_facets];
    let mut given = vec![false; n_facets];
    let face_lookup = topo.face_lookup();
    for (k, f) in linear.facets.chunks_exact(dim).enumerate() {
        let id = if dim == 2 {
            edge_lookup.get(&[f[0].min(f[1]), f[0].max(f[1])]).copied()
        } else {
            let mut key = [f[0], f[1], f[2]];
            key.sort_unstable();
            face_lookup.get(&key).copied()
        };
        let id = match id {
            Some(id) if is_boundary[id] => id,
            _ => {
                return Err(Error::InvalidInput(format!(
                    "tagged facet {k} {:?} is not a boundary facet of the mesh",
                    f
                )))
            }
        };
        if given[id] {
            return Err(Error::InvalidInput(format!("boundary facet {:?} is tagged twice (facet {k})", f)));
        }
        given[id] = true;
        facet_tag[id] = Some(linear.facet_tags[k]);
    }
    Ok(facet_tag)
}

/// 3D: constrain the boundary faces' nodes and gather the tags of the faces around each edge.
fn constrain_boundary_faces(
    topo: &Topology,
    num: &Numbering,
    facet_tag: &[Option<i32>],
    edge_lookup: &HashMap<[usize; 2], usize>,
    constraint: &mut [NodeConstraint],
) -> Vec<Tagging> {
    let mut edge_tagging = vec![Tagging::None; topo.edges.len()];
    for &f in &topo.boundary_facets {
        num.constrain_face(constraint, f, facet_constraint(facet_tag[f], 2));
        let [a, b, cc] = topo.faces[f];
        for e in [[a, b], [b, cc], [a, cc]] {
            let id = edge_lookup[&e];
            edge_tagging[id] = edge_tagging[id].add(facet_tag[f]);
        }
    }
    edge_tagging
}

/// 3D: put the nodes of boundary-face edges on the surface when their faces agree, else fix them.
fn constrain_face_edges(num: &Numbering, edge_tagging: &[Tagging], constraint: &mut [NodeConstraint]) {
    for (e, t) in edge_tagging.iter().enumerate() {
        let c = match *t {
            Tagging::None => continue,
            Tagging::Tag(tag) => NodeConstraint::OnEntity { dim: 2, tag },
            Tagging::Untagged | Tagging::Mixed => NodeConstraint::Fixed,
        };
        num.constrain_edge(constraint, e, c);
    }
}

/// 3D: constrain the feature edges' nodes onto their curves; each must be a boundary edge, listed once.
fn constrain_feature_edges(
    linear: &LinearMesh,
    num: &Numbering,
    edge_tagging: &[Tagging],
    edge_lookup: &HashMap<[usize; 2], usize>,
    constraint: &mut [NodeConstraint],
) -> Result<()> {
    let mut edge_given = vec![false; edge_tagging.len()];
    for (k, e) in linear.feature_edges.chunks_exact(2).enumerate() {
        let key = [e[0].min(e[1]), e[0].max(e[1])];
        let id = match edge_lookup.get(&key) {
            Some(&id) if edge_tagging[id] != Tagging::None => id,
            _ => return Err(Error::InvalidInput(format!("feature edge {k} {:?} is not an edge of the boundary", e))),
        };
        if edge_given[id] {
            return Err(Error::InvalidInput(format!("feature edge {:?} is tagged twice (edge {k})", e)));
        }
        edge_given[id] = true;
        num.constrain_edge(constraint, id, NodeConstraint::OnEntity { dim: 1, tag: linear.feature_edge_tags[k] });
    }
    Ok(())
}
