//! hocurve: valid high-order curved triangle and tetrahedral meshes by the
//! solid-mechanics analogy of Poya, Sevilla & Gil (Comput. Mech. 2016).
//!
//! The chain, each module knowing only the ones before it:
//! `reference` → `quadrature` → `mapping` → `mesh` → `geometry` → `material`
//! → `quality` → `assembly` → `solver` → `optimize` → `curve` → `session`; `io`, `ffi`
//! and the CLI sit at the edges, `cases` builds demo and test meshes.

pub mod error;

pub mod assembly;
pub mod curve;
pub mod geometry;
pub mod mapping;
pub mod material;
pub mod mesh;
pub mod optimize;
pub mod quadrature;
pub mod quality;
pub mod reference;
pub mod session;
pub mod solver;
pub mod study;

pub mod cases;
pub mod ffi;
pub mod io;

pub use curve::{curve, CurveOptions, CurveReport, CurvedMesh, Formulation};
pub use error::{Error, Result};
