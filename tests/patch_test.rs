//! Patch test: a linear displacement prescribed on the whole boundary is
//! reproduced to round-off at every interior node, for p = 1..6, in 2D and 3D,
//! with one and several ILE increments.

mod common;

use hocurve::assembly::LinearElasticKernel;
use hocurve::curve::{add_rate, solve_increments, solve_increments_from, Stepping, Timings};
use hocurve::mapping::ElementCache;
use hocurve::material::LinearElastic;
use hocurve::mesh::{validate_and_orient, HighOrderMesh, LinearMesh, NodeConstraint, Topology};
use hocurve::quadrature::simplex_rule;
use hocurve::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use hocurve::solver::SolverChoice;

/// u(X) = A X + b with a general (non-symmetric) A.
fn linear_field(x: &[f64], dim: usize) -> Vec<f64> {
    let a = [[0.05, -0.02, 0.03], [0.01, 0.04, -0.03], [-0.02, 0.02, 0.06]];
    let b = [0.01, -0.02, 0.015];
    (0..dim).map(|i| b[i] + (0..dim).map(|j| a[i][j] * x[j]).sum::<f64>()).collect()
}

/// The patch problem at order `order`: the straight mesh, the linear field
/// on its boundary nodes, and the ILE kernel.
fn patch_problem(linear: &LinearMesh, order: usize) -> (HighOrderMesh, Vec<f64>, LinearElasticKernel) {
    let (linear, _) = validate_and_orient(linear).unwrap();
    let topo = Topology::new(&linear).unwrap();
    let nodes = NodeSet::new(topo.simplex, order, NodeSpacing::Optimal);
    let mesh = HighOrderMesh::elevate(&linear, &topo, &nodes, NodeSpacing::Optimal).unwrap();
    let dim = mesh.dim();
    let mut ubar = vec![0.0; mesh.coords.len()];
    let mut n_interior = 0;
    for n in 0..mesh.n_nodes() {
        if mesh.constraint[n] != NodeConstraint::Free {
            let u = linear_field(&mesh.coords[n * dim..(n + 1) * dim], dim);
            ubar[n * dim..(n + 1) * dim].copy_from_slice(&u);
        } else {
            n_interior += 1;
        }
    }
    assert!(n_interior > 0, "the patch must have interior nodes");
    let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(topo.simplex, 2 * order));
    let kernel = LinearElasticKernel { cache, material: LinearElastic::try_from_young_poisson(1e5, 0.3).unwrap() };
    (mesh, ubar, kernel)
}

fn run_patch(linear: &LinearMesh, order: usize, increments: usize) -> f64 {
    let (mut mesh, ubar, kernel) = patch_problem(linear, order);
    let dim = mesh.dim();
    let straight = mesh.coords.clone();
    let mut t = Timings::default();
    let stepping = Stepping::new(increments);
    solve_increments(&mut mesh, &kernel, &ubar, stepping, &mut t, &mut |_, _, _| Ok(())).unwrap();
    let mut err: f64 = 0.0;
    for n in 0..mesh.n_nodes() {
        let x0 = &straight[n * dim..(n + 1) * dim];
        let u = linear_field(x0, dim);
        for d in 0..dim {
            err = err.max((mesh.coords[n * dim + d] - (x0[d] + u[d])).abs());
        }
    }
    err
}

#[test]
fn linear_displacement_is_reproduced_in_2d_for_p_1_to_6() {
    let mesh = common::square_mesh(3);
    for p in 1..=6 {
        for inc in [1, 3] {
            let e = run_patch(&mesh, p, inc);
            println!("2D p={p} increments={inc}: max nodal error {e:.2e}");
            assert!(e < 1e-11, "2D p={p} increments={inc}: error {e:e}");
        }
    }
}

#[test]
fn linear_displacement_is_reproduced_in_3d_for_p_1_to_6() {
    for p in 1..=6 {
        // p = 1 needs interior vertices; higher orders have interior nodes anyway.
        let mesh = common::cube_mesh(if p == 1 { 3 } else { 2 });
        let inc = if p <= 3 { 2 } else { 1 };
        let e = run_patch(&mesh, p, inc);
        println!("3D p={p} increments={inc}: max nodal error {e:.2e}");
        assert!(e < 1e-11, "3D p={p}: error {e:e}");
    }
}

