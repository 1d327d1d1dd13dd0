//! The formulations of the paper's Table 1: CIL and IIL with one increment give
//! the ILE mesh, Newton–Raphson converges quadratically and approaches CIL with
//! many increments, the transversely isotropic models run and report Q4 and
//! Q5, and settings that cannot work fail with a clear message.

use hocurve::cases::{self, Case};
use hocurve::curve::{curve, CurveOptions, CurvedMesh, Formulation};
use hocurve::material::MaterialModel;
use hocurve::Error;

fn run(
    case: &Case,
    formulation: Formulation,
    material: MaterialModel,
    order: usize,
    increments: usize,
) -> hocurve::Result<CurvedMesh> {
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
    let opts = CurveOptions { order, increments, formulation, material, poisson: 0.3, ..Default::default() };
    curve(&mesh, &case.projector, &opts, &mut |_| true)
}

fn max_diff(a: &CurvedMesh, b: &CurvedMesh) -> f64 {
    a.mesh.coords.iter().zip(&b.mesh.coords).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn cil_and_iil_with_one_increment_equal_ile_with_one_increment() {
    // At the first increment x_n = X: F = I, σ = 0 and c = c_lin for every
    // calibrated model, so all linearised formulations are classical elasticity.
    for case in [cases::annulus_2d(0.5, 1.0, 12, 2), cases::spherical_shell_3d(0.5, 1.0, 2, 1)] {
        let ile = run(&case, Formulation::Ile, MaterialModel::LinearElastic, 3, 1).unwrap();
        for f in [Formulation::Cil, Formulation::Iil] {
            for m in [
                MaterialModel::NeoHookean,
                MaterialModel::MooneyRivlin,
                MaterialModel::NearlyIncompressibleMooneyRivlin,
            ] {
                let other = run(&case, f, m, 3, 1).unwrap();
                let d = max_diff(&ile, &other);
                println!("{} {:?} {:?}: max |x_ILE - x| = {d:.2e}", case.name, f, m);
                assert!(d < 1e-10, "{} {f:?} {m:?}: {d:e}", case.name);
            }
        }
    }
}

#[test]
fn newton_converges_quadratically_and_matches_cil_with_many_increments() {
    let case = cases::annulus_2d(0.5, 1.0, 16, 3);
    let newton = run(&case, Formulation::Nonlinear, MaterialModel::NeoHookean, 3, 1).unwrap();
    let history = &newton.report.newton_history[0];
    println!("Newton relative residuals: {:?}", history.iter().map(|r| format!("{r:.2e}")).collect::<Vec<_>>());
    assert!(*history.last().unwrap() < 1e-5);
    // Quadratic: once in the asymptotic range, each residual is at most a
    // modest multiple of the square of the previous one.
    let tail: Vec<f64> = history.iter().copied().filter(|&r| r < 1e-1).collect();
    assert!(tail.len() >= 2, "too few iterations to judge: {history:?}");
    for w in tail.windows(2) {
        assert!(w[1] <= 10.0 * w[0] * w[0], "not quadratic: {history:?}");
    }
    // CIL with many increments approaches the non-linear solution.
    let mut previous = f64::INFINITY;
    for n in [2, 8, 32] {
        let cil = run(&case, Formulation::Cil, MaterialModel::NeoHookean, 3, n).unwrap();
        let d = max_diff(&cil, &newton);
        println!("CIL with {n:2} increments: max |x_CIL - x_Newton| = {d:.2e}");
        assert!(d < previous, "CIL does not approach Newton as increments grow");
        previous = d;
    }
    // The mesh size is h ~ 0.2 here: 1e-3 is well within the discretisation error.
    assert!(previous < 1e-3, "{previous:e}");
    assert_eq!(newton.report.quality.n_invalid, 0);
}

#[test]
fn hyperelastic_formulations_need_a_hyperelastic_material() {
    let case = cases::annulus_2d(0.5, 1.0, 12, 2);
    for f in [Formulation::Iil, Formulation::Cil, Formulation::Nonlinear] {
        let e = run(&case, f, MaterialModel::LinearElastic, 2, 1).unwrap_err();
        assert!(matches!(&e, Error::InvalidInput(m) if m.contains("hyperelastic")), "{e}");
    }
}

#[test]
fn newton_that_cannot_converge_says_so() {
    let case = cases::annulus_2d(0.5, 1.0, 12, 2);
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
    let opts = CurveOptions {
        order: 3,
        increments: 1,
        formulation: Formulation::Nonlinear,
        material: MaterialModel::NeoHookean,
        max_iterations: 1,
        tolerance: 1e-14,
        ..Default::default()
    };
    let e = curve(&mesh, &case.projector, &opts, &mut |_| true).unwrap_err();
    assert!(matches!(&e, Error::Solver { message: m, .. } if m.contains("did not converge")), "{e}");
}

#[test]
fn transversely_isotropic_models_run_and_report_q4_q5() {
    let case = cases::annulus_2d(0.5, 1.0, 12, 2);
    for (f, m) in [
        (Formulation::Ile, MaterialModel::TransverselyIsotropicLinear),
        (Formulation::Cil, MaterialModel::TransverselyIsotropic),
    ] {
        let c = run(&case, f, m, 3, 4).unwrap();
        let q = &c.report.quality;
        println!("{f:?} {m:?}: min Q3 {:.4} Q4 {:.4} Q5 {:.4}", q.min_q3, q.min_q4, q.min_q5);
        assert_eq!(q.n_invalid, 0);
        assert!(q.min_q4 > 0.0 && q.min_q4 <= 1.0 && q.min_q5 > 0.0 && q.min_q5 <= 1.0);
    }
    let iso = run(&case, Formulation::Ile, MaterialModel::LinearElastic, 3, 4).unwrap();
    assert!(iso.report.quality.min_q4.is_nan(), "Q4 only for TI models");
}
