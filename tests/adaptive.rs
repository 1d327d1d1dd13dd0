//! Adaptive load stepping: an increment that inverts
//! a cell or whose Newton iteration fails is undone and halved.

use hocurve::cases::{self, Case};
use hocurve::curve::{curve, CurveOptions, CurvedMesh, Formulation, StepBackReason};
use hocurve::material::MaterialModel;
use hocurve::optimize::OptimizeOptions;
use hocurve::session::Session;
use hocurve::{Error, Result};

fn run(case: &Case, opts: &CurveOptions) -> Result<CurvedMesh> {
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
    curve(&mesh, &case.projector, opts, &mut |_| true)
}

fn describe(c: &CurvedMesh) -> String {
    let r = &c.report;
    let backs: Vec<String> = r
        .step_backs
        .iter()
        .map(|b| format!("{} (step {}, {}, cell {:?})", b.load, b.step, b.reason.name(), b.cell))
        .collect();
    format!(
        "{} increments taken of {} requested, loads {:?}; stepped back at [{}]; min Q3 {:.4}, certified min Q3 {:.4}, \
         invalid {}, certified invalid {}, uncertain {}",
        r.increments_taken(),
        r.increments,
        r.load_fractions,
        backs.join(", "),
        r.quality.min_q3,
        r.quality.certified_min_q3,
        r.quality.n_invalid,
        r.quality.n_certified_invalid,
        r.quality.n_uncertain
    )
}

/// No optimisation stage: these tests look at the elastic stage alone.
fn off() -> OptimizeOptions {
    OptimizeOptions { enabled: false, ..Default::default() }
}

/// The cubed sphere with one division per face and two layers, p = 4: plain
/// ILE in 1 or 2 increments leaves 12 inverted tets; adaptive stepping from
/// the same request comes out valid, certified.
#[test]
fn coarse_sphere_at_p4_comes_out_certified_valid_with_adaptive_stepping() {
    let case = cases::sphere_in_box_3d(1, 2);
    for increments in [1, 2] {
        let base = CurveOptions { order: 4, increments, poisson: 0.45, ..Default::default() };
        // The elastic stage alone: the optimisation stage would repair it.
        let plain = run(&case, &CurveOptions { adaptive: Some(false), optimize: off(), ..base.clone() }).unwrap();
        println!("plain ILE, {increments} increment(s): {}", describe(&plain));
        assert!(plain.report.quality.n_certified_invalid > 0, "the case must defeat plain ILE");
        assert!(plain.report.step_backs.is_empty() && plain.report.increments_taken() == increments);

        let adaptive = run(&case, &CurveOptions { optimize: off(), ..base.clone() }).unwrap();
        println!("adaptive ILE, {increments} increment(s) requested: {}", describe(&adaptive));
        let r = &adaptive.report;
        assert!(r.adaptive, "on by default for ILE");
        assert_eq!(r.quality.n_certified_invalid, 0);
        assert_eq!(r.quality.n_uncertain, 0);
        assert_eq!(r.quality.n_invalid, 0);
        assert!(r.quality.certified_min_q3 > 0.0);
        assert!(!r.step_backs.is_empty());
        assert!(r.increments_taken() > increments);
        assert_eq!(*r.load_fractions.last().unwrap(), 1.0);
        assert!(r.load_fractions.windows(2).all(|w| w[0] < w[1]));
        assert!(r.step_backs.iter().all(|b| b.reason == StepBackReason::CertifiedInvalid && b.cell.is_some()));

        // With the optimisation stage (the default), a cell that rejects the
        // whole load in one step hands the run over to it at once (cell 0
        // here, which also rejects the step from 0.5: see the test below).
        let handed = run(&case, &base).unwrap();
        println!("adaptive ILE + optimisation, {increments} increment(s): {}", describe(&handed));
        let h = &handed.report;
        assert_eq!((h.quality.n_certified_invalid, h.quality.n_uncertain), (0, 0));
        assert!(h.quality.min_q3 > r.quality.min_q3, "{} vs {}", h.quality.min_q3, r.quality.min_q3);
        if increments == 1 {
            let stop = h.elastic_stop.as_ref().expect("the elastic stage stopped at the first rejection");
            assert_eq!((stop.load, stop.cell, h.solves.len()), (0.0, Some(0), 1));
        }
    }
}

#[test]
fn linear_has_adaptive_stepping_off_by_default() {
    let case = cases::sphere_in_box_3d(1, 2);
    let opts = CurveOptions { order: 4, formulation: Formulation::Linear, optimize: off(), ..Default::default() };
    assert!(!opts.adaptive_enabled());
    let c = run(&case, &opts).unwrap();
    println!("LINEAR: {}", describe(&c));
    assert!(!c.report.adaptive && c.report.increments_taken() == 1);
    assert!(c.report.quality.n_certified_invalid > 0);
    // Asked for, it splits LINEAR's single solve into increments.
    let c = run(&case, &CurveOptions { adaptive: Some(true), ..opts }).unwrap();
    println!("LINEAR, adaptive on: {}", describe(&c));
    assert_eq!(c.report.quality.n_certified_invalid, 0);
}

