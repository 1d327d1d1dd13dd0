//! Mesh topology, high-order node numbering and boundary classification.
//! No files here: see `io`.

pub mod linear;

pub mod high_order;
pub mod repair;
pub mod topology;

pub use high_order::{HighOrderMesh, NodeConstraint};
pub use linear::LinearMesh;
/// Boundary caps, the first step of the repair (kept at its former path).
pub use repair::caps;
pub use repair::{remove_boundary_caps, repair, repair_with, RepairSummary, Repaired};
pub use topology::{validate_and_orient, Topology};
