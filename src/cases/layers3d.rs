//! 3D boundary layer: prism layers on a sphere, split into tetrahedra.
//!
//! The surface is an icosphere (an icosahedron whose faces are split into
//! four `level` times, its vertices on the unit sphere). Each surface vertex
//! is extruded along its radius through `n_layers` layers whose thicknesses
//! grow geometrically, the first one the mean surface edge divided by the
//! stretching, so that the first layer's prisms have edge / height ≈ the
//! stretching. Each prism is split into three tetrahedra by the
//! minimum-vertex-index rule (each quad face along the diagonal through its
//! smallest global index, the same seen from both prisms that share it), so
//! the tets conform. This is how boundary-layer meshes for CFD are made:
//! extruded prisms, split where the solver wants tets.

use std::collections::HashMap;

use super::{push_cell, push_facet, Case};
use crate::geometry::shapes::{Shape, ShapeProjector};
use crate::mesh::LinearMesh;

/// The icosphere of `level` on the unit sphere: vertices and triangles
/// (counter-clockwise seen from outside).
fn icosphere(level: usize) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| unit(p))
    .collect();
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut midpoint = |a: usize, b: usize, v: &mut Vec<[f64; 3]>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (v[a], v[b]);
                v.push(unit([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
                v.len() - 1
            })
        };
        let mut next = Vec::with_capacity(4 * f.len());
        for &[a, b, c] in &f {
            let (ab, bc, ca) = (midpoint(a, b, &mut v), midpoint(b, c, &mut v), midpoint(c, a, &mut v));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

fn unit(p: [f64; 3]) -> [f64; 3] {
    let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    [p[0] / r, p[1] / r, p[2] / r]
}

/// The three tetrahedra of the prism with bottom triangle `b` and top `t`
/// (t[i] above b[i]), by the minimum-vertex-index rule.
fn split_prism(b: [usize; 3], t: [usize; 3]) -> [[usize; 4]; 3] {
    let v = [b[0], b[1], b[2], t[0], t[1], t[2]];
    // Renumber the prism so that its smallest index is at position 0 (the
    // symmetries of the prism, top and bottom swapped for positions 3..5).
    const TURN: [[usize; 6]; 6] = [
        [0, 1, 2, 3, 4, 5],
        [1, 2, 0, 4, 5, 3],
        [2, 0, 1, 5, 3, 4],
        [3, 5, 4, 0, 2, 1],
        [4, 3, 5, 1, 0, 2],
        [5, 4, 3, 2, 1, 0],
    ];
    let m = (0..6).min_by_key(|&k| v[k]).unwrap_or(0);
    let w = TURN[m].map(|k| v[k]);
    // The quad faces through w[0] are split through it; the opposite one,
    // (1, 2, 5, 4), through its own smallest index.
    if w[1].min(w[5]) < w[2].min(w[4]) {
        [[w[0], w[1], w[2], w[5]], [w[0], w[1], w[5], w[4]], [w[0], w[4], w[5], w[3]]]
    } else {
        [[w[0], w[1], w[2], w[4]], [w[0], w[4], w[2], w[5]], [w[0], w[4], w[5], w[3]]]
    }
}

/// Prism layers on the unit sphere, split into tetrahedra (module docs):
/// an icosphere of `level` (20·4^level triangles), `n_layers` layers whose
/// thicknesses grow by `growth`, the first one the mean surface edge
/// divided by `stretching`. Stretching 1 and growth 1 give layers as thick
/// as the surface edges: the isotropic mesh of the same size.
///
/// Tags: the unit sphere 1, the outer sphere 2, both in the projector.
///
/// # Panics
/// Unless `stretching` ≥ 1 and `growth` ≥ 1 (finite) and `n_layers` ≥ 1.
pub fn sphere_layers_3d(level: usize, n_layers: usize, stretching: f64, growth: f64) -> Case {
    let (surface, triangles) = icosphere(level);
    let edges: f64 = triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (0..3).map(|k| (surface[a][k] - surface[b][k]).powi(2)).sum::<f64>().sqrt())
        .sum::<f64>()
        / (3 * triangles.len()) as f64;
    let radius = super::layer_radii(edges, n_layers, stretching, growth);
    let ns = surface.len();
    let mut mesh = LinearMesh { dim: 3, ..Default::default() };
    for &r in &radius {
        for p in &surface {
            mesh.coords.extend_from_slice(&[r * p[0], r * p[1], r * p[2]]);
        }
    }
    let id = |k: usize, v: usize| k * ns + v;
    for k in 0..n_layers {
        for tri in &triangles {
            for tet in split_prism(tri.map(|v| id(k, v)), tri.map(|v| id(k + 1, v))) {
                push_cell(&mut mesh, tet.to_vec());
            }
        }
    }
    // Boundary facets: the unit sphere (its outside is the sphere's inside)
    // and the outer sphere, each oriented away from a vertex of its layer.
    for tri in &triangles {
        push_facet(&mut mesh, tri.map(|v| id(0, v)).to_vec(), id(1, tri[0]), 1);
        push_facet(&mut mesh, tri.map(|v| id(n_layers, v)).to_vec(), id(n_layers - 1, tri[0]), 2);
    }
    let outer = radius[n_layers];
    let mut projector = ShapeProjector::new();
    projector.insert(1, Shape::Sphere { center: [0.0; 3], radius: 1.0 });
    projector.insert(2, Shape::Sphere { center: [0.0; 3], radius: outer });
    Case {
        name: "sphere_layers_3d".into(),
        description: format!(
            "prism layers on the unit sphere, split into tets: icosphere level {level} ({} triangles), \
             {n_layers} layers growing by {growth}, the first = mean edge {edges:.4} / {stretching}, out to \
             r = {outer:.4}; {} vertices, {} tetrahedra",
            triangles.len(),
            mesh.n_vertices(),
            mesh.n_cells()
        ),
        mesh,
        projector,
    }
}

