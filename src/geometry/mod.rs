//! The geometry seen by hocurve: a [`Projector`] that maps points onto
//! geometric entities (CAD curves and surfaces), and analytic shapes.

/// Projects batches of points onto geometric entities.
///
/// Points always carry three components (z = 0 in 2D). `entity_dim` is 1 for
/// a curve and 2 for a surface; `tag` is the caller's entity tag. The
/// projector writes the closest point on the entity for each input point into
/// `out` (same length as `points`).
pub trait Projector: Sync {
    /// Project `points` onto entity (`entity_dim`, `tag`), writing into `out`.
    /// An `Err` carries a message and stops the run.
    fn project(
        &self,
        entity_dim: usize,
        tag: i32,
        points: &[[f64; 3]],
        out: &mut [[f64; 3]],
    ) -> std::result::Result<(), String>;
}

pub mod naca;
pub mod placement;
pub mod shapes;

pub use naca::Naca4;
pub use placement::{place_boundary_nodes, BoundaryPlacement};
pub use shapes::{Shape, ShapeProjector};

/// The bulge of each facet of `mesh` ([`crate::mesh::repair::bulge`]): its
/// sample points are projected with one call to `projector` per entity.
/// A projector error or a non-finite point is an error of the run.
pub fn facet_bulges(mesh: &crate::mesh::LinearMesh, projector: &dyn Projector) -> crate::Result<Vec<f64>> {
    use crate::mesh::repair::bulge;
    let samples = bulge::bulge_samples(mesh);
    let projected = project_samples(mesh.dim, &samples, projector)?;
    Ok(bulge::facet_bulges(mesh, &samples, &projected))
}

/// The bulge samples of a mesh of dimension `dim`
/// ([`crate::mesh::repair::bulge_samples`]) projected onto their entities,
/// with one call to `projector` per entity (z = 0 in 2D). A projector error
/// or a non-finite point is an error of the run.
pub fn project_samples(
    dim: usize,
    samples: &crate::mesh::repair::BulgeSamples,
    projector: &dyn Projector,
) -> crate::Result<Vec<[f64; 3]>> {
    let mut groups: std::collections::BTreeMap<(usize, i32), Vec<usize>> = Default::default();
    for (i, &e) in samples.entities.iter().enumerate() {
        groups.entry(e).or_default().push(i);
    }
    let mut projected = vec![[f64::NAN; 3]; samples.points.len()];
    for ((edim, tag), ids) in groups {
        let pts: Vec<[f64; 3]> = ids.iter().map(|&i| samples.points[i]).collect();
        let mut out = vec![[f64::NAN; 3]; pts.len()];
        projector.project(edim, tag, &pts, &mut out).map_err(|m| {
            crate::Error::Projection(format!("projector failed on entity (dim {edim}, tag {tag}): {m}"))
        })?;
        for (&i, mut y) in ids.iter().zip(out) {
            if dim == 2 {
                y[2] = 0.0;
            }
            if !y.iter().all(|v| v.is_finite()) {
                return Err(crate::Error::Projection(format!(
                    "projector returned a non-finite point on entity (dim {edim}, tag {tag})"
                )));
            }
            projected[i] = y;
        }
    }
    Ok(projected)
}
