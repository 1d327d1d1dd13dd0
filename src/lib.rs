//! hocurve: valid high-order curved triangle and tetrahedral meshes by the
//! solid-mechanics analogy of Poya, Sevilla & Gil (Comput. Mech. 2016).
//!
//! The modules form a chain, each using only those before it (the test
//! `tests/layers.rs` holds the code to it):
//!
//! ```text
//! error → jacobi → linalg → sparse            leaves: errors, 1D Gauss points,
//!                                             3×3 algebra, sparse storage
//!   → reference → quadrature → mapping        the reference element, its rules,
//!                                             the element map
//!   → mesh → geometry → material → quality    meshes, projectors, materials,
//!                                             quality and certified validity
//!   → assembly → solver → optimize            systems, their solvers, the
//!                                             optimisation stage
//!   → curve → session                         the pipeline, and its stateful form
//!   → cases → study → io → ffi                demo and test meshes, the
//!                                             formulation study, files, the C ABI
//! ```
//!
//! The command-line tool (`src/bin`) sits above them all.

pub mod error;

pub mod jacobi;
pub mod linalg;
pub mod sparse;

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
pub use error::{Error, Result, SolverFailure};
