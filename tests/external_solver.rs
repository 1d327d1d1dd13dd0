//! The external linear-solver hook: the host sees each reduced
//! system as a full symmetric CSR matrix, and a host CG gives the mesh the
//! direct solver gives.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use hocurve::assembly::DofMap;
use hocurve::cases::{self, Case};
use hocurve::curve::{curve, CurveOptions, CurvedMesh};
use hocurve::mesh::{validate_and_orient, HighOrderMesh, Topology};
use hocurve::reference::{NodeSet, NodeSpacing};
use hocurve::session::Session;
use hocurve::solver::{CsrView, ExternalAdapter, ExternalSolver, LinearSolver, LowerCscView, SolverChoice};
use hocurve::Error;

fn sphere_case() -> Case {
    let mut case = cases::sphere_in_box_3d(2, 1);
    let projector = case.projector.clone();
    case.mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    case
}

/// The free-dof pattern of the sphere case at order `p`.
fn sphere_pattern(p: usize) -> hocurve::solver::SymmetricCsc {
    let case = sphere_case();
    let (linear, _) = validate_and_orient(&case.mesh).unwrap();
    let topo = Topology::new(&linear).unwrap();
    let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
    let mesh = HighOrderMesh::elevate(&linear, &topo, &nodes, NodeSpacing::Optimal).unwrap();
    DofMap::new(&mesh).pattern(&mesh)
}

/// Checks the CSR contract: row_ptr monotone from 0, columns sorted, in range, symmetric values.
fn check_csr(a: &CsrView) -> Result<(), String> {
    if a.row_ptr.len() != a.n + 1 || a.row_ptr[0] != 0 || a.row_ptr[a.n] != a.col_idx.len() {
        return Err("bad row_ptr".into());
    }
    let entry = |i: usize, j: usize| {
        let (s, e) = (a.row_ptr[i], a.row_ptr[i + 1]);
        a.col_idx[s..e].binary_search(&j).ok().map(|k| a.values[s + k])
    };
    for i in 0..a.n {
        let row = &a.col_idx[a.row_ptr[i]..a.row_ptr[i + 1]];
        if !row.windows(2).all(|w| w[0] < w[1]) || row.iter().any(|&j| j >= a.n) {
            return Err(format!("row {i} is not sorted or out of range"));
        }
        for (k, &j) in row.iter().enumerate() {
            if entry(j, i) != Some(a.values[a.row_ptr[i] + k]) {
                return Err(format!("entry ({i}, {j}) has no equal mirror"));
            }
        }
    }
    Ok(())
}

/// Jacobi-preconditioned conjugate gradients to ‖r‖ ≤ 1e-13 ‖b‖, from the initial guess in `x`.
fn pcg(a: CsrView, b: &[f64], x: &mut [f64]) -> Result<(), String> {
    let n = a.n;
    let diag: Vec<f64> = (0..n)
        .map(|i| (a.row_ptr[i]..a.row_ptr[i + 1]).find(|&k| a.col_idx[k] == i).map(|k| a.values[k]))
        .collect::<Option<_>>()
        .ok_or("a diagonal entry is missing")?;
    let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(p, q)| p * q).sum::<f64>();
    let ax = a.matvec(x);
    let mut r: Vec<f64> = b.iter().zip(&ax).map(|(b, y)| b - y).collect();
    let mut z: Vec<f64> = r.iter().zip(&diag).map(|(r, d)| r / d).collect();
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let tol = 1e-13 * dot(b, b).sqrt();
    for _ in 0..20 * n {
        if dot(&r, &r).sqrt() <= tol {
            return Ok(());
        }
        let ap = a.matvec(&p);
        let alpha = rz / dot(&p, &ap);
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
            z[i] = r[i] / diag[i];
        }
        let rz_new = dot(&r, &z);
        for i in 0..n {
            p[i] = z[i] + rz_new / rz * p[i];
        }
        rz = rz_new;
    }
    Err("CG did not converge".into())
}

#[test]
fn full_csr_times_a_vector_equals_the_lower_triangle_product() {
    let pattern = sphere_pattern(2);
    let n = pattern.n;
    let values: Vec<f64> = (0..pattern.nnz()).map(|k| ((k * 7919) % 1000) as f64 / 250.0 - 2.0).collect();
    let v: Vec<f64> = (0..n).map(|i| (i as f64 * 0.61).sin()).collect();
    let guess: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let seen = Arc::new(AtomicUsize::new(0));
    let seen2 = seen.clone();
    let expect_guess = guess.clone();
    // Answers A·rhs, so the adapter returns the full CSR product.
    let product = move |a: CsrView, rhs: &[f64], x: &mut [f64]| -> Result<(), String> {
        check_csr(&a)?;
        assert_eq!(x, &expect_guess[..], "x must hold the initial guess");
        seen2.store(a.col_idx.len(), Ordering::SeqCst);
        x.copy_from_slice(&a.matvec(rhs));
        Ok(())
    };
    let mut adapter = ExternalAdapter::new(ExternalSolver::new(product), &pattern);
    let mut x = guess;
    adapter.solve(&pattern, &values, &v, &mut x).unwrap();
    let diagonal = (0..n).filter(|&c| pattern.position(c, c).is_some()).count();
    assert_eq!(seen.load(Ordering::SeqCst), 2 * pattern.nnz() - diagonal);
    let y = pattern.sym_matvec(&values, &v);
    let scale = y.iter().fold(0.0f64, |m, y| m.max(y.abs()));
    for (i, (a, b)) in x.iter().zip(&y).enumerate() {
        assert!((a - b).abs() <= 1e-14 * scale, "row {i}: {a} != {b}");
    }
    assert_eq!(adapter.name(), "external");
}

