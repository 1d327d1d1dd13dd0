//! Which cells no curving can keep valid with their vertices fixed, and the
//! quality that the flips maximise.
//!
//! A pure function of the linear mesh and the bulge β of each tagged
//! boundary facet ([`super::bulge`]; β > 0 when curving pushes the facet into
//! its cell). A cell is *bad* when
//!
//! * **surface**: all its vertices lie on one boundary entity (they are
//!   vertices of facets with that tag) that bulges into the domain at them
//!   (some facet of that tag at one of them has β > [`CONCAVE_BULGE`] times
//!   its longest edge). Such a cell lies between the straight boundary and the
//!   curved one (on a sphere cavity: inside the ball), the region that curving
//!   removes from the domain, and it has nowhere to go; or
//! * **bulge**: one of its facets is a boundary facet whose bulge exceeds
//!   [`BULGE_FRACTION`] of the height h of the opposite vertex over it, and
//!   that vertex is on the boundary, so the solve keeps it fixed. (An interior
//!   apex moves with the boundary: the first layer of the demo's stretched
//!   boundary layer around a cylinder has β = 1.64 h and curves well.) At
//!   p = 2 the Jacobian at a curved edge's midpoint is det J₀ (1 − 2 ∇(λ_a +
//!   λ_b)·δ) for a displacement δ of that midpoint, and 2 ∇(λ_a + λ_b)·δ is
//!   about 4β/(3h) with the apex above the facet's centroid: such cells invert,
//!   or come close, as soon as β reaches h/2 (the free interior nodes of higher
//!   orders help only so much).
//!
//! The quality of a cell, in [−2, 1] (1 for a regular straight cell with no
//! bulge, negative exactly for bad cells), is the smallest of
//!
//! * its mean ratio q_mr, 1 for the regular simplex: 12 (3|K|)^(2/3) / Σ l²
//!   for a tet, 4√3 |K| / Σ l² for a triangle (l the edge lengths);
//! * (h − β / [`BULGE_FRACTION`]) / (c L) over its boundary facets with β > 0
//!   and a boundary vertex opposite, L the facet's longest edge and c the height-to-edge ratio of the regular
//!   simplex (√(2/3), √3/2): the height left once the bulge is taken out;
//! * q_mr − 1 for a surface cell.

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use super::geom::{boundary_facets, cross, facet_key, facet_of, norm, orient, sub, FacetKey};
use crate::mesh::LinearMesh;

/// A boundary facet whose bulge exceeds this fraction of the height of the
/// opposite vertex over it makes its cell bad.
pub const BULGE_FRACTION: f64 = 0.5;

/// An entity bulges into the domain at a facet when the facet's bulge exceeds
/// this fraction of its longest edge (far above round-off, far below any
/// curvature that matters).
pub const CONCAVE_BULGE: f64 = 1e-6;

/// A cell whose dim! |K| is at most this times L^dim (L its longest edge) is
/// degenerate: flips never create one.
pub const DEGENERATE: f64 = 1e-12;

/// Why a cell is bad, and its quality (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assessment {
    pub quality: f64,
    /// All vertices on one entity that bulges into the domain there.
    pub surface: bool,
    /// A boundary facet bulges past [`BULGE_FRACTION`] of the opposite height.
    pub bulge: bool,
}

impl Assessment {
    pub fn is_bad(&self) -> bool {
        self.surface || self.bulge
    }
}

/// The per-mesh data of the criteria (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Criteria {
    dim: usize,
    /// Bulge of each tagged facet.
    bulge: HashMap<FacetKey, f64>,
    /// Per vertex: the tags of the facets at it, each with whether one of
    /// those facets bulges into the domain.
    surfaces: Vec<Vec<(i32, bool)>>,
    /// The facets with one cell (tagged or not): the boundary, which flips keep.
    boundary: HashSet<FacetKey>,
    /// Per vertex: on the boundary, hence fixed in the solve.
    boundary_vertex: Vec<bool>,
}

impl Criteria {
    /// `bulge`: one value per facet of `mesh` ([`super::bulge::facet_bulges`]).
    pub fn new(mesh: &LinearMesh, bulge: &[f64]) -> Criteria {
        Criteria::on_boundary(mesh, bulge, &boundary_facets(mesh))
    }

    /// [`Criteria::new`], the boundary facets of `mesh` known ([`boundary_facets`]).
    pub fn on_boundary(mesh: &LinearMesh, bulge: &[f64], boundary: &[FacetKey]) -> Criteria {
        let d = mesh.dim;
        let mut surfaces: Vec<Vec<(i32, bool)>> = vec![Vec::new(); mesh.n_vertices()];
        let mut map = HashMap::default();
        for ((f, &tag), &b) in mesh.facets.chunks_exact(d.max(1)).zip(&mesh.facet_tags).zip(bulge) {
            let x: Vec<[f64; 3]> = f.iter().map(|&v| mesh.vertex(v)).collect();
            let concave = b > CONCAVE_BULGE * longest_edge(&x);
            for &v in f {
                match surfaces[v].iter_mut().find(|(t, _)| *t == tag) {
                    Some(s) => s.1 |= concave,
                    None => surfaces[v].push((tag, concave)),
                }
            }
            map.insert(facet_key(f), b);
        }
        let boundary: HashSet<FacetKey> = boundary.iter().copied().collect();
        let mut boundary_vertex = vec![false; mesh.n_vertices()];
        for f in &boundary {
            for &v in f.iter().filter(|&&v| v != usize::MAX) {
                boundary_vertex[v] = true;
            }
        }
        Criteria { dim: d, bulge: map, surfaces, boundary, boundary_vertex }
    }

