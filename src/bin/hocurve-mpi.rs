//! `hocurve-mpi`: the command line of `hocurve`, built with the `mpi`
//! feature, whose `curve` spreads its elastic stages over MPI processes
//! (`mpirun -np N hocurve-mpi curve IN.msh ...`; see `hocurve/mpi_run.rs`).

#[path = "hocurve/main.rs"]
mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
