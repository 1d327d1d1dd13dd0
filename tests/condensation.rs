//! Static condensation of the cell-interior nodes: every solver path
//! and formulation gives the same mesh with and without it, and the systems
//! lose exactly the interior unknowns.

mod common;

use hocurve::cases::{self, Case};
use hocurve::curve::{curve, CurveOptions, CurvedMesh, Formulation};
use hocurve::material::MaterialModel;
use hocurve::optimize::OptimizeOptions;
use hocurve::solver::SolverChoice;

fn run(case: &Case, order: usize, formulation: Formulation, solver: SolverChoice, condense: bool) -> CurvedMesh {
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
    let material =
        if formulation == Formulation::Ile { MaterialModel::LinearElastic } else { MaterialModel::NeoHookean };
    // The elastic stage alone: the optimisation after it would amplify
    // round-off differences between the solver paths.
    let optimize = OptimizeOptions { enabled: false, ..Default::default() };
    let opts =
        CurveOptions { order, increments: 2, formulation, material, solver, condense, optimize, ..Default::default() };
    curve(&mesh, &case.projector, &opts, &mut |_| true).unwrap()
}

/// Largest node distance between two curved meshes, relative to the bounding box.
fn difference(a: &CurvedMesh, b: &CurvedMesh) -> f64 {
    let extent = a.mesh.coords.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.mesh.coords.iter().zip(&b.mesh.coords).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / extent
}

/// Cells with interior nodes: one per tet at p = 4 (3 unknowns), one per triangle at p = 3 (2).
fn interior_unknowns(m: &CurvedMesh, per_cell: usize) -> usize {
    m.mesh.n_cells() * per_cell
}

#[test]
fn condensed_and_full_direct_solves_give_the_same_mesh_in_3d() {
    let case = cases::sphere_in_box_3d(2, 1);
    for (p, formulation, per_cell) in
        [(4, Formulation::Ile, 3), (5, Formulation::Ile, 12), (4, Formulation::Iil, 3), (4, Formulation::Nonlinear, 3)]
    {
        let full = run(&case, p, formulation, SolverChoice::Direct, false);
        let cond = run(&case, p, formulation, SolverChoice::Direct, true);
        let (rf, rc) = (&full.report, &cond.report);
        assert_eq!(rf.system_dofs, rf.dofs, "no condensation asked");
        assert_eq!(rc.dofs, rf.dofs);
        assert_eq!(rc.system_dofs, rf.dofs - interior_unknowns(&cond, per_cell), "p={p}");
        let d = difference(&full, &cond);
        println!("p={p} {formulation:?}: {} -> {} unknowns, nodes differ by {d:.1e}", rf.dofs, rc.system_dofs);
        assert!(d < 1e-10, "p={p} {formulation:?}: nodes differ by {d:e}");
        assert_eq!(rf.quality.n_certified_invalid, rc.quality.n_certified_invalid);
    }
}

#[test]
fn condensed_and_full_solves_give_the_same_mesh_in_2d() {
    let case = cases::cylinder_channel_2d(16, 4, 10.0);
    for (p, per_cell) in [(3, 2), (5, 12)] {
        let full = run(&case, p, Formulation::Ile, SolverChoice::Direct, false);
        let cond = run(&case, p, Formulation::Ile, SolverChoice::Direct, true);
        assert_eq!(cond.report.system_dofs, full.report.dofs - interior_unknowns(&cond, per_cell));
        let d = difference(&full, &cond);
        println!("2D p={p}: nodes differ by {d:.1e}");
        assert!(d < 1e-10, "2D p={p}: nodes differ by {d:e}");
    }
}

#[test]
fn the_iterative_solver_on_the_condensed_system_matches_the_direct_full_one() {
    let case = cases::sphere_in_box_3d(2, 3);
    for p in [4, 5, 6] {
        let full = run(&case, p, Formulation::Ile, SolverChoice::Direct, false);
        let cond = run(&case, p, Formulation::Ile, SolverChoice::Iterative, true);
        assert_eq!(cond.report.solves.solver, "pcg-pmg");
        // PCG itself converged (no direct fallback, which reports 0 iterations).
        assert!(cond.report.solves.iterations.iter().all(|&n| n > 0 && n < 60), "{:?}", cond.report.solves.iterations);
        let d = difference(&full, &cond);
        println!("p={p}: PCG iterations {:?}, nodes differ by {d:.1e}", cond.report.solves.iterations);
        // PCG stops at ‖r‖ ≤ 1e-5 ‖b‖: a few 1e-6 of the mesh size.
        assert!(d < 1e-5, "p={p}: nodes differ by {d:e}");
    }
}

#[test]
fn orders_without_interior_nodes_are_left_whole() {
    let case = cases::sphere_in_box_3d(2, 3);
    let cond = run(&case, 3, Formulation::Ile, SolverChoice::Direct, true);
    assert_eq!(cond.report.system_dofs, cond.report.dofs);
}

/// The Newton residual is measured on every free dof whether or not the
/// interior ones are condensed out of the system.
#[test]
fn the_residual_norm_counts_the_condensed_unknowns() {
    let case = cases::sphere_in_box_3d(2, 1);
    let norms: Vec<(f64, f64, usize)> = [false, true]
        .into_iter()
        .map(|condensed| {
            let s = common::straight_system(&case, 4, condensed, true);
            let a = &s.system;
            (a.rhs_norm(), a.rhs().iter().map(|v| v * v).sum::<f64>().sqrt(), s.pattern().n)
        })
        .collect();
    let ((full, full_rhs, nf), (cond, cond_rhs, nc)) = (norms[0], norms[1]);
    println!("‖b‖ full {full:.6e} ({nf} unknowns), condensed {cond:.6e} ({nc}); ‖condensed rhs‖ {cond_rhs:.6e}");
    assert!(nc < nf);
    assert!((full - full_rhs).abs() <= 1e-14 * full, "without condensation the norm is ‖rhs‖");
    assert!((full - cond).abs() <= 1e-12 * full, "{full} vs {cond}");
    assert!((cond - cond_rhs).abs() > 1e-6 * full, "the condensed rhs alone would measure another norm");
}
