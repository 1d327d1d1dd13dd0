//! `hocurve-mpi curve ...`: `hocurve curve` with its elastic stages spread
//! over the processes of an MPI run (`mpirun -np N hocurve-mpi curve ...`).
//! Rank 0 reads the mesh, runs the pipeline and writes the outputs; the
//! other ranks take part in each elastic stage ([`hocurve::distributed`]).

use std::process::ExitCode;
use std::sync::Arc;

use mpi::traits::Communicator;

use hocurve::distributed::{petsc, serve, Lead};
use hocurve::Error;

pub fn main(args: &[String]) -> ExitCode {
    let Some(universe) = mpi::initialize() else {
        eprintln!("hocurve-mpi: MPI was already initialised");
        return ExitCode::FAILURE;
    };
    let world = universe.world();
    if let Err(e) = petsc::initialize() {
        eprintln!("hocurve-mpi: {e}");
        return ExitCode::FAILURE;
    }
    let rank = world.rank();
    let result = if rank != 0 {
        serve(world, None)
    } else {
        let lead = Arc::new(Lead::new(world));
        let result = match args.first().map(String::as_str) {
            Some("curve") => super::cmd_curve(&args[1..], lead.parallel(), Some(lead.size())),
            Some("--version") => {
                println!("hocurve-mpi {}", env!("CARGO_PKG_VERSION"));
                Ok(())
            }
            _ => Err(Error::InvalidInput(
                "usage: mpirun -np N hocurve-mpi curve IN.msh [the options of hocurve curve]".into(),
            )),
        };
        lead.stop();
        result
    };
    petsc::finalize();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error (rank {rank}): {e}");
            ExitCode::FAILURE
        }
    }
}
