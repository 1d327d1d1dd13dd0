//! How the elastic stage runs when its system is split over processes.
//!
//! The library's core does no communication: a distributed run (the `mpi`
//! feature's [`crate::distributed`]) plugs in here. Its first process runs
//! the whole pipeline and hands each elastic stage to an
//! [`ElasticBackend`]; every process then runs the ordinary increment loop
//! on its own cells, with the linear solves shared through PETSc and every
//! decision that must be the same everywhere (step back, stop, fail) taken
//! through a [`Collective`].

use std::fmt;
use std::sync::Arc;

use super::stepping::{IncrementsReport, Stepping};
use super::{Stage, Timings};
use crate::material::LinearElastic;
use crate::mesh::HighOrderMesh;
use crate::Result;

/// Runs an elastic stage of linear elastic increments somewhere else, for
/// the whole mesh; what [`super::solve_increments_from`] does, with the
/// same result to the solver's tolerance.
pub trait ElasticBackend: Send + Sync {
    #[allow(clippy::too_many_arguments)]
    fn solve_increments(
        &self,
        mesh: &mut HighOrderMesh,
        material: LinearElastic,
        ubar: &[f64],
        stepping: &Stepping,
        rate: Option<&[f64]>,
        timings: &mut Timings,
        tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
    ) -> Result<IncrementsReport>;
}

/// The decisions every process of a distributed elastic stage takes alike.
pub trait Collective: Send + Sync {
    /// Of the processes' `(key, message)`, the one with the smallest key
    /// (the lowest process on a tie), on every process; None when no
    /// process has one.
    fn first(&self, local: Option<(u64, String)>) -> Option<(u64, String)>;
    /// The whole mesh's index of this process's cell `local`.
    fn global_cell(&self, local: usize) -> usize;
}

/// Where the elastic stage runs.
#[derive(Clone, Default)]
pub enum Parallel {
    /// In this process, on the whole mesh.
    #[default]
    Serial,
    /// Handed to a backend (on the first process of a distributed run).
    Lead(Arc<dyn ElasticBackend>),
    /// This process's cells of a distributed stage.
    Part(Arc<dyn Collective>),
}

impl fmt::Debug for Parallel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Parallel::Serial => "Serial",
            Parallel::Lead(_) => "Lead(..)",
            Parallel::Part(_) => "Part(..)",
        })
    }
}

impl PartialEq for Parallel {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Parallel::Serial, Parallel::Serial) => true,
            (Parallel::Lead(a), Parallel::Lead(b)) => Arc::ptr_eq(a, b),
            (Parallel::Part(a), Parallel::Part(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

impl Parallel {
    /// The collective of a process's part, if this is one.
    pub(crate) fn part(&self) -> Option<&dyn Collective> {
        match self {
            Parallel::Part(c) => Some(c.as_ref()),
            _ => None,
        }
    }
}

/// Whether any process has `local` true (only this one's when serial).
pub(crate) fn any(collective: Option<&dyn Collective>, local: bool) -> bool {
    match collective {
        Some(c) => c.first(local.then(|| (0, String::new()))).is_some(),
        None => local,
    }
}

/// Of the processes' failing cells `(local cell, message about it)`, the
/// one with the smallest index in the whole mesh, renumbered (messages
/// name the cell as "cell N"); serially, `local` itself.
pub(crate) fn first_cell(
    collective: Option<&dyn Collective>,
    local: Option<(usize, String)>,
) -> Option<(usize, String)> {
    let Some(c) = collective else { return local };
    let keyed = local.map(|(cell, message)| {
        let g = c.global_cell(cell);
        (g as u64, message.replace(&format!("cell {cell}"), &format!("cell {g}")))
    });
    c.first(keyed).map(|(g, m)| (g as usize, m))
}
