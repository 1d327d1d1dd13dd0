//! 3D cubed-sphere cases: a spherical cavity in a box, and a spherical shell.
//!
//! Six blocks, one per cube face, each an n × n × n_radial grid of hexahedra
//! along rays from the centre between an inner surface (the sphere, by the
//! equiangular cube-sphere map) and an outer one. Vertices live in one global
//! table indexed by the integer point of the cube surface lattice and the
//! layer, so block interfaces share them. Each hex gets a centre vertex; each
//! of its six quad faces is split along the diagonal through the face's
//! smallest global vertex index (the same choice seen from both hexes that
//! share the face) and each face triangle joined to the centre: 12
//! conforming tets per hex.

use std::f64::consts::PI;

use super::{push_cell, push_facet, Case};
use crate::geometry::shapes::{Shape, ShapeProjector};
use crate::mesh::LinearMesh;

/// Sphere radius of [`sphere_in_box_3d`].
pub const SPHERE_RADIUS: f64 = 0.5;
/// Half width of the box of [`sphere_in_box_3d`].
pub const BOX_HALF_WIDTH: f64 = 2.0;

/// A spherical cavity (radius 0.5, centre origin) inside the box [−2, 2]³.
///
/// `n` (at least 1) is the number of divisions of each cube-sphere face edge,
/// `n_radial` (at least 1) the number of layers between sphere and box,
/// graded geometrically so the first layer is about as thick as the surface
/// spacing πr/(2n) (ratio at most 3). 6·n²·n_radial hexes, 12 tets each.
///
/// Tags: sphere triangles 1 (projector: `Sphere { center: 0, radius: 0.5 }`),
/// box triangles 2 (flat: not in the projector). No feature edges.
pub fn sphere_in_box_3d(n: usize, n_radial: usize) -> Case {
    let (r, l) = (SPHERE_RADIUS, BOX_HALF_WIDTH);
    let n = n.max(1);
    let nr = n_radial.max(1);
    let layers = graded_layers(PI * r / (2.0 * n as f64) / (l - r), nr);
    let mesh = cubed_sphere_shell(
        n,
        &layers,
        |w| {
            let s = r / norm(w);
            [s * w[0], s * w[1], s * w[2]]
        },
        |w| [l * w[0], l * w[1], l * w[2]],
    );
    let mut projector = ShapeProjector::new();
    projector.insert(1, Shape::Sphere { center: [0.0; 3], radius: r });
    Case {
        name: "sphere_in_box_3d".into(),
        description: format!(
            "spherical cavity r = {r} in the box [-{l}, {l}]^3: cubed sphere with {n}x{n} \
             divisions per face, {nr} radial layers; {} vertices, {} tetrahedra",
            mesh.n_vertices(),
            mesh.n_cells()
        ),
        mesh,
        projector,
    }
}

/// The spherical shell r_in < |x| < r_out around the origin, cubed-sphere
/// with `n` divisions per face edge and `n_radial` uniform layers.
/// Tags: inner sphere 1, outer sphere 2, both in the projector.
///
/// # Panics
/// Unless 0 < r_in < r_out (finite).
pub fn spherical_shell_3d(r_in: f64, r_out: f64, n: usize, n_radial: usize) -> Case {
    assert!(
        r_in > 0.0 && r_in < r_out && r_out.is_finite(),
        "shell radii must satisfy 0 < r_in < r_out, got {r_in}, {r_out}"
    );
    let n = n.max(1);
    let nr = n_radial.max(1);
    let layers: Vec<f64> = (0..=nr).map(|k| k as f64 / nr as f64).collect();
    let on_sphere = |radius: f64| {
        move |w: [f64; 3]| {
            let s = radius / norm(w);
            [s * w[0], s * w[1], s * w[2]]
        }
    };
    let mesh = cubed_sphere_shell(n, &layers, on_sphere(r_in), on_sphere(r_out));
    let mut projector = ShapeProjector::new();
    for (tag, radius) in [(1, r_in), (2, r_out)] {
        projector.insert(tag, Shape::Sphere { center: [0.0; 3], radius });
    }
    Case {
        name: "spherical_shell_3d".into(),
        description: format!(
            "spherical shell {r_in} < r < {r_out}: cubed sphere with {n}x{n} divisions per \
             face, {nr} layers; {} vertices, {} tetrahedra",
            mesh.n_vertices(),
            mesh.n_cells()
        ),
        mesh,
        projector,
    }
}

