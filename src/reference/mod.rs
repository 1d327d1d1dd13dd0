//! Reference simplices, Lagrange node sets, the orthonormal (PKDO) basis and
//! the nodal Lagrange bases built on it. Reference coordinates only: no mesh.

pub mod nodes;
pub mod simplex;

pub use nodes::{NodeSet, NodeSpacing};
pub use simplex::Simplex;
