//! hocurve: valid high-order curved triangle and tetrahedral meshes by the
//! solid-mechanics analogy of Poya, Sevilla & Gil (Comput. Mech. 2016).
//!
//! The chain, each module knowing only the ones before it:
//! `reference` → `quadrature` → `mapping` → `mesh` → `geometry` → `material`
//! → `quality` → `assembly` → `solver` → `curve`; `io`, `ffi` and the CLI sit
//! at the edges.

pub mod cases;
pub mod error;
pub mod geometry;
pub mod io;
pub mod mesh;
pub mod quadrature;
pub mod reference;

pub use error::{Error, Result};
pub mod assembly;
pub mod curve;
pub mod mapping;
pub mod material;
pub mod quality;
pub mod solver;

pub use curve::{curve, CurveOptions, CurveReport, CurvedMesh, Formulation};
pub mod ffi;
pub mod session;
