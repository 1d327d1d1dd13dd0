//! Typed errors of the library. The C ABI maps each variant to a status code
//! in one place.

use std::fmt;

/// Every failure hocurve can report.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// The caller's input is malformed: bad mesh, bad index, bad parameter.
    InvalidInput(String),
    /// The projector failed or returned a non-finite point.
    Projection(String),
    /// A linear solve, factorisation or Newton iteration failed.
    Solver { kind: SolverFailure, message: String },
    /// The curving produced, or would produce, an inverted element: `cell`
    /// (an index into the mesh being curved) when one is known.
    InvalidElement { cell: Option<usize>, message: String },
    /// A file could not be read or written, or is malformed.
    Io(String),
    /// A progress callback asked the run to stop.
    Cancelled,
}

/// Why a solver failed, so that callers can tell the causes apart (the direct
/// solver falls back to LU only when Cholesky meets an indefinite matrix).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverFailure {
    /// The matrix, or a preconditioner block, is not positive definite.
    NotPositiveDefinite,
    /// The matrix is singular (LU).
    Singular,
    /// An iteration (PCG or Newton) did not reach its tolerance.
    NotConverged,
    /// A solution or residual is not finite.
    NonFinite,
    /// The solver could not be set up: ordering, preconditioner, sizes.
    Setup,
    /// An allocation for a factor or workspace failed.
    OutOfMemory,
    /// The host's own linear solver failed or returned a bad solution.
    External,
}

impl Error {
    /// A [`Error::Solver`] of `kind`.
    pub fn solver(kind: SolverFailure, message: impl Into<String>) -> Error {
        Error::Solver { kind, message: message.into() }
    }

    /// A [`Error::InvalidElement`] at `cell`, when it is known.
    pub fn invalid_element(cell: Option<usize>, message: impl Into<String>) -> Error {
        Error::InvalidElement { cell, message: message.into() }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidInput(m) => write!(f, "invalid input: {m}"),
            Error::Projection(m) => write!(f, "projection failed: {m}"),
            Error::Solver { message, .. } => write!(f, "solver failed: {message}"),
            Error::InvalidElement { message, .. } => write!(f, "invalid element: {message}"),
            Error::Io(m) => write!(f, "i/o error: {m}"),
            Error::Cancelled => write!(f, "cancelled by the progress callback"),
        }
    }
}

impl std::error::Error for Error {}

/// Result alias used across the crate.
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_keep_their_prefix_and_details_stay_fields() {
        let e = Error::invalid_element(Some(7), "cell 7 is inverted");
        assert_eq!(e.to_string(), "invalid element: cell 7 is inverted");
        assert!(matches!(e, Error::InvalidElement { cell: Some(7), .. }));
        let e = Error::solver(SolverFailure::Singular, "the matrix is singular");
        assert_eq!(e.to_string(), "solver failed: the matrix is singular");
        assert!(matches!(e, Error::Solver { kind: SolverFailure::Singular, .. }));
    }
}
