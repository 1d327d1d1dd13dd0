//! Mesh topology, high-order node numbering and boundary classification.
//! No files here: see `io`.

pub mod linear;

pub use linear::LinearMesh;
