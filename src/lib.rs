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
//!   → curve → session → distributed           the pipeline, its stateful form, and its
//!                                             elastic stage over MPI processes (`mpi`)
//!   → cases → io → ffi                        demo and test meshes, files, the C ABI
//! ```
//!
//! The command-line tool (`src/bin`, with the formulation study) sits above
//! them all.
//!
//! The API is [`curve()`] (or [`curve::curve_prepared`]) and
//! [`session::Session`], with the meshes, projectors, materials, quality
//! measures, solver choices and files they take. `jacobi`, `linalg`,
//! `sparse`, `assembly` and `optimize` are the engine's internals:
//! crate-private, public only with the `internals` feature, which the
//! crate's own tests turn on. `cases` (built-in meshes) comes with the
//! default `demo` feature, which the command line needs.

// Every type the public API reaches can be named from outside.
#![cfg_attr(not(feature = "internals"), warn(unnameable_types))]

/// Modules of the engine that are not its API: public with the `internals`
/// feature (which the crate's own integration tests turn on), crate-private
/// otherwise.
macro_rules! internal {
    ($($(#[$attr:meta])* mod $name:ident;)*) => {$(
        $(#[$attr])*
        #[cfg(feature = "internals")]
        pub mod $name;
        $(#[$attr])*
        #[cfg(not(feature = "internals"))]
        pub(crate) mod $name;
    )*};
}

pub mod error;

#[cfg(test)]
mod testing;

internal! {
    mod jacobi;
    mod linalg;
    mod sparse;
    mod assembly;
    mod optimize;
}

pub mod curve;
pub mod geometry;
pub mod mapping;
pub mod material;
pub mod mesh;
pub mod quadrature;
pub mod quality;
pub mod reference;
pub mod session;
pub mod solver;

/// Built-in demonstration and test meshes (the `demo` feature, on by default).
#[cfg(any(feature = "demo", feature = "internals", test))]
pub mod cases;
/// cbindgen:ignore
#[cfg(feature = "mpi")]
pub mod distributed;
pub mod ffi;
pub mod io;

pub use curve::{curve, CurveOptions, CurveReport, CurvedMesh, Formulation};
pub use error::{Error, Result, SolverFailure};
