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
    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        if self.dim == 0 {
            0
        } else {
            self.coords.len() / self.dim
        }
    }
    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.cells.len() / (self.dim + 1)
    }
    /// Number of tagged boundary facets.
    pub fn n_facets(&self) -> usize {
        if self.dim == 0 {
            0
        } else {
            self.facets.len() / self.dim
        }
    }
    /// Vertex `v` as a 3-vector (z = 0 in 2D).
    pub fn vertex(&self, v: usize) -> [f64; 3] {
        let mut x = [0.0; 3];
        x[..self.dim].copy_from_slice(&self.coords[v * self.dim..(v + 1) * self.dim]);
        x
    }
}
