//! Reference simplices, Lagrange node sets, the orthonormal (PKDO) basis and
//! the nodal Lagrange bases built on it. Reference coordinates only: no mesh.

pub mod lagrange;
pub mod nodes;
pub mod ordering;
pub mod orthonormal;
pub mod simplex;

pub use lagrange::{LagrangeBasis, Tabulation};
pub use nodes::{NodeSet, NodeSpacing};
pub use orthonormal::OrthonormalBasis;
pub use simplex::Simplex;
