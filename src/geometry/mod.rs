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
pub mod shapes;

pub use naca::Naca4;
pub use shapes::{Shape, ShapeProjector};
