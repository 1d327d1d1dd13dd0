//! Quadrature rules on the reference simplices (see [`crate::reference`]) and
//! on the unit interval, with the 1D Gauss–Jacobi and Gauss–Lobatto–Legendre
//! rules they are built from. Nothing is cached here: callers cache rules.

pub mod simplex_rules;
mod symmetric_data;

pub use crate::jacobi::{gauss_jacobi, gauss_lobatto_legendre, gauss_lobatto_legendre_weights};
pub use simplex_rules::{collapsed_rule, line_rule, simplex_rule};

/// A quadrature rule ∫ f ≈ Σ_q w_q f(x_q) on a reference domain.
///
/// Points have 3 components (unused ones are 0); on a simplex the weights sum
/// to the reference volume (1/2 triangle, 1/6 tetrahedron), on [0, 1] to 1.
#[derive(Debug, Clone)]
pub struct QuadratureRule {
    pub points: Vec<[f64; 3]>,
    pub weights: Vec<f64>,
}

impl QuadratureRule {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.weights.len()
    }
    /// True if the rule has no points.
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }
}
