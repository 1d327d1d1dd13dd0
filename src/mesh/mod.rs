//! Mesh topology, high-order node numbering and boundary classification.
//! No files here: see `io`.

pub mod linear;

pub mod caps;
pub mod high_order;
pub mod topology;

pub use caps::remove_boundary_caps;
pub use high_order::{HighOrderMesh, NodeConstraint};
pub use linear::LinearMesh;
pub use topology::{validate_and_orient, Topology};
