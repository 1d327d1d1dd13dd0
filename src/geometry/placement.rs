//! Placing the high-order boundary nodes on the geometry: each node
//! classified on an entity is projected onto it through the [`Projector`],
//! and the distance it moves is measured.
//!
//! The closest point of a straight node is the right place when the
//! boundary bends little over an element, and the wrong one where an edge
//! cuts across a bend: on a coarse aerofoil whose leading edge is not a
//! vertex, the closest points of the nodes on the chord that cuts off the
//! nose lie on the upper and lower surfaces on either side, none on the
//! nose, and the curved edge skips it. The nodes of such an edge on a
//! curve are placed again along the curve ([`along_curves`]).

use std::collections::BTreeMap;

use super::shapes::{dot, norm, sub, unit_or};
use super::Projector;
use crate::mesh::{HighOrderMesh, LinearMesh, NodeConstraint};
use crate::reference::NodeSet;
use crate::{Error, Result};

/// The boundary nodes placed on the geometry: the displacement that takes
/// the straight mesh there, and how far the nodes moved.
#[derive(Debug, Clone)]
pub struct BoundaryPlacement {
    /// Displacement of each dof from its straight position to its projection
    /// (zero off the boundary).
    pub displacement: Vec<f64>,
    /// Nodes projected.
    pub projected_nodes: usize,
    /// Largest distance between a straight node and its projection.
    pub max_distance: f64,
    /// Edges on curves whose nodes were placed along the curve, their
    /// closest points being out of place ([`along_curves`]).
    pub edges_along_curves: usize,
}

/// Project the boundary nodes of `mesh`, elevated from `linear`, onto the
/// geometry of `projector`, and measure how far they move.
///
/// Fails on a projector error, a non-finite point, or a point farther from
/// its straight node than the longest edge of the cells around it.
pub fn place_boundary_nodes(
    mesh: &HighOrderMesh,
    linear: &LinearMesh,
    projector: &dyn Projector,
) -> Result<BoundaryPlacement> {
    let mut target = project_boundary(mesh, linear, projector)?;
    let edges_along_curves = along_curves(mesh, projector, &mut target)?;
    let dim = mesh.dim();
    let mut ubar = vec![0.0; mesh.coords.len()];
    let mut projected_nodes = 0;
    let mut max_dist: f64 = 0.0;
    for (n, x) in &target {
        let mut d2 = 0.0;
        for k in 0..dim {
            let u = x[k] - mesh.coords[n * dim + k];
            ubar[n * dim + k] = u;
            d2 += u * u;
        }
        max_dist = max_dist.max(d2.sqrt());
        projected_nodes += 1;
    }
    Ok(BoundaryPlacement { displacement: ubar, projected_nodes, max_distance: max_dist, edges_along_curves })
}

/// Batch size of projector calls.
const PROJECT_BATCH: usize = 65_536;

