//! Fibre directions of the transversely isotropic models, one per cell:
//! the paper's default, and the check of user-given ones.

use crate::mesh::{LinearMesh, Topology};
use crate::{Error, Result};

/// Normalise user fibres: one finite non-zero vector per cell.
pub(crate) fn checked_fibres(f: &[[f64; 3]], n_cells: usize) -> Result<Vec<[f64; 3]>> {
    if f.len() != n_cells {
        return Err(Error::InvalidInput(format!("{} fibre directions given for {n_cells} cells", f.len())));
    }
    f.iter()
        .enumerate()
        .map(|(c, v)| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if n.is_finite() && n > 0.0 {
                Ok([v[0] / n, v[1] / n, v[2] / n])
            } else {
                Err(Error::InvalidInput(format!("fibre direction of cell {c} is zero or not finite")))
            }
        })
        .collect()
}

/// The paper's fibres: −x inside; on cells with a boundary facet, tangent to
/// that facet (in 3D, −x projected onto the facet's plane, or an edge of the
/// facet when −x is normal to it).
pub fn default_fibres(linear: &LinearMesh, topo: &Topology) -> Vec<[f64; 3]> {
    let dim = linear.dim;
    let mut fibres = vec![[-1.0, 0.0, 0.0]; linear.n_cells()];
    let unit = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        (n > 1e-12).then(|| [v[0] / n, v[1] / n, v[2] / n])
    };
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let mut boundary = vec![false; if dim == 2 { topo.edges.len() } else { topo.faces.len() }];
    for &f in &topo.boundary_facets {
        boundary[f] = true;
    }
    for (c, fibre) in fibres.iter_mut().enumerate() {
        if dim == 2 {
            let ne = topo.simplex.edges().len();
            if let Some(&e) = topo.cell_edges[c * ne..(c + 1) * ne].iter().find(|&&e| boundary[e]) {
                let [a, b] = topo.edges[e];
                if let Some(t) = unit(sub(linear.vertex(b), linear.vertex(a))) {
                    *fibre = t;
                }
            }
        } else if let Some(&f) = topo.cell_faces[c * 4..(c + 1) * 4].iter().find(|&&f| boundary[f]) {
            let [a, b, d] = topo.faces[f].map(|v| linear.vertex(v));
            let (u, v) = (sub(b, a), sub(d, a));
            let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            if let Some(n) = unit(n) {
                let m = [-1.0, 0.0, 0.0];
                let dot = m[0] * n[0];
                let proj = [m[0] - dot * n[0], -dot * n[1], -dot * n[2]];
                *fibre = unit(proj).or_else(|| unit(u)).unwrap_or(*fibre);
            }
        }
    }
    fibres
}
