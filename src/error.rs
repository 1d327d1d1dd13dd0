//! Typed errors of the library. The C ABI maps each variant to a status code.

use std::fmt;

/// Every failure hocurve can report.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// The caller's input is malformed: bad mesh, bad index, bad parameter.
    InvalidInput(String),
    /// The projector failed or returned a non-finite point.
    Projection(String),
    /// A linear solve or factorisation failed (e.g. matrix not positive definite).
    Solver(String),
    /// The curving produced, or would produce, an inverted element.
    InvalidElement(String),
    /// A file could not be read or written, or is malformed.
    Io(String),
    /// A progress callback asked the run to stop.
    Cancelled,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidInput(m) => write!(f, "invalid input: {m}"),
            Error::Projection(m) => write!(f, "projection failed: {m}"),
            Error::Solver(m) => write!(f, "solver failed: {m}"),
            Error::InvalidElement(m) => write!(f, "invalid element: {m}"),
            Error::Io(m) => write!(f, "i/o error: {m}"),
            Error::Cancelled => write!(f, "cancelled by the progress callback"),
        }
    }
}

impl std::error::Error for Error {}

/// Result alias used across the crate.
pub type Result<T> = std::result::Result<T, Error>;