#[cfg(test)]
mod tests {
    use super::super::check;
    use super::*;
    use crate::mesh::Topology;

    #[test]
    fn the_icosphere_has_the_counts_and_radius_of_its_level() {
        for level in 0..4 {
            let (v, f) = icosphere(level);
            assert_eq!(f.len(), 20 << (2 * level));
            assert_eq!(v.len(), 10 * (1 << (2 * level)) + 2);
            assert!(v.iter().all(|p| (p.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-14));
        }
    }

    #[test]
    fn every_prism_splits_into_three_positive_tets_that_conform() {
        // Topology::new checks that every interior face is shared by two
        // cells; assert_valid that cells are positive and the boundary
        // closes (the volume by cells equals the one by facets).
        for (level, layers, stretching, growth) in [(0, 1, 1.0, 1.0), (1, 3, 100.0, 1.3), (2, 5, 1000.0, 1.3)] {
            let case = sphere_layers_3d(level, layers, stretching, growth);
            let (min, _, _) = check::assert_valid(&case.mesh);
            assert!(min > 0.0);
            let topo = Topology::new(&case.mesh).unwrap();
            let triangles = 20 << (2 * level);
            assert_eq!(case.mesh.n_cells(), 3 * triangles * layers);
            assert_eq!(topo.boundary_facets.len(), 2 * triangles);
            assert_eq!(case.mesh.facet_tags.len(), 2 * triangles);
            for tag in [1, 2] {
                let shape = case.projector.get(2, tag).expect("both spheres are curved");
                for v in check::tagged_vertices(&case.mesh, tag) {
                    let x = case.mesh.vertex(v);
                    let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                    let Shape::Sphere { radius, .. } = shape else { panic!("a sphere") };
                    assert!((r - radius).abs() < 1e-12 * radius, "tag {tag}: r {r} against {radius}");
                }
            }
        }
    }

    #[test]
    fn the_first_layer_has_the_stretching_asked() {
        for stretching in [100.0, 1000.0] {
            let case = sphere_layers_3d(2, 4, stretching, 1.3);
            let (surface, triangles) = icosphere(2);
            let t = &triangles[0];
            let edge = (0..3).map(|k| (surface[t[0]][k] - surface[t[1]][k]).powi(2)).sum::<f64>().sqrt();
            let x = case.mesh.vertex(surface.len() + t[0]);
            let height = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt() - 1.0;
            let ratio = edge / height;
            assert!((ratio / stretching - 1.0).abs() < 0.2, "stretching {stretching}: edge / height {ratio}");
        }
    }
}