/// Project every node classified on an entity; returns node → projected point.
///
/// Rejects a projector error, a non-finite point, or a point farther from the
/// straight node than the longest edge of the cells around it (a projection
/// onto the wrong entity).
fn project_boundary(
    mesh: &HighOrderMesh,
    linear: &LinearMesh,
    projector: &dyn Projector,
) -> Result<Vec<(usize, [f64; 3])>> {
    let mut groups: BTreeMap<(usize, i32), Vec<usize>> = BTreeMap::new();
    for (n, c) in mesh.constraint.iter().enumerate() {
        if let NodeConstraint::OnEntity { dim, tag } = *c {
            groups.entry((dim, tag)).or_default().push(n);
        }
    }
    if groups.is_empty() {
        return Ok(Vec::new());
    }
    // Local size: longest vertex-to-vertex edge of the cells around each node.
    let mut size = vec![0.0f64; mesh.n_nodes()];
    let npc_lin = linear.dim + 1;
    for (c, lv) in linear.cells.chunks_exact(npc_lin).enumerate() {
        let mut h: f64 = 0.0;
        for i in 0..npc_lin {
            for j in i + 1..npc_lin {
                let (a, b) = (linear.vertex(lv[i]), linear.vertex(lv[j]));
                h = h.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt());
            }
        }
        for &n in mesh.cell(c) {
            size[n] = size[n].max(h);
        }
    }
    let mut out = Vec::new();
    for ((edim, tag), ids) in groups {
        for chunk in ids.chunks(PROJECT_BATCH) {
            let pts: Vec<[f64; 3]> = chunk.iter().map(|&n| mesh.node(n)).collect();
            let mut proj = vec![[f64::NAN; 3]; pts.len()];
            projector
                .project(edim, tag, &pts, &mut proj)
                .map_err(|m| Error::Projection(format!("projector failed on entity (dim {edim}, tag {tag}): {m}")))?;
            for ((&n, x), y) in chunk.iter().zip(&pts).zip(&proj) {
                let mut y = *y;
                if mesh.dim() == 2 {
                    y[2] = 0.0;
                }
                if !y.iter().all(|v| v.is_finite()) {
                    return Err(Error::Projection(format!(
                        "projector returned a non-finite point for node {n} on entity (dim {edim}, tag {tag})"
                    )));
                }
                let d = ((y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2) + (y[2] - x[2]).powi(2)).sqrt();
                if d > size[n] {
                    return Err(Error::Projection(format!(
                        "projector moved node {n} on entity (dim {edim}, tag {tag}) by {d:.3e}, more than the size \
                         of its elements ({:.3e}): is the tag mapped to the right entity?",
                        size[n]
                    )));
                }
                out.push((n, y));
            }
        }
    }
    Ok(out)
}

/// The largest ratio between the gaps of consecutive nodes of an edge
/// (vertices included), each over its share of the reference edge, beyond
/// which the closest points are out of place. On a circular arc the
/// closest points give 1 at p = 2 (by symmetry), at most 1.9 for arcs up
/// to 90° at p ≤ 10, and 2.2 to 3.5 for an arc of 120° at p = 4..10; the
/// chord that cuts off a coarse aerofoil's nose gives 3 at p = 2.
const GAP_RATIO: f64 = 2.0;

/// The least distance from the chord, as a fraction of its length, at
/// which an edge's closest points count as a bend (a circular arc of about
/// 23°): below it, uneven gaps are the projector's slips along an almost
/// straight curve, which a march would not mend.
const BEND: f64 = 0.05;

/// Steps per node of the march along a curve in [`along_curves`].
const MARCH_STEPS: usize = 8;

