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
    SampleProjections::default().project(dim, samples, projector)
}

/// Projections of bulge samples, remembered by entity and exact point: an
/// edge's midpoint is a sample of both its facets, and the repair measures
/// its mesh again after each change, mostly at the same points. Each point
/// goes to the projector once per entity, which assumes (as every stage of
/// hocurve does) that the projector's answer depends on the point and
/// entity alone. On STEP parts through OpenCASCADE this halves the
/// projections of the repair.
#[derive(Debug, Default)]
pub struct SampleProjections {
    known: rustc_hash::FxHashMap<(usize, i32, [u64; 3]), [f64; 3]>,
}

impl SampleProjections {
    /// [`project_samples`], asking `projector` only for the points not projected before.
    pub fn project(
        &mut self,
        dim: usize,
        samples: &crate::mesh::repair::BulgeSamples,
        projector: &dyn Projector,
    ) -> crate::Result<Vec<[f64; 3]>> {
        let key = |(edim, tag): (usize, i32), x: &[f64; 3]| (edim, tag, x.map(f64::to_bits));
        // The new points of each entity, once each, in the order they come.
        let mut groups: std::collections::BTreeMap<(usize, i32), Vec<[f64; 3]>> = Default::default();
        let mut queued = rustc_hash::FxHashSet::default();
        for (x, &e) in samples.points.iter().zip(&samples.entities) {
            let k = key(e, x);
            if !self.known.contains_key(&k) && queued.insert(k) {
                groups.entry(e).or_default().push(*x);
            }
        }
        for ((edim, tag), pts) in groups {
            let mut out = vec![[f64::NAN; 3]; pts.len()];
            projector.project(edim, tag, &pts, &mut out).map_err(|m| {
                crate::Error::Projection(format!("projector failed on entity (dim {edim}, tag {tag}): {m}"))
            })?;
            for (x, mut y) in pts.iter().zip(out) {
                if dim == 2 {
                    y[2] = 0.0;
                }
                if !y.iter().all(|v| v.is_finite()) {
                    return Err(crate::Error::Projection(format!(
                        "projector returned a non-finite point on entity (dim {edim}, tag {tag})"
                    )));
                }
                self.known.insert(key((edim, tag), x), y);
            }
        }
        Ok(samples.points.iter().zip(&samples.entities).map(|(x, &e)| self.known[&key(e, x)]).collect())
    }
}
