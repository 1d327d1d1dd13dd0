//! 2D O-grid cases: a cylinder in a square channel with a stretched boundary
//! layer, and an annulus.

use std::f64::consts::PI;

use super::{geometric_thicknesses, push_cell, push_facet, Case};
use crate::geometry::shapes::{Shape, ShapeProjector};
use crate::mesh::LinearMesh;

/// Cylinder radius of [`cylinder_channel_2d`].
pub const CYLINDER_RADIUS: f64 = 0.5;
/// Half width of the square channel of [`cylinder_channel_2d`].
pub const CHANNEL_HALF_WIDTH: f64 = 2.0;
/// Growth ratio of the boundary-layer thicknesses (and the target ratio of
/// the outer cells) in [`cylinder_channel_2d`].
pub const GROWTH: f64 = 1.2;

/// A circular cylinder (radius 0.5, centre origin) in the square channel
/// [−2, 2]², meshed by an O-grid of rays from the centre.
///
/// Around the circle `n_around` uniform angles, rounded up to a multiple of 4
/// (at least 8), start at 45° so the channel corners are vertices. Along each
/// ray, `n_layers` boundary-layer cells of thickness h₀·1.2ᵏ with
/// h₀ = (circle chord between two rays) / `stretching`, so the first-layer
/// triangles have longest/shortest edge ≈ `stretching`. Beyond, cells grow
/// geometrically (ratio ≈ 1.2, from 1.2× the last layer) out to the square.
/// If the boundary layer would fill more than half of the gap to the walls it
/// is scaled down (then the stretching is larger than requested). Every quad
/// is split along its shorter diagonal.
///
/// Tags: circle edges 1 (projector: `Circle { center: [0, 0], radius: 0.5 }`),
/// channel walls 2 (straight: not in the projector).
///
/// # Panics
/// If `stretching` is not finite or is < 1.
pub fn cylinder_channel_2d(n_around: usize, n_layers: usize, stretching: f64) -> Case {
    assert!(stretching.is_finite() && stretching >= 1.0, "stretching must be finite and >= 1, got {stretching}");
    let n = n_around.max(8).div_ceil(4) * 4;
    let (r, l) = (CYLINDER_RADIUS, CHANNEL_HALF_WIDTH);
    let chord = 2.0 * r * (PI / n as f64).sin();
    let h0 = chord / stretching;
    // Boundary layer offsets from the circle, the same on every ray.
    let mut bl: Vec<f64> = (0..n_layers).map(|k| h0 * GROWTH.powi(k as i32)).collect();
    let gap = l - r;
    let bl_total: f64 = bl.iter().sum();
    if bl_total > 0.5 * gap {
        bl.iter_mut().for_each(|h| *h *= 0.5 * gap / bl_total);
    }
    let mut offsets = vec![0.0];
    for h in &bl {
        offsets.push(offsets[offsets.len() - 1] + h);
    }
    let rho_bl = offsets[n_layers];
    // Outer region: fractions s_j ∈ [0, 1] of the remaining distance to the
    // wall along each ray, grading from the boundary layer's last cell.
    let h1 = bl.last().map_or(h0, |h| h * GROWTH);
    let rest = gap - rho_bl;
    let n_out = ((1.0 + rest * (GROWTH - 1.0) / h1).ln() / GROWTH.ln()).ceil() as usize;
    let n_out = n_out.max(2);
    let mut fractions = vec![0.0];
    for h in geometric_thicknesses(h1, rest, n_out) {
        fractions.push(fractions[fractions.len() - 1] + h / rest);
    }
    fractions[n_out] = 1.0;
    let n_rings = n_layers + n_out;

    let position = |i: usize, k: usize| -> [f64; 2] {
        let th = PI / 4.0 + 2.0 * PI * i as f64 / n as f64;
        let (s, c) = th.sin_cos();
        if k == 0 {
            return [r * c, r * s];
        }
        let m = c.abs().max(s.abs());
        if k == n_rings {
            // On the square, exactly.
            return if i.is_multiple_of(n / 4) {
                [l * c.signum(), l * s.signum()]
            } else if c.abs() >= s.abs() {
                [l * c.signum(), l * s / c.abs()]
            } else {
                [l * c / s.abs(), l * s.signum()]
            };
        }
        let rho = if k <= n_layers {
            r + offsets[k]
        } else {
            let wall = l / m;
            r + rho_bl + fractions[k - n_layers] * (wall - r - rho_bl)
        };
        [rho * c, rho * s]
    };
    let mesh = ring_mesh(n, n_rings, position);
    let mut projector = ShapeProjector::new();
    projector.insert(1, Shape::Circle { center: [0.0, 0.0], radius: r });
    Case {
        name: "cylinder_channel_2d".into(),
        description: format!(
            "cylinder r = {r} in the square channel [-{l}, {l}]^2: {n} divisions around, \
             {n_layers} boundary layers (first thickness {:.3e}, stretching {stretching}), \
             {n_out} outer layers; {} vertices, {} triangles",
            offsets.get(1).copied().unwrap_or(0.0),
            mesh.n_vertices(),
            mesh.n_cells()
        ),
        mesh,
        projector,
    }
}