/// Place again, along its curve, the nodes of each edge on a curve whose
/// closest-point projections (`target`) are out of place ([`uneven`])
/// across a bend ([`BEND`]): the curve between the edge's vertices is
/// followed ([`march`]) and the nodes are placed at the arc-length
/// fractions of their reference positions on the edge, then projected once
/// more. Edges whose march does not reach the other vertex keep their
/// closest points. Returns the edges placed again.
fn along_curves(mesh: &HighOrderMesh, projector: &dyn Projector, target: &mut [(usize, [f64; 3])]) -> Result<usize> {
    let on_curve = |n: usize| matches!(mesh.constraint[n], NodeConstraint::OnEntity { dim: 1, .. });
    if mesh.order < 2 || !(0..mesh.n_nodes()).any(on_curve) {
        return Ok(0);
    }
    let mut at = vec![usize::MAX; mesh.n_nodes()];
    for (i, &(n, _)) in target.iter().enumerate() {
        at[n] = i;
    }
    let mut placed = 0;
    for ([u, v], (tag, members)) in curve_edges(mesh) {
        let (xa, xb) = (mesh.node(u), mesh.node(v));
        let ab = sub(xb, xa);
        let len2 = dot(ab, ab);
        if len2.is_nan() || len2 <= 0.0 || members.iter().any(|&n| at[n] == usize::MAX) {
            continue;
        }
        // The nodes by their fraction along the straight edge.
        let mut by_s: Vec<(f64, usize)> = members.iter().map(|&n| (dot(sub(mesh.node(n), xa), ab) / len2, n)).collect();
        by_s.sort_by(|x, y| x.0.total_cmp(&y.0));
        let points: Vec<[f64; 3]> =
            std::iter::once(xa).chain(by_s.iter().map(|&(_, n)| target[at[n]].1)).chain([xb]).collect();
        let fractions: Vec<f64> = std::iter::once(0.0).chain(by_s.iter().map(|&(s, _)| s)).chain([1.0]).collect();
        let off_chord = points.iter().map(|&x| {
            let r = sub(x, xa);
            let t = dot(r, ab) / len2;
            norm([0, 1, 2].map(|d| r[d] - t * ab[d]))
        });
        if !uneven(&points, &fractions) || off_chord.fold(0.0, f64::max) < BEND * len2.sqrt() {
            continue;
        }
        let project_one = |x: [f64; 3]| -> Result<[f64; 3]> {
            let mut out = [[f64::NAN; 3]];
            projector
                .project(1, tag, &[x], &mut out)
                .map_err(|m| Error::Projection(format!("projector failed on entity (dim 1, tag {tag}): {m}")))?;
            let mut y = out[0];
            if mesh.dim() == 2 {
                y[2] = 0.0;
            }
            Ok(y)
        };
        let Some(arc) = march(&project_one, xa, xb, norm(ab) / (MARCH_STEPS * mesh.order) as f64)? else { continue };
        let mut length = vec![0.0];
        for k in 1..arc.len() {
            length.push(length[k - 1] + norm(sub(arc[k], arc[k - 1])));
        }
        let total = *length.last().expect("two points");
        for &(s, n) in &by_s {
            let want = s * total;
            let k = length.partition_point(|&l| l <= want).clamp(1, arc.len() - 1);
            let w = ((want - length[k - 1]) / (length[k] - length[k - 1]).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            let y = project_one([0, 1, 2].map(|d| arc[k - 1][d] + w * (arc[k][d] - arc[k - 1][d])))?;
            if y.iter().all(|v| v.is_finite()) {
                target[at[n]].1 = y;
            }
        }
        placed += 1;
    }
    Ok(placed)
}

/// The edges of `mesh` whose nodes lie on a curve: their vertices (sorted),
/// the curve's tag and the edge's nodes.
fn curve_edges(mesh: &HighOrderMesh) -> BTreeMap<[usize; 2], (i32, Vec<usize>)> {
    // The local edge nodes of a cell, with the local vertices of their edge.
    let nodes = NodeSet::new(mesh.simplex, mesh.order, mesh.spacing);
    let dim = mesh.dim();
    let vertex_slot: Vec<usize> =
        (0..=dim).map(|i| nodes.multi.iter().position(|m| m[i] == mesh.order).expect("a vertex node")).collect();
    let edge_nodes: Vec<(usize, usize, usize)> = nodes
        .multi
        .iter()
        .enumerate()
        .filter_map(|(a, m)| match (0..=dim).filter(|&i| m[i] > 0).collect::<Vec<_>>()[..] {
            [i, j] => Some((a, vertex_slot[i], vertex_slot[j])),
            _ => None,
        })
        .collect();
    let mut edges: BTreeMap<[usize; 2], (i32, Vec<usize>)> = BTreeMap::new();
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        for &(a, i, j) in &edge_nodes {
            let NodeConstraint::OnEntity { dim: 1, tag } = mesh.constraint[cell[a]] else { continue };
            let (u, v) = (cell[i], cell[j]);
            let entry = edges.entry([u.min(v), u.max(v)]).or_insert_with(|| (tag, Vec::new()));
            if !entry.1.contains(&cell[a]) {
                entry.1.push(cell[a]);
            }
        }
    }
    edges
}

