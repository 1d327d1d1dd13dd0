//! Reference simplices.

pub mod simplex;
pub use simplex::Simplex;
