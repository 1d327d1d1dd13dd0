//! One row of the solver table (docs/performance.md): curve `sphere_in_box_3d(n, n_radial)`
//! at order p with ILE and print unknowns, set-up, solve time, iterations and
//! peak memory.
//!
//! `cargo run --release --example solver_table -- <n> <n_radial> <p> <auto|direct|iterative> [increments]`

mod common;

use hocurve::cases;
use hocurve::curve::{curve, CurveOptions};
use hocurve::solver::SolverChoice;

fn main() -> hocurve::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: &str| a.get(i).cloned().unwrap_or_else(|| d.to_string());
    let n: usize = arg(1, "6").parse().expect("n");
    let nr: usize = arg(2, "4").parse().expect("n_radial");
    let p: usize = arg(3, "4").parse().expect("p");
    let solver = SolverChoice::parse(&arg(4, "iterative"))?;
    let increments: usize = arg(5, "1").parse().expect("increments");
    let case = cases::sphere_in_box_3d(n, nr);
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|dim, tag| case.projector.get(dim, tag).is_some());
    let opts = CurveOptions { order: p, increments, solver, ..Default::default() };
    let c = curve(&mesh, &case.projector, &opts, &mut |_| true)?;
    let r = &c.report;
    let t = &r.timings;
    println!(
        "n={n} nr={nr} p={p} solver={} inc={increments} dofs={} setup={:.2}s assembly={:.2}s solve={:.2}s total={:.2}s \
         iterations={:?} min_q3={:.6} peak_rss={:.0}MB",
        r.solves.solver,
        r.dofs,
        t.setup,
        t.assembly,
        t.solve,
        t.total,
        r.solves.iterations,
        r.quality.min_q3,
        common::peak_rss_mb()
    );
    Ok(())
}