/// The annulus r_in < |x| < r_out around the origin: `n_around` uniform
/// divisions (at least 3), `n_radial` uniform layers (at least 1).
/// Tags: inner circle 1, outer circle 2, both in the projector.
///
/// # Panics
/// Unless 0 < r_in < r_out (finite).
pub fn annulus_2d(r_in: f64, r_out: f64, n_around: usize, n_radial: usize) -> Case {
    assert!(
        r_in > 0.0 && r_in < r_out && r_out.is_finite(),
        "annulus radii must satisfy 0 < r_in < r_out, got {r_in}, {r_out}"
    );
    let n = n_around.max(3);
    let nr = n_radial.max(1);
    let position = |i: usize, k: usize| -> [f64; 2] {
        let (s, c) = (2.0 * PI * i as f64 / n as f64).sin_cos();
        let rho = if k == nr { r_out } else { r_in + (r_out - r_in) * k as f64 / nr as f64 };
        [rho * c, rho * s]
    };
    let mesh = ring_mesh(n, nr, position);
    let mut projector = ShapeProjector::new();
    for (tag, radius) in [(1, r_in), (2, r_out)] {
        projector.insert(tag, Shape::Circle { center: [0.0, 0.0], radius });
    }
    Case {
        name: "annulus_2d".into(),
        description: format!(
            "annulus {r_in} < r < {r_out}: {n} divisions around, {nr} layers; \
             {} vertices, {} triangles",
            mesh.n_vertices(),
            mesh.n_cells()
        ),
        mesh,
        projector,
    }
}

/// Boundary layers on the unit circle: `n_around` uniform divisions (at
/// least 3) and `n_layers` layers whose thicknesses grow by `growth`, the
/// first one the chord between two rays divided by `stretching`, so that
/// the first layer's quads have chord / height = `stretching`; each quad is
/// split into two triangles. The 2D counterpart of
/// [`super::sphere_layers_3d`]: stretching 1 and growth 1 give the
/// isotropic mesh of the same size.
///
/// Tags: the unit circle 1, the outer circle 2, both in the projector.
///
/// # Panics
/// Unless `stretching` ≥ 1 and `growth` ≥ 1 (finite) and `n_layers` ≥ 1.
pub fn circle_layers_2d(n_around: usize, n_layers: usize, stretching: f64, growth: f64) -> Case {
    let n = n_around.max(3);
    let chord = 2.0 * (PI / n as f64).sin();
    let radius = super::layer_radii(chord, n_layers, stretching, growth);
    let position = |i: usize, k: usize| -> [f64; 2] {
        let (s, c) = (2.0 * PI * i as f64 / n as f64).sin_cos();
        [radius[k] * c, radius[k] * s]
    };
    let mesh = ring_mesh(n, n_layers, position);
    let outer = radius[n_layers];
    let mut projector = ShapeProjector::new();
    projector.insert(1, Shape::Circle { center: [0.0, 0.0], radius: 1.0 });
    projector.insert(2, Shape::Circle { center: [0.0, 0.0], radius: outer });
    Case {
        name: "circle_layers_2d".into(),
        description: format!(
            "layers on the unit circle: {n} divisions around, {n_layers} layers growing by {growth}, the first = \
             chord {chord:.4} / {stretching}, out to r = {outer:.4}; {} vertices, {} triangles",
            mesh.n_vertices(),
            mesh.n_cells()
        ),
        mesh,
        projector,
    }
}