/// Fractions 0 = s₀ < … < s_N = 1 growing geometrically with first step
/// `first` (ratio clamped to [1, 3]).
fn graded_layers(first: f64, n: usize) -> Vec<f64> {
    let step = |q: f64| {
        if q == 1.0 {
            1.0 / n as f64
        } else {
            (q - 1.0) / (q.powi(n as i32) - 1.0)
        }
    };
    let q = if first >= step(1.0) {
        1.0
    } else if first <= step(3.0) {
        3.0
    } else {
        // step(q) decreases in q: bisect.
        let (mut lo, mut hi) = (1.0, 3.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if step(mid) > first {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    let mut s = vec![0.0];
    for k in 0..n {
        s.push(s[k] + step(q) * q.powi(k as i32));
    }
    s[n] = 1.0;
    s
}

/// The tet mesh between `inner(w)` and `outer(w)`, w on the cube [−1, 1]³
/// surface (equiangular coordinates, exact ±1 on faces), with points at the
/// fractions `layers` (from 0 to 1) along each segment. Inner facets tag 1,
/// outer facets tag 2.
fn cubed_sphere_shell(
    n: usize,
    layers: &[f64],
    inner: impl Fn([f64; 3]) -> [f64; 3],
    outer: impl Fn([f64; 3]) -> [f64; 3],
) -> LinearMesh {
    let nr = layers.len() - 1;
    let side = n + 1;
    let on_surface = |t: [usize; 3]| t.iter().any(|&c| c == 0 || c == n);
    // Global ids of the cube surface lattice points.
    let mut surf_id = vec![usize::MAX; side * side * side];
    let mut lattice = Vec::new();
    for a in 0..side {
        for b in 0..side {
            for c in 0..side {
                if on_surface([a, b, c]) {
                    surf_id[(a * side + b) * side + c] = lattice.len();
                    lattice.push([a, b, c]);
                }
            }
        }
    }
    let n_surf = lattice.len();
    let coord = |c: usize| {
        if c == 0 {
            -1.0
        } else if c == n {
            1.0
        } else {
            (PI / 4.0 * (2.0 * c as f64 / n as f64 - 1.0)).tan()
        }
    };
    let mut mesh = LinearMesh { dim: 3, ..Default::default() };
    for &s in layers {
        for t in &lattice {
            let w = [coord(t[0]), coord(t[1]), coord(t[2])];
            let (p, q) = (inner(w), outer(w));
            let x = if s == 0.0 {
                p
            } else if s == 1.0 {
                q
            } else {
                [p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1]), p[2] + s * (q[2] - p[2])]
            };
            mesh.coords.extend_from_slice(&x);
        }
    }
    let vid = |t: [usize; 3], k: usize| k * n_surf + surf_id[(t[0] * side + t[1]) * side + t[2]];
    for axis in 0..3 {
        let (b1, b2) = ((axis + 1) % 3, (axis + 2) % 3);
        for end in [0, n] {
            for i in 0..n {
                for j in 0..n {
                    let corner = |di: usize, dj: usize| {
                        let mut t = [0; 3];
                        t[axis] = end;
                        t[b1] = i + di;
                        t[b2] = j + dj;
                        t
                    };
                    let quad = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    for k in 0..nr {
                        let lo = quad.map(|t| vid(t, k));
                        let hi = quad.map(|t| vid(t, k + 1));
                        add_hex(&mut mesh, lo, hi, k == 0, k + 1 == nr);
                    }
                }
            }
        }
    }
    mesh
}

/// Split the hex with bottom quad `lo` and top quad `hi` (same winding) into
/// 12 tets around a new centre vertex; record the bottom triangles as tag 1
/// facets if `inner_boundary`, the top ones as tag 2 if `outer_boundary`.
fn add_hex(mesh: &mut LinearMesh, lo: [usize; 4], hi: [usize; 4], inner_boundary: bool, outer_boundary: bool) {
    let centre = mesh.n_vertices();
    let mut x = [0.0; 3];
    for &v in lo.iter().chain(&hi) {
        let p = mesh.vertex(v);
        for d in 0..3 {
            x[d] += p[d] / 8.0;
        }
    }
    mesh.coords.extend_from_slice(&x);
    let mut faces = vec![(lo, inner_boundary.then_some(1)), (hi, outer_boundary.then_some(2))];
    for m in 0..4 {
        let m1 = (m + 1) % 4;
        faces.push(([lo[m], lo[m1], hi[m1], hi[m]], None));
    }
    for (quad, tag) in faces {
        let m = (0..4).min_by_key(|&k| quad[k]).unwrap_or(0);
        let q = |k: usize| quad[(m + k) % 4];
        for tri in [[q(0), q(1), q(2)], [q(0), q(2), q(3)]] {
            push_cell(mesh, vec![tri[0], tri[1], tri[2], centre]);
            if let Some(tag) = tag {
                push_facet(mesh, tri.to_vec(), centre, tag);
            }
        }
    }
}

fn norm(w: [f64; 3]) -> f64 {
    w[0].hypot(w[1]).hypot(w[2])
}

#[cfg(test)]
mod tests {
    use super::super::check::{assert_valid, tagged_vertices};
    use super::*;

    /// Volume of the polyhedron bounded by the facets with `tag`.
    fn enclosed_by(mesh: &LinearMesh, tag: i32) -> f64 {
        mesh.facets
            .chunks(3)
            .zip(&mesh.facet_tags)
            .filter(|(_, &t)| t == tag)
            .map(|(f, _)| {
                let (a, b, c) = (mesh.vertex(f[0]), mesh.vertex(f[1]), mesh.vertex(f[2]));
                (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    / 6.0
            })
            .sum::<f64>()
            .abs()
    }

    #[test]
    fn sphere_in_box_is_valid_conforming_and_has_the_right_volume() {
        let exact = 64.0 - 4.0 / 3.0 * PI * 0.125;
        let mut errors = Vec::new();
        for (n, nr) in [(1, 1), (2, 2), (4, 3), (8, 4)] {
            let case = sphere_in_box_3d(n, nr);
            let m = &case.mesh;
            let (_, volume, _) = assert_valid(m);
            assert_eq!(m.n_cells(), 12 * 6 * n * n * nr);
            assert_eq!(m.n_vertices(), (6 * n * n + 2) * (nr + 1) + 6 * n * n * nr);
            // Exactly the box minus the inscribed polyhedron...
            let poly = enclosed_by(m, 1);
            assert!((enclosed_by(m, 2) - 64.0).abs() < 1e-12);
            assert!((volume - (64.0 - poly)).abs() < 1e-12, "{volume} vs {}", 64.0 - poly);
            // ... which converges to the ball as n grows, error O(1/n²).
            let err = volume - exact;
            let h = PI * 0.5 / (2.0 * n as f64);
            assert!(err > 0.0 && err < 4.0 * h * h, "n = {n}: error {err}");
            errors.push(err);
            for v in tagged_vertices(m, 1) {
                assert!((norm(m.vertex(v)) - 0.5).abs() < 1e-12);
            }
            for v in tagged_vertices(m, 2) {
                let x = m.vertex(v);
                assert_eq!(x.iter().fold(0.0f64, |a, c| a.max(c.abs())), 2.0, "{x:?}");
            }
            assert!(case.projector.get(2, 1).is_some() && case.projector.get(2, 2).is_none());
        }
        // Second order: halving h divides the error by about 4.
        for w in errors[1..].windows(2) {
            assert!(w[1] < 0.35 * w[0], "{errors:?}");
        }
    }

    #[test]
    fn spherical_shell_is_valid_with_both_spheres_in_the_projector() {
        let case = spherical_shell_3d(0.5, 1.0, 3, 2);
        let m = &case.mesh;
        let (_, volume, _) = assert_valid(m);
        let exact = 4.0 / 3.0 * PI * (1.0 - 0.125);
        assert!((volume - exact).abs() < 0.15 * exact, "{volume} vs {exact}");
        for (tag, r) in [(1, 0.5), (2, 1.0)] {
            let shape = case.projector.get(2, tag).unwrap();
            for v in tagged_vertices(m, tag) {
                assert!(shape.distance(m.vertex(v)) < 1e-12 * r);
            }
        }
    }

    #[test]
    fn graded_layers_start_with_the_requested_step() {
        let s = graded_layers(0.05, 6);
        assert_eq!((s[0], s[6]), (0.0, 1.0));
        assert!((s[1] - 0.05).abs() < 1e-12);
        assert!(s.windows(2).all(|w| w[1] > w[0]));
        assert_eq!(graded_layers(0.9, 3), vec![0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0]);
    }
}