/// True when the gaps between consecutive `points` of an edge (its
/// vertices and its nodes' closest points, in order), each over its share
/// `fractions[k + 1] − fractions[k]` of the reference edge, differ by more
/// than [`GAP_RATIO`].
fn uneven(points: &[[f64; 3]], fractions: &[f64]) -> bool {
    let (lo, hi) = points.windows(2).zip(fractions.windows(2)).fold((f64::INFINITY, 0.0f64), |(lo, hi), (x, s)| {
        let rate = norm(sub(x[1], x[0])) / (s[1] - s[0]);
        (lo.min(rate), hi.max(rate))
    });
    hi > GAP_RATIO * lo
}

/// The curve from `xa` to `xb` as a polyline: from `xa`'s projection, steps
/// of length `step` along the direction of the last (the first along the
/// curve towards `xb`), each projected back by `project_one`, until within
/// a step of `xb`. None if it does not get there in four times the steps
/// of the chord, or stalls.
fn march(
    project_one: &dyn Fn([f64; 3]) -> Result<[f64; 3]>,
    xa: [f64; 3],
    xb: [f64; 3],
    step: f64,
) -> Result<Option<Vec<[f64; 3]>>> {
    let ab = sub(xb, xa);
    let start = project_one(xa)?;
    let probe = sub(project_one([0, 1, 2].map(|d| start[d] + 1e-2 * ab[d]))?, start);
    let mut dir = unit_or(probe, probe);
    let mut arc = vec![xa, start];
    let steps = (4.0 * norm(ab) / step).ceil() as usize;
    for _ in 0..steps {
        let last = *arc.last().expect("xa");
        if norm(sub(xb, last)) <= step {
            arc.push(xb);
            return Ok(Some(arc));
        }
        let next = project_one([0, 1, 2].map(|d| last[d] + step * dir[d]))?;
        let moved = sub(next, last);
        if !next.iter().all(|v| v.is_finite()) || norm(moved) <= 1e-3 * step {
            return Ok(None);
        }
        dir = unit_or(moved, moved);
        arc.push(next);
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Shape, ShapeProjector};
    use crate::mesh::{validate_and_orient, Topology};
    use crate::reference::NodeSpacing;

    /// A triangle with vertices on the unit circle at angles −`half`, `half`
    /// (degrees) and 180°, its edge between the first two on the circle
    /// (tag 1, the others straight), elevated to order `p`.
    fn cap(half: f64, p: usize) -> (HighOrderMesh, LinearMesh) {
        let h = half.to_radians();
        let linear = LinearMesh {
            dim: 2,
            coords: vec![h.cos(), -h.sin(), h.cos(), h.sin(), -1.0, 0.0],
            cells: vec![0, 1, 2],
            facets: vec![0, 1],
            facet_tags: vec![1],
            feature_edges: Vec::new(),
            feature_edge_tags: Vec::new(),
        };
        let (linear, _) = validate_and_orient(&linear).unwrap();
        let topo = Topology::new(&linear).unwrap();
        let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
        (HighOrderMesh::elevate(&linear, &topo, &nodes, NodeSpacing::Optimal).unwrap(), linear)
    }

    fn unit_circle() -> ShapeProjector {
        let mut p = ShapeProjector::new();
        p.insert(1, Shape::Circle { center: [0.0, 0.0], radius: 1.0 });
        p
    }

    /// The nodes of the circle edge: fraction along the straight edge and
    /// angle of the placed node.
    fn placed(mesh: &HighOrderMesh, placement: &BoundaryPlacement) -> Vec<(f64, f64, f64)> {
        let (a, b) = (mesh.node(0), mesh.node(1));
        (mesh.n_vertices..mesh.n_nodes())
            .filter(|&n| matches!(mesh.constraint[n], NodeConstraint::OnEntity { .. }))
            .map(|n| {
                let x = mesh.node(n);
                let s = (x[1] - a[1]) / (b[1] - a[1]);
                let y = [x[0] + placement.displacement[2 * n], x[1] + placement.displacement[2 * n + 1]];
                (s, y[1].atan2(y[0]), (y[0] * y[0] + y[1] * y[1]).sqrt())
            })
            .collect()
    }

    #[test]
    fn an_edge_across_a_bend_has_its_nodes_placed_by_arc_length() {
        // The chord of an arc of 170°: the closest points of its nodes crowd
        // towards the vertices (a node a quarter of the way along goes to
        // −80°, not −42.5°).
        let h = 85.0f64.to_radians();
        for p in [3, 4, 6, 8] {
            let (mesh, linear) = cap(85.0, p);
            let placement = place_boundary_nodes(&mesh, &linear, &unit_circle()).unwrap();
            assert_eq!(placement.edges_along_curves, 1, "p = {p}");
            let nodes = placed(&mesh, &placement);
            assert_eq!(nodes.len(), p - 1);
            let mut apart: f64 = 0.0;
            for (s, angle, radius) in nodes {
                assert!((radius - 1.0).abs() < 1e-12, "p = {p}: off the circle ({radius})");
                let closest = ((2.0 * s - 1.0) * h.sin()).atan2(h.cos());
                let by_arc = -h + 2.0 * h * s;
                assert!((angle - by_arc).abs() < 2e-3, "p = {p}, s = {s}: {angle} against {by_arc}");
                apart = apart.max((closest - by_arc).abs());
            }
            assert!(apart > 0.3, "p = {p}: the closest points are {apart} rad from the arc's, too close to tell");
        }
    }

    /// Projects onto the line x = cos 85° of the cap's circle edge, but
    /// slips along it: y goes to `slip(y)`, monotone, which moves the
    /// projections of evenly spaced points towards y_b in the middle.
    struct Slipping;

    fn slip(y: f64) -> f64 {
        let h = 85.0f64.to_radians();
        let s = (y + h.sin()) / (2.0 * h.sin());
        y + 0.3 * h.sin() * (std::f64::consts::PI * s).sin()
    }

    impl Projector for Slipping {
        fn project(
            &self,
            _: usize,
            _: i32,
            points: &[[f64; 3]],
            out: &mut [[f64; 3]],
        ) -> std::result::Result<(), String> {
            for (x, y) in points.iter().zip(out) {
                *y = [85.0f64.to_radians().cos(), slip(x[1]), 0.0];
            }
            Ok(())
        }
    }

    #[test]
    fn uneven_projections_on_a_straight_edge_are_left_as_they_are() {
        // Gaps from 0.55 to 1.45 times their share at p = 4: uneven, but
        // the edge is straight.
        let (mesh, linear) = cap(85.0, 4);
        let placement = place_boundary_nodes(&mesh, &linear, &Slipping).unwrap();
        assert_eq!(placement.edges_along_curves, 0);
        let nodes: Vec<usize> = (mesh.n_vertices..mesh.n_nodes())
            .filter(|&n| matches!(mesh.constraint[n], NodeConstraint::OnEntity { .. }))
            .collect();
        assert_eq!(nodes.len(), 3);
        for n in nodes {
            let y = mesh.node(n)[1];
            assert!((y + placement.displacement[2 * n + 1] - slip(y)).abs() < 1e-12);
        }
    }

    #[test]
    fn a_gently_curved_edge_keeps_the_closest_points() {
        // An arc of 60° at p = 4, and the symmetric arc of 170° at p = 2
        // (its one node goes to the arc's midpoint either way).
        for (half, p) in [(30.0f64, 4), (85.0, 2)] {
            let (mesh, linear) = cap(half, p);
            let placement = place_boundary_nodes(&mesh, &linear, &unit_circle()).unwrap();
            assert_eq!(placement.edges_along_curves, 0);
            let h = half.to_radians();
            for (s, angle, _) in placed(&mesh, &placement) {
                let closest = ((2.0 * s - 1.0) * h.sin()).atan2(h.cos());
                assert!((angle - closest).abs() < 1e-12, "{angle} against {closest}");
            }
        }
    }
}