/// Triangle mesh of a ring grid: vertex (i, k), i ∈ 0..n around (periodic),
/// k ∈ 0..=n_rings outward, index k·n + i. Each quad is split along its
/// shorter diagonal. Inner ring edges get tag 1, outer ring edges tag 2.
fn ring_mesh(n: usize, n_rings: usize, position: impl Fn(usize, usize) -> [f64; 2]) -> LinearMesh {
    let mut mesh = LinearMesh { dim: 2, ..Default::default() };
    for k in 0..=n_rings {
        for i in 0..n {
            mesh.coords.extend_from_slice(&position(i, k));
        }
    }
    let id = |i: usize, k: usize| k * n + i % n;
    let dist = |mesh: &LinearMesh, a: usize, b: usize| {
        let (p, q) = (mesh.vertex(a), mesh.vertex(b));
        (p[0] - q[0]).hypot(p[1] - q[1])
    };
    for k in 0..n_rings {
        for i in 0..n {
            let (a, b, c, d) = (id(i, k), id(i + 1, k), id(i + 1, k + 1), id(i, k + 1));
            let (t1, t2) =
                if dist(&mesh, a, c) <= dist(&mesh, b, d) { ([a, b, c], [a, c, d]) } else { ([a, b, d], [b, c, d]) };
            push_cell(&mut mesh, t1.to_vec());
            push_cell(&mut mesh, t2.to_vec());
            // The triangle holding a boundary edge and its opposite vertex.
            if k == 0 {
                let inside = if t1.contains(&c) { c } else { d };
                push_facet(&mut mesh, vec![a, b], inside, 1);
            }
            if k + 1 == n_rings {
                let inside = if t2.contains(&a) { a } else { b };
                push_facet(&mut mesh, vec![d, c], inside, 2);
            }
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::super::check::{assert_valid, tagged_vertices};
    use super::*;

    /// Area of the polygon inscribed in the circle by the tag-1 edges.
    fn inscribed_area(mesh: &LinearMesh, tag: i32) -> f64 {
        mesh.facets
            .chunks(2)
            .zip(&mesh.facet_tags)
            .filter(|(_, &t)| t == tag)
            .map(|(f, _)| {
                let (p, q) = (mesh.vertex(f[0]), mesh.vertex(f[1]));
                0.5 * (p[0] * q[1] - q[0] * p[1])
            })
            .sum::<f64>()
            .abs()
    }

    #[test]
    fn cylinder_channel_is_valid_conforming_and_has_the_right_area() {
        for (na, nl, st) in [(16, 3, 10.0), (64, 10, 100.0), (30, 6, 800.0), (8, 0, 1.0)] {
            let case = cylinder_channel_2d(na, nl, st);
            let m = &case.mesh;
            let (_, area, _) = assert_valid(m);
            // Exact: square minus the inscribed polygon (ray vertices on the
            // circle), and close to square minus disk with error ~ (2π/n)².
            let poly = inscribed_area(m, 1);
            assert!((area - (16.0 - poly)).abs() < 1e-12, "{area} vs {}", 16.0 - poly);
            let n = na.max(8).div_ceil(4) * 4;
            let exact = 16.0 - PI * 0.25;
            let err = area - exact;
            assert!(err > 0.0 && err < 0.25 * (2.0 * PI / n as f64).powi(2), "{err}");
            for v in tagged_vertices(m, 1) {
                let x = m.vertex(v);
                assert!((x[0].hypot(x[1]) - 0.5).abs() < 1e-12);
            }
            for v in tagged_vertices(m, 2) {
                let x = m.vertex(v);
                assert_eq!(x[0].abs().max(x[1].abs()), 2.0, "{x:?} not on the wall");
            }
            assert!(case.projector.get(1, 1).is_some() && case.projector.get(1, 2).is_none());
            assert_eq!(m.n_facets(), 2 * n);
        }
    }

    /// Mean over the triangles touching the circle of longest / shortest edge.
    fn first_layer_stretching(m: &LinearMesh) -> f64 {
        let on_circle = tagged_vertices(m, 1);
        let len = |a: usize, b: usize| {
            let (p, q) = (m.vertex(a), m.vertex(b));
            (p[0] - q[0]).hypot(p[1] - q[1])
        };
        let ratios: Vec<f64> = m
            .cells
            .chunks(3)
            .filter(|c| c.iter().any(|v| on_circle.contains(v)))
            .map(|c| {
                let e = [len(c[0], c[1]), len(c[1], c[2]), len(c[2], c[0])];
                e.iter().copied().fold(0.0, f64::max) / e.iter().copied().fold(f64::MAX, f64::min)
            })
            .collect();
        ratios.iter().sum::<f64>() / ratios.len() as f64
    }

    #[test]
    fn first_layer_stretching_is_as_requested() {
        for st in [25.0, 100.0, 400.0, 800.0] {
            let s = first_layer_stretching(&cylinder_channel_2d(64, 10, st).mesh);
            println!("requested stretching {st}: measured {s:.2}");
            assert!((s / st - 1.0).abs() < 0.05, "requested {st}, measured {s}");
        }
    }

    #[test]
    fn circle_layers_are_valid_with_the_stretching_asked() {
        for (stretching, growth) in [(1.0, 1.0), (100.0, 1.3), (1000.0, 1.3)] {
            let case = circle_layers_2d(64, 10, stretching, growth);
            let (min, _, _) = assert_valid(&case.mesh);
            assert!(min > 0.0);
            assert_eq!(case.mesh.n_cells(), 2 * 64 * 10);
            assert_eq!(case.mesh.facet_tags.len(), 2 * 64);
            // Vertex 0 of ring 1 sits the first layer's height above vertex 0.
            let chord = 2.0 * (PI / 64.0).sin();
            let x = case.mesh.vertex(64);
            let height = x[0].hypot(x[1]) - 1.0;
            assert!((chord / height / stretching - 1.0).abs() < 1e-9, "{stretching}: {}", chord / height);
            for tag in [1, 2] {
                let Some(Shape::Circle { radius, .. }) = case.projector.get(1, tag) else { panic!("tag {tag}") };
                for v in tagged_vertices(&case.mesh, tag) {
                    let p = case.mesh.vertex(v);
                    assert!((p[0].hypot(p[1]) - radius).abs() < 1e-12, "tag {tag}");
                }
            }
        }
    }

    #[test]
    fn annulus_is_valid_with_both_circles_in_the_projector() {
        let case = annulus_2d(0.5, 1.25, 24, 4);
        let m = &case.mesh;
        let (_, area, _) = assert_valid(m);
        let exact = PI * (1.25f64.powi(2) - 0.25);
        assert!((area - exact).abs() < 0.05 * exact);
        assert_eq!((m.n_vertices(), m.n_cells()), (24 * 5, 2 * 24 * 4));
        for (tag, r) in [(1, 0.5), (2, 1.25)] {
            for v in tagged_vertices(m, tag) {
                let x = m.vertex(v);
                assert!(case.projector.get(1, tag).unwrap().distance(x) < 1e-12 * r);
            }
        }
    }
}