/// NONLINEAR on a coarse annulus at p = 4 with at most 2 Newton iterations:
/// the whole load in one step leaves ‖R‖/‖R₀‖ = 5e-4.
fn newton_case(tolerance: f64) -> (Case, CurveOptions) {
    let case = cases::annulus_2d(0.5, 1.0, 6, 1);
    let opts = CurveOptions {
        order: 4,
        increments: 1,
        formulation: Formulation::Nonlinear,
        material: MaterialModel::NeoHookean,
        max_iterations: 2,
        tolerance,
        ..Default::default()
    };
    (case, opts)
}

/// Newton–Raphson limited to 2 iterations cannot reach 1e-4 with the whole
/// load in one step; halved steps do.
#[test]
fn a_newton_failure_steps_back_and_halves_the_increment() {
    let (case, opts) = newton_case(1e-4);
    let e = run(&case, &CurveOptions { adaptive: Some(false), ..opts.clone() }).unwrap_err();
    println!("adaptive off: {e}");
    assert!(
        matches!(&e, Error::Solver { message: m, .. } if m.contains("did not converge") && !m.contains("limit")),
        "{e}"
    );
    let c = run(&case, &opts).unwrap();
    println!("adaptive on: {}", describe(&c));
    let r = &c.report;
    assert_eq!(r.step_backs.len(), 1);
    assert_eq!(r.load_fractions, [0.5, 1.0]);
    assert_eq!(r.step_backs[0].reason, StepBackReason::NewtonFailed);
    assert_eq!((r.step_backs[0].load, r.step_backs[0].step), (0.0, 1.0));
    assert_eq!(*r.load_fractions.last().unwrap(), 1.0);
    assert!(r.newton_history.iter().filter(|h| *h.last().unwrap() < opts.tolerance).count() == r.increments_taken());
    assert_eq!(r.quality.n_invalid, 0);
}

/// At the split limit the run fails with the clear error and the session's
/// mesh is exactly as before the run.
#[test]
fn the_split_limit_fails_clearly_and_leaves_the_mesh_unchanged() {
    // 1e-5 needs steps of 1/8 of the load.
    let (case, opts) = newton_case(1e-5);
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
    let mut s = Session::try_new(mesh).unwrap();
    s.set_order(opts.order, opts.spacing).unwrap();
    s.set_material(opts.material, opts.young, opts.poisson).unwrap();
    s.set_formulation(opts.formulation);
    s.set_newton(opts.tolerance, opts.max_iterations).unwrap();
    s.set_projector(Some(Box::new(case.projector.clone())));
    // One good run, then one that cannot succeed.
    s.run(4).unwrap();
    let before = s.mesh().coords.clone();
    let report_before = s.report().unwrap().load_fractions.clone();
    s.set_adaptive(Some(true), 0).unwrap();
    let e = s.run(1).unwrap_err();
    println!("max_splits 0: {e}");
    assert!(
        matches!(&e, Error::Solver { message: m, .. } if m.contains("did not converge") && m.contains("limit")),
        "{e}"
    );
    assert_eq!(s.mesh().coords, before, "the mesh must be unchanged");
    assert_eq!(s.report().unwrap().load_fractions, report_before);
    s.set_adaptive(Some(true), 1).unwrap();
    let e = s.run(1).unwrap_err();
    println!("max_splits 1: {e}");
    assert!(matches!(&e, Error::Solver { message: m, .. } if m.contains("halving the step 1 times")), "{e}");
    assert_eq!(s.mesh().coords, before);
    assert!(s.set_adaptive(None, 31).is_err());
}

/// The case above in one increment, with the iterative solver. The elastic
/// stage alone: the halved retry from load 0 is a linear solve with the
/// first one's matrix and a scaled right-hand side, so it starts from its
/// solution scaled and needs no iteration, and cell 0 rejects the second
/// half too. With the optimisation, the run is handed over at the first
/// rejection: the rest of the load on the straight mesh, the whole load, is
/// the first solution, and is not solved again (that both give the scaled
/// solution: tests/patch_test.rs); the mesh handed over is the same.
#[test]
fn retried_and_finishing_solves_start_from_the_first_solution_scaled() {
    use hocurve::solver::SolverChoice;
    let case = cases::sphere_in_box_3d(1, 2);
    let base =
        CurveOptions { order: 4, increments: 1, poisson: 0.45, solver: SolverChoice::Iterative, ..Default::default() };
    let alone = run(&case, &CurveOptions { optimize: off(), ..base.clone() }).unwrap();
    let r = &alone.report;
    println!("elastic stage alone: {}; iterations {:?}", describe(&alone), r.solves.iterations);
    let it = &r.solves.iterations;
    // 1 from 0 (rejected), 0.5 from 0 (its half), 0.5 from 0.5 (rejected by cell 0 again), ...
    assert!(it.len() > 3 && it[0] > 0 && it[1] == 0 && it[2] > 0, "{it:?}");
    assert_eq!(
        r.step_backs[..2].iter().map(|b| (b.load, b.cell)).collect::<Vec<_>>(),
        [(0.0, Some(0)), (0.5, Some(0))]
    );

    let handed = run(&case, &base).unwrap();
    let h = &handed.report;
    println!("with the optimisation: {}; iterations {:?}", describe(&handed), h.solves.iterations);
    assert_eq!(h.elastic_stop.as_ref().map(|s| s.load), Some(0.0));
    assert_eq!(h.solves.iterations, it[..1]);
    assert!(h.solves.fallback.iter().all(|f| f.is_none()));
    assert_eq!(h.quality.n_certified_invalid, 0);
}