    /// The criteria of the same mesh after interior edges were split, with
    /// `n_vertices` vertices now: the facets and the boundary are the same
    /// (a split edge is interior, so no facet and no boundary face holds
    /// it), and the new vertices are interior. Equal to [`Criteria::new`] on
    /// that mesh, without sorting its cells' faces again.
    pub fn after_split(mut self, n_vertices: usize) -> Criteria {
        self.surfaces.resize(n_vertices, Vec::new());
        self.boundary_vertex.resize(n_vertices, false);
        self
    }

    /// Whether facet `f` is on the boundary of the mesh the criteria were made for.
    pub fn is_boundary(&self, f: &FacetKey) -> bool {
        self.boundary.contains(f)
    }

    /// Whether vertex `v` is on the boundary.
    pub fn is_boundary_vertex(&self, v: usize) -> bool {
        self.boundary_vertex[v]
    }

    /// Whether the cell can be bad at all: a bad cell has all its vertices
    /// on the boundary (a surface cell by definition, a bulge cell because
    /// its facet and the opposite vertex are).
    pub fn may_be_bad(&self, cell: &[usize]) -> bool {
        cell.iter().all(|&v| self.boundary_vertex[v])
    }

    /// Assess the cell with vertices `cell` (`dim + 1`, positively oriented
    /// unless degenerate: then the quality is −∞) at coordinates `coords`
    /// (`dim` per vertex), in the mesh the criteria were made for or one
    /// with the same boundary.
    pub fn assess(&self, coords: &[f64], cell: &[usize]) -> Assessment {
        let d = self.dim;
        let x: Vec<[f64; 3]> = cell
            .iter()
            .map(|&v| {
                let mut p = [0.0; 3];
                p[..d].copy_from_slice(&coords[v * d..(v + 1) * d]);
                p
            })
            .collect();
        let vol = orient(d, &x);
        let l2: f64 = (0..=d).flat_map(|i| (i + 1..=d).map(move |j| (i, j))).map(|(i, j)| dist2(x[i], x[j])).sum();
        let lmax = longest_edge(&x);
        // Also catches a NaN.
        if vol.is_nan() || vol <= DEGENERATE * lmax.powi(d as i32) {
            return Assessment { quality: f64::NEG_INFINITY, surface: false, bulge: false };
        }
        let mean_ratio = if d == 2 {
            // 4√3 A / Σ l², A = vol / 2.
            2.0 * 3f64.sqrt() * vol / l2
        } else {
            12.0 * (vol / 2.0).powf(2.0 / 3.0) / l2
        };
        let c = if d == 2 { 3f64.sqrt() / 2.0 } else { (2.0f64 / 3.0).sqrt() };
        let mut quality = mean_ratio;
        let mut bulge = false;
        for k in 0..=d {
            let key = facet_of(cell, k);
            let Some(&b) = self.bulge.get(&key) else { continue };
            if b <= 0.0 || !self.boundary.contains(&key) || !self.boundary_vertex[cell[k]] {
                continue;
            }
            let y: Vec<[f64; 3]> = (0..=d).filter(|&j| j != k).map(|j| x[j]).collect();
            // Height of vertex k over the facet: dim! |K| / ((dim − 1)! |F|).
            let h =
                if d == 2 { vol / norm(sub(y[1], y[0])) } else { vol / norm(cross(sub(y[1], y[0]), sub(y[2], y[0]))) };
            bulge |= b > BULGE_FRACTION * h;
            quality = quality.min((h - b / BULGE_FRACTION) / (c * longest_edge(&y)));
        }
        let surface = self.on_one_bulging_surface(cell);
        if surface {
            quality = quality.min(mean_ratio - 1.0);
        }
        Assessment { quality, surface, bulge }
    }

    /// All vertices of `cell` on one entity, which bulges into the domain at one of them.
    fn on_one_bulging_surface(&self, cell: &[usize]) -> bool {
        self.surfaces[cell[0]].iter().any(|&(tag, concave0)| {
            let mut concave = concave0;
            for &v in &cell[1..] {
                match self.surfaces[v].iter().find(|(t, _)| *t == tag) {
                    Some(&(_, c)) => concave |= c,
                    None => return false,
                }
            }
            concave
        })
    }
}

/// The bad cells of `mesh` (a validated, positively oriented mesh) and their
/// assessment, given the bulge of each of its facets.
pub fn bad_cells(mesh: &LinearMesh, bulge: &[f64]) -> Vec<(usize, Assessment)> {
    let crit = Criteria::new(mesh, bulge);
    crit.bad_cells(mesh)
}

impl Criteria {
    /// The bad cells of `mesh` (the mesh the criteria were made for).
    pub fn bad_cells(&self, mesh: &LinearMesh) -> Vec<(usize, Assessment)> {
        use rayon::prelude::*;
        let d = mesh.dim;
        let bad: Vec<(usize, Assessment)> = mesh
            .cells
            .par_chunks_exact(d + 1)
            .enumerate()
            .filter(|(_, c)| self.may_be_bad(c))
            .map(|(i, c)| (i, self.assess(&mesh.coords, c)))
            .filter(|(_, a)| a.is_bad())
            .collect();
        bad
    }
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let v = sub(a, b);
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

fn longest_edge(x: &[[f64; 3]]) -> f64 {
    let mut l: f64 = 0.0;
    for i in 0..x.len() {
        for j in i + 1..x.len() {
            l = l.max(dist2(x[i], x[j]));
        }
    }
    l.sqrt()
}
