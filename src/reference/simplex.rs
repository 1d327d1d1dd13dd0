//! The reference simplices.
//!
//! Triangle: vertices (0,0), (1,0), (0,1). Tetrahedron: (0,0,0), (1,0,0),
//! (0,1,0), (0,0,1) — the same as gmsh and VTK. A point is given by its
//! barycentric coordinates λ, with λ_0 = 1 − Σ ξ_i and λ_i = ξ_i (i ≥ 1).

/// A reference simplex: the triangle (2D) or the tetrahedron (3D).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Simplex {
    Tri,
    Tet,
}

/// Local edges of the triangle, as pairs of local vertices.
pub const TRI_EDGES: [[usize; 2]; 3] = [[0, 1], [1, 2], [2, 0]];
/// Local edges of the tetrahedron (gmsh's order).
pub const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]];
/// Local faces of the tetrahedron, outward-oriented (gmsh's order).
pub const TET_FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [3, 1, 2]];

impl Simplex {
    /// The simplex of spatial dimension `dim` (2 or 3).
    pub fn from_dim(dim: usize) -> Option<Simplex> {
        match dim {
            2 => Some(Simplex::Tri),
            3 => Some(Simplex::Tet),
            _ => None,
        }
    }
    /// Spatial dimension.
    pub fn dim(self) -> usize {
        match self {
            Simplex::Tri => 2,
            Simplex::Tet => 3,
        }
    }
    /// Number of vertices (dim + 1).
    pub fn n_vertices(self) -> usize {
        self.dim() + 1
    }
    /// Number of Lagrange nodes of order `p`: (p+1)(p+2)/2 or (p+1)(p+2)(p+3)/6.
    pub fn n_nodes(self, p: usize) -> usize {
        match self {
            Simplex::Tri => (p + 1) * (p + 2) / 2,
            Simplex::Tet => (p + 1) * (p + 2) * (p + 3) / 6,
        }
    }
    /// Local edges as vertex pairs.
    pub fn edges(self) -> &'static [[usize; 2]] {
        match self {
            Simplex::Tri => &TRI_EDGES,
            Simplex::Tet => &TET_EDGES,
        }
    }
    /// Reference coordinates of the vertices (3 components; z = 0 for the triangle).
    pub fn vertex_coords(self) -> &'static [[f64; 3]] {
        const TRI: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        const TET: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        match self {
            Simplex::Tri => &TRI,
            Simplex::Tet => &TET,
        }
    }
    /// Reference volume (1/2 or 1/6).
    pub fn volume(self) -> f64 {
        match self {
            Simplex::Tri => 0.5,
            Simplex::Tet => 1.0 / 6.0,
        }
    }
}
