//! Placing the high-order boundary nodes on the geometry: each node
//! classified on an entity is projected onto it through the [`Projector`],
//! and the distance it moves is measured.

use std::collections::BTreeMap;

use super::Projector;
use crate::mesh::{HighOrderMesh, LinearMesh, NodeConstraint};
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
    let target = project_boundary(mesh, linear, projector)?;
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
    Ok(BoundaryPlacement { displacement: ubar, projected_nodes, max_distance: max_dist })
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
