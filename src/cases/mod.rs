//! Built-in test cases: linear meshes built in code (no input files) together
//! with the analytic geometry of their curved boundaries, for the demo and the
//! tests.
//!
//! Every case tags its boundary facets; the tags attached to a shape in
//! [`Case::projector`] are curved, the others are straight (flat) walls that
//! stay fixed. Cells are positively oriented and boundary facets are ordered
//! so that their normal (right-hand rule in 3D, the right side in 2D) points
//! out of the domain.

pub mod cylinder2d;
pub mod layers3d;
pub mod sphere3d;

pub use cylinder2d::{annulus_2d, circle_layers_2d, cylinder_channel_2d};
pub use layers3d::sphere_layers_3d;
pub use sphere3d::{sphere_in_box_3d, spherical_shell_3d};

use crate::geometry::shapes::ShapeProjector;
use crate::mesh::LinearMesh;

/// A linear mesh with the geometry of its tagged boundary.
#[derive(Debug, Clone)]
pub struct Case {
    /// Short identifier, e.g. `cylinder_channel_2d`.
    pub name: String,
    /// The straight-sided mesh.
    pub mesh: LinearMesh,
    /// Shapes of the curved boundary entities, keyed by facet tag.
    pub projector: ShapeProjector,
    /// One-line human description with the parameters used.
    pub description: String,
}

/// Signed measure of a simplex given by its vertices: the triangle area in 2D,
/// the tet volume in 3D (positive for counter-clockwise / right-handed order).
pub(crate) fn signed_measure(mesh: &LinearMesh, cell: &[usize]) -> f64 {
    let p: Vec<[f64; 3]> = cell.iter().map(|&v| mesh.vertex(v)).collect();
    let factorial = if mesh.dim == 2 { 2.0 } else { 6.0 };
    crate::mesh::topology::signed_measure(mesh.dim, &p) / factorial
}

/// Radii of boundary layers on a unit circle or sphere: 1, then `n_layers`
/// layers whose thicknesses grow by `growth` from `edge / stretching`.
///
/// # Panics
/// Unless `stretching` ≥ 1 and `growth` ≥ 1 (finite) and `n_layers` ≥ 1.
pub(crate) fn layer_radii(edge: f64, n_layers: usize, stretching: f64, growth: f64) -> Vec<f64> {
    assert!(stretching.is_finite() && stretching >= 1.0, "stretching must be finite and >= 1, got {stretching}");
    assert!(growth.is_finite() && growth >= 1.0, "growth must be finite and >= 1, got {growth}");
    assert!(n_layers >= 1, "at least one layer");
    let mut radius = vec![1.0];
    for k in 0..n_layers {
        radius.push(radius[k] + edge / stretching * growth.powi(k as i32));
    }
    radius
}

/// Append `cell` to the mesh, swapping its last two vertices if needed so
/// that its signed measure is positive.
pub(crate) fn push_cell(mesh: &mut LinearMesh, mut cell: Vec<usize>) {
    if signed_measure(mesh, &cell) < 0.0 {
        let n = cell.len();
        cell.swap(n - 2, n - 1);
    }
    mesh.cells.extend_from_slice(&cell);
}

/// Append the boundary facet `facet` with `tag`, ordered so that its normal
/// points away from `inside` (the vertex of its cell opposite to it).
pub(crate) fn push_facet(mesh: &mut LinearMesh, mut facet: Vec<usize>, inside: usize, tag: i32) {
    let mut simplex = facet.clone();
    simplex.push(inside);
    // With the outward order, (facet, inside) is negatively oriented in 3D
    // (normal away from the inside vertex) and, in 2D, the inside lies to
    // the left of the edge (positive triangle).
    let s = signed_measure(mesh, &simplex);
    let flip = if mesh.dim == 2 { s < 0.0 } else { s > 0.0 };
    if flip {
        facet.swap(0, 1);
    }
    mesh.facets.extend_from_slice(&facet);
    mesh.facet_tags.push(tag);
}