fn run(order: usize, solver: SolverChoice) -> CurvedMesh {
    let case = sphere_case();
    let mut opts = CurveOptions { order, increments: 3, solver, ..Default::default() };
    // The elastic stage alone: the optimisation keeps or drops a patch's new
    // positions by comparing qualities, so a difference at round-off level
    // in the solves can make it keep another patch.
    opts.optimize.enabled = false;
    curve(&case.mesh, &case.projector, &opts, &mut |_| true).unwrap()
}

#[test]
fn external_cg_gives_the_mesh_of_the_direct_solver() {
    for p in [2, 3] {
        let calls = Arc::new(AtomicUsize::new(0));
        let c = calls.clone();
        let cg = move |a: CsrView, b: &[f64], x: &mut [f64]| {
            c.fetch_add(1, Ordering::SeqCst);
            check_csr(&a)?;
            pcg(a, b, x)
        };
        let ext = run(p, SolverChoice::External(ExternalSolver::new(cg)));
        let direct = run(p, SolverChoice::Direct);
        assert_eq!(calls.load(Ordering::SeqCst), 3, "p={p}: one call per increment");
        assert_eq!(ext.report.solves.solver, "external");
        assert_eq!(ext.report.quality.n_invalid, 0);
        let diff = ext.mesh.coords.iter().zip(&direct.mesh.coords).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        // The box is 4 wide.
        println!("p={p}: {} dofs, max |x_cg - x_direct| = {diff:.2e}", ext.report.dofs);
        assert!(diff < 1e-9 * 4.0, "p={p}: nodes differ by {diff:e}");
    }
}

#[test]
fn host_errors_and_non_finite_solutions_fail_the_run_and_change_nothing() {
    let case = sphere_case();
    let mut s = Session::try_new(case.mesh.clone()).unwrap();
    s.set_projector(Some(Box::new(case.projector.clone())));
    s.set_order(2, NodeSpacing::Optimal).unwrap();
    s.run(2).unwrap();
    let before = s.mesh().coords.clone();
    let failing = |_: CsrView, _: &[f64], _: &mut [f64]| -> Result<(), String> { Err("status 7".into()) };
    let nan = |_: CsrView, _: &[f64], x: &mut [f64]| -> Result<(), String> {
        x[0] = f64::NAN;
        Ok(())
    };
    for (solver, expect) in [(ExternalSolver::new(failing), "status 7"), (ExternalSolver::new(nan), "non-finite")] {
        s.set_linear_solver(Some(solver));
        let e = s.run(2).unwrap_err();
        assert!(matches!(e, Error::Solver { .. }), "{e}");
        let m = e.to_string();
        assert!(m.contains("external linear solver") && m.contains(expect), "{m}");
        assert_eq!(before, s.mesh().coords, "{m}: mesh changed");
    }
    // None restores the built-in solver.
    s.set_linear_solver(None);
    s.run(2).unwrap();
    assert_eq!(s.report().unwrap().solves.solver, "direct");
    assert_eq!(before, s.mesh().coords);
}

/// A host that takes the lower triangle: the full CSR is never built, it is
/// handed the library's own arrays, and the iterations it counts reach the
/// report.
struct LowerHost {
    calls: Arc<AtomicUsize>,
}

impl hocurve::solver::SystemSolver for LowerHost {
    fn solve(&self, _: CsrView<'_>, _: &[f64], _: &mut [f64]) -> Result<(), String> {
        Err("not called: the host takes the lower triangle".into())
    }
    fn takes_lower_triangle(&self) -> bool {
        true
    }
    fn solve_lower(&self, a: LowerCscView<'_>, rhs: &[f64], x: &mut [f64]) -> Result<Option<usize>, String> {
        self.calls.fetch_add(1, Ordering::SeqCst);
        // Mirror it into a full CSR (the check of the layout) and solve by CG.
        let lower = hocurve::solver::SymmetricCsc { n: a.n, col_ptr: a.col_ptr.to_vec(), row_idx: a.row_idx.to_vec() };
        let full = hocurve::solver::FullCsrPattern::from_lower_csc(&lower);
        let mut values = vec![0.0; full.col_idx.len()];
        full.values_into(a.values, &mut values);
        let csr = CsrView { n: a.n, row_ptr: &full.row_ptr, col_idx: &full.col_idx, values: &values };
        check_csr(&csr)?;
        pcg(csr, rhs, x).map(|()| Some(7))
    }
    fn name(&self) -> &'static str {
        "lower-host"
    }
}

#[test]
fn a_host_taking_the_lower_triangle_gives_the_mesh_of_the_direct_solver() {
    let calls = Arc::new(AtomicUsize::new(0));
    let host = LowerHost { calls: calls.clone() };
    let ext = run(2, SolverChoice::External(ExternalSolver::new(host)));
    let direct = run(2, SolverChoice::Direct);
    assert_eq!(calls.load(Ordering::SeqCst), 3, "one call per increment");
    assert_eq!(ext.report.solves.solver, "lower-host");
    assert_eq!(ext.report.solves.iterations, vec![7, 7, 7]);
    let diff = ext.mesh.coords.iter().zip(&direct.mesh.coords).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff < 1e-9 * 4.0, "nodes differ by {diff:e}");
}