/// ILE's solve is linear in the load: a run started from the first rate of
/// another (per unit load) scaled to its load takes no PCG iteration and
/// moves every node by that scaled displacement, to round-off.
#[test]
fn a_solve_started_from_an_earlier_rate_takes_no_iteration_and_scales_its_displacement() {
    let (mesh, ubar, kernel) = patch_problem(&common::cube_mesh(2), 3);
    let stepping = Stepping { solver: SolverChoice::Iterative, ..Stepping::new(1) };
    let mut t = Timings::default();
    let mut first = mesh.clone();
    let r = solve_increments(&mut first, &kernel, &ubar, stepping.clone(), &mut t, &mut |_, _, _| Ok(())).unwrap();
    assert!(r.solves.iterations[0] > 0, "{:?}", r.solves.iterations);
    let rate = r.first_rate.expect("the first increment's rate");
    assert_eq!(rate.len(), r.n_free);
    for scale in [0.5, 0.3] {
        let part: Vec<f64> = ubar.iter().map(|u| scale * u).collect();
        let start: Vec<f64> = rate.iter().map(|v| scale * v).collect();
        let mut second = mesh.clone();
        let s = solve_increments_from(
            &mut second,
            &kernel,
            &part,
            stepping.clone(),
            Some(&start),
            &mut t,
            &mut |_, _, _| Ok(()),
        )
        .unwrap();
        assert_eq!(s.solves.iterations, [0], "scale {scale}");
        let worst = (0..mesh.coords.len())
            .map(|i| ((second.coords[i] - mesh.coords[i]) - scale * (first.coords[i] - mesh.coords[i])).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-14, "scale {scale}: {worst:e}");
        // From zero, the same system takes iterations.
        let mut cold = mesh.clone();
        let c = solve_increments(&mut cold, &kernel, &part, stepping.clone(), &mut t, &mut |_, _, _| Ok(())).unwrap();
        assert!(c.solves.iterations[0] > 0);
    }
}

/// The linear solve that the optimisation stage's hand-over needs (the rest
/// of the load on the straight mesh) is the first increment's rate scaled:
/// `add_rate` gives what solving again gives, with the cell interiors
/// condensed or not, and refuses a rate of another length.
#[test]
fn adding_the_scaled_rate_gives_the_mesh_of_solving_again() {
    let (mesh, ubar, kernel) = patch_problem(&common::cube_mesh(2), 3);
    for condense in [true, false] {
        let stepping = Stepping { solver: SolverChoice::Direct, condense, ..Stepping::new(1) };
        let mut t = Timings::default();
        let mut first = mesh.clone();
        let r = solve_increments(&mut first, &kernel, &ubar, stepping.clone(), &mut t, &mut |_, _, _| Ok(())).unwrap();
        let rate = r.first_rate.expect("the first increment's rate");
        for scale in [1.0, 0.375] {
            let part: Vec<f64> = ubar.iter().map(|u| scale * u).collect();
            let mut solved = mesh.clone();
            solve_increments(&mut solved, &kernel, &part, stepping.clone(), &mut t, &mut |_, _, _| Ok(())).unwrap();
            let mut added = mesh.clone();
            assert!(add_rate(&mut added, &ubar, &rate, scale, condense));
            let moved = (0..mesh.coords.len()).map(|i| (solved.coords[i] - mesh.coords[i]).abs()).fold(0.0, f64::max);
            let worst = (0..mesh.coords.len()).map(|i| (added.coords[i] - solved.coords[i]).abs()).fold(0.0, f64::max);
            assert!(moved > 1e-3, "condense {condense}, scale {scale}: the load moves nothing ({moved:e})");
            assert!(worst < 1e-12 * moved, "condense {condense}, scale {scale}: {worst:e} of {moved:e}");
        }
        let mut unchanged = mesh.clone();
        assert!(!add_rate(&mut unchanged, &ubar, &rate[1..], 1.0, condense));
        assert_eq!(unchanged.coords, mesh.coords);
    }
}