/// Geometric growth: `n` thicknesses starting at `h1` with the ratio that
/// makes them add up to `total` (found by bisection; the ratio may be < 1).
pub(crate) fn geometric_thicknesses(h1: f64, total: f64, n: usize) -> Vec<f64> {
    let sum = |q: f64| (0..n).map(|j| h1 * q.powi(j as i32)).sum::<f64>();
    let (mut lo, mut hi) = (1e-3, 1.0);
    while sum(hi) < total && hi < 1e3 {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if sum(mid) < total {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let q = 0.5 * (lo + hi);
    let mut h: Vec<f64> = (0..n).map(|j| h1 * q.powi(j as i32)).collect();
    // Absorb the bisection round-off so that the sum is `total` to 1 ulp.
    let s: f64 = h.iter().sum();
    for v in &mut h {
        *v *= total / s;
    }
    h
}

#[cfg(test)]
pub(crate) mod check {
    //! Mesh checks shared by the case tests.
    use super::signed_measure;
    use crate::mesh::LinearMesh;
    use std::collections::{BTreeMap, BTreeSet};

    /// Facets (sorted vertex lists) of every cell, with their multiplicity
    /// and the opposite vertex of (one of) their cells.
    fn facet_counts(mesh: &LinearMesh) -> BTreeMap<Vec<usize>, (usize, usize)> {
        let nv = mesh.dim + 1;
        let mut counts = BTreeMap::new();
        for cell in mesh.cells.chunks(nv) {
            for skip in 0..nv {
                let mut f: Vec<usize> = (0..nv).filter(|&k| k != skip).map(|k| cell[k]).collect();
                f.sort_unstable();
                counts.entry(f).or_insert((0, cell[skip])).0 += 1;
            }
        }
        counts
    }

    /// Panics unless the mesh is a valid, conforming simplicial mesh whose
    /// boundary is exactly its tagged facets, each facet oriented outward.
    /// Returns (minimum cell measure, total measure, measure enclosed by the
    /// boundary facets by the divergence theorem).
    pub fn assert_valid(mesh: &LinearMesh) -> (f64, f64, f64) {
        let nv = mesh.dim + 1;
        assert!(mesh.dim == 2 || mesh.dim == 3);
        assert_eq!(mesh.coords.len() % mesh.dim, 0);
        assert_eq!(mesh.cells.len() % nv, 0);
        assert_eq!(mesh.facets.len(), mesh.dim * mesh.facet_tags.len());
        assert!(mesh.cells.iter().all(|&v| v < mesh.n_vertices()));
        assert!(mesh.coords.iter().all(|c| c.is_finite()));
        // Positive cells.
        let mut min = f64::INFINITY;
        let mut total = 0.0;
        for cell in mesh.cells.chunks(nv) {
            let m = signed_measure(mesh, cell);
            min = min.min(m);
            total += m;
        }
        assert!(min > 0.0, "a cell has non-positive measure {min}");
        // Conforming: interior facets shared by 2 cells, boundary ones by 1,
        // the boundary equal to the tagged facets.
        let counts = facet_counts(mesh);
        assert!(counts.values().all(|&(c, _)| c <= 2), "a facet in > 2 cells");
        let boundary: BTreeSet<Vec<usize>> =
            counts.iter().filter(|(_, &(c, _))| c == 1).map(|(f, _)| f.clone()).collect();
        let mut tagged = BTreeSet::new();
        for f in mesh.facets.chunks(mesh.dim) {
            let mut f = f.to_vec();
            f.sort_unstable();
            assert!(tagged.insert(f), "a tagged facet is listed twice");
        }
        assert_eq!(boundary, tagged, "boundary facets differ from the tagged ones");
        // Outward: the cell lies to the left of a 2D facet, behind a 3D one.
        for f in mesh.facets.chunks(mesh.dim) {
            let mut key = f.to_vec();
            key.sort_unstable();
            let mut simplex = f.to_vec();
            simplex.push(counts[&key].1);
            let s = signed_measure(mesh, &simplex);
            let outward = if mesh.dim == 2 { s > 0.0 } else { s < 0.0 };
            assert!(outward, "facet {f:?} is not oriented outward");
        }
        // Every vertex used by a cell.
        let used: BTreeSet<usize> = mesh.cells.iter().copied().collect();
        assert_eq!(used.len(), mesh.n_vertices(), "unused vertices");
        // Closed, outward boundary: the measure it encloses (divergence
        // theorem) equals the total cell measure.
        let enclosed: f64 = mesh
            .facets
            .chunks(mesh.dim)
            .map(|f| {
                let p: Vec<[f64; 3]> = f.iter().map(|&v| mesh.vertex(v)).collect();
                if mesh.dim == 2 {
                    // ∮ x dy / ... = ½ Σ (x_a y_b − x_b y_a) for the outward order.
                    0.5 * (p[0][0] * p[1][1] - p[1][0] * p[0][1])
                } else {
                    let (a, b, c) = (p[0], p[1], p[2]);
                    (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                        + a[2] * (b[0] * c[1] - b[1] * c[0]))
                        / 6.0
                }
            })
            .sum();
        assert!((enclosed - total).abs() <= 1e-12 * total.abs(), "boundary encloses {enclosed}, cells measure {total}");
        (min, total, enclosed)
    }

    /// Vertices of the facets with `tag`.
    pub fn tagged_vertices(mesh: &LinearMesh, tag: i32) -> BTreeSet<usize> {
        mesh.facets
            .chunks(mesh.dim)
            .zip(&mesh.facet_tags)
            .filter(|(_, &t)| t == tag)
            .flat_map(|(f, _)| f.iter().copied())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometric_thicknesses_sum_to_total() {
        for (h1, total, n) in [(0.01, 1.5, 20), (0.5, 1.0, 4), (0.1, 0.3, 3), (1e-5, 2.0, 60)] {
            let h = geometric_thicknesses(h1, total, n);
            assert_eq!(h.len(), n);
            assert!((h.iter().sum::<f64>() - total).abs() < 1e-14 * total);
            let q = h[1] / h[0];
            assert!(h.windows(2).all(|w| (w[1] / w[0] - q).abs() < 1e-9 * q));
            assert!((h[0] / h1 - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn check_accepts_a_good_mesh_and_catches_bad_ones() {
        // Unit square split along 0-2, facets outward (counter-clockwise).
        let good = LinearMesh {
            dim: 2,
            coords: vec![0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0],
            cells: vec![0, 1, 2, 0, 2, 3],
            facets: vec![0, 1, 1, 2, 2, 3, 3, 0],
            facet_tags: vec![1; 4],
            ..Default::default()
        };
        let (min, total, _) = check::assert_valid(&good);
        assert!((min - 0.5).abs() < 1e-15 && (total - 1.0).abs() < 1e-15);
        let fails = |m: LinearMesh| std::panic::catch_unwind(move || check::assert_valid(&m)).is_err();
        // Duplicated vertex 4 = 0: the diagonal is not shared (non-conforming).
        let mut dup = good.clone();
        dup.coords.extend_from_slice(&[0.0, 0.0]);
        dup.cells = vec![0, 1, 2, 4, 2, 3];
        dup.facets = vec![0, 1, 1, 2, 2, 3, 3, 4];
        assert!(fails(dup));
        // Inverted cell.
        let mut inv = good.clone();
        inv.cells = vec![0, 2, 1, 0, 2, 3];
        assert!(fails(inv));
        // Inward facet.
        let mut inward = good.clone();
        inward.facets[0..2].copy_from_slice(&[1, 0]);
        assert!(fails(inward));
        // Missing boundary facet.
        let mut missing = good;
        missing.facets.truncate(6);
        missing.facet_tags.truncate(3);
        assert!(fails(missing));
    }
}
