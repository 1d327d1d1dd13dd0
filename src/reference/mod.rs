pub mod ordering;
pub mod simplex;
pub use simplex::Simplex;
