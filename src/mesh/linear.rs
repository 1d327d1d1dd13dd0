//! The linear (order-1) input mesh, as the caller hands it over.

/// A straight-sided triangle (dim 2) or tetrahedral (dim 3) mesh with its
/// tagged boundary. All indices are 0-based.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinearMesh {
    /// Spatial dimension, 2 or 3.
    pub dim: usize,
    /// Vertex coordinates, `dim` interleaved components per vertex.
    pub coords: Vec<f64>,
    /// Cell vertices, `dim + 1` per cell.
    pub cells: Vec<usize>,
    /// Boundary facets (edges in 2D, triangles in 3D), `dim` vertices each.
    pub facets: Vec<usize>,
    /// Geometric entity tag of each facet (`facets.len() / dim` entries).
    pub facet_tags: Vec<i32>,
    /// 3D only: feature edges (where two CAD surfaces meet), 2 vertices each.
    pub feature_edges: Vec<usize>,
    /// CAD curve tag of each feature edge.
    pub feature_edge_tags: Vec<i32>,
}

impl LinearMesh {
    /// Drop the tags of facets (entity dim = dim − 1) and feature edges
    /// (entity dim 1) for which `keep(entity_dim, tag)` is false: they stay
    /// straight. Used when the geometry describes only some entities.
    pub fn retain_tags(&mut self, keep: impl Fn(usize, i32) -> bool) {
        let d = self.dim;
        let (mut facets, mut tags) = (Vec::new(), Vec::new());
        for (f, &t) in self.facets.chunks_exact(d.max(1)).zip(&self.facet_tags) {
            if keep(d.saturating_sub(1), t) {
                facets.extend_from_slice(f);
                tags.push(t);
            }
        }
        self.facets = facets;
        self.facet_tags = tags;
        let (mut edges, mut etags) = (Vec::new(), Vec::new());
        for (e, &t) in self.feature_edges.chunks_exact(2).zip(&self.feature_edge_tags) {
            if keep(1, t) {
                edges.extend_from_slice(e);
                etags.push(t);
            }
        }
        self.feature_edges = edges;
        self.feature_edge_tags = etags;
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.coords.len().checked_div(self.dim).unwrap_or(0)
    }
    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.cells.len() / (self.dim + 1)
    }
    /// Number of tagged boundary facets.
    pub fn n_facets(&self) -> usize {
        self.facets.len().checked_div(self.dim).unwrap_or(0)
    }
    /// Vertex `v` as a 3-vector (z = 0 in 2D).
    pub fn vertex(&self, v: usize) -> [f64; 3] {
        let mut x = [0.0; 3];
        x[..self.dim].copy_from_slice(&self.coords[v * self.dim..(v + 1) * self.dim]);
        x
    }
}
