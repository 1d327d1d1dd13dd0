//! p-convergence on curved meshes (the paper's Figs. 25 and 33).
//!
//! On a fixed coarse mesh of an annulus (2D) and a spherical shell (3D), both
//! boundaries curved, we measure for p = 1..6:
//! - the L2 error of interpolating a smooth f at the curved mesh's nodes,
//!   integrated over the curved elements, and
//! - the error of the domain's area/volume (the boundary approximation).
//!
//! Both must fall exponentially with p. A control shows that the straight-
//! sided order-p mesh does not converge in area: the curving is what matters.

use hocurve::cases::{self, Case};
use hocurve::curve::{curve, CurveOptions, CurvedMesh};
use hocurve::linalg;
use hocurve::mapping::{self, ElementCache};
use hocurve::quadrature::simplex_rule;
use hocurve::reference::{LagrangeBasis, NodeSet};
use std::f64::consts::PI;

fn f(x: [f64; 3]) -> f64 {
    (2.0 * x[0]).sin() * (1.5 * x[1]).cos() * (0.5 * x[2]).exp()
}

/// (L2 interpolation error, measure) over the mesh given by `coords`.
fn interpolation_error(c: &CurvedMesh, coords: &[f64]) -> (f64, f64) {
    let m = &c.mesh;
    let dim = m.dim();
    let nodes = NodeSet::new(m.simplex, m.order, m.spacing);
    let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(m.simplex, 2 * m.order + 6));
    let n = cache.n_basis;
    let (mut err2, mut measure) = (0.0, 0.0);
    for cell in m.cells.chunks_exact(n) {
        let xe: Vec<f64> = cell.iter().flat_map(|&g| coords[g * dim..(g + 1) * dim].to_vec()).collect();
        let fe: Vec<f64> = cell
            .iter()
            .map(|&g| {
                let mut x = [0.0; 3];
                x[..dim].copy_from_slice(&coords[g * dim..(g + 1) * dim]);
                f(x)
            })
            .collect();
        for q in 0..cache.n_points() {
            let vals = &cache.values[q * n..(q + 1) * n];
            let j = linalg::det(dim, &mapping::jacobian(dim, &xe, cache.grads_at(q)));
            let mut x = [0.0; 3];
            for d in 0..dim {
                x[d] = (0..n).map(|a| vals[a] * xe[a * dim + d]).sum();
            }
            let fh: f64 = (0..n).map(|a| vals[a] * fe[a]).sum();
            let w = cache.weights[q] * j;
            err2 += w * (f(x) - fh).powi(2);
            measure += w;
        }
    }
    (err2.sqrt(), measure)
}

fn study(case: &Case, exact_measure: f64) -> Vec<(f64, f64, f64)> {
    let mut rows = Vec::new();
    for p in 1..=6 {
        let opts = CurveOptions { order: p, increments: 2, ..Default::default() };
        let c = curve(&case.mesh, &case.projector, &opts, &mut |_| true).unwrap();
        assert_eq!(c.report.quality.n_invalid, 0);
        let (e, meas) = interpolation_error(&c, &c.mesh.coords);
        let (_, straight_meas) = interpolation_error(&c, &c.straight);
        let row = (e, (meas - exact_measure).abs(), (straight_meas - exact_measure).abs());
        println!(
            "{} p={p}: nodes={:6} L2 interpolation error={:.3e} measure error={:.3e} (straight-sided: {:.3e})",
            case.name, c.report.nodes, row.0, row.1, row.2
        );
        rows.push(row);
    }
    rows
}

fn assert_exponential(name: &str, errors: &[f64], min_rate: f64) {
    // Least-squares slope of ln(error) against p must be below −min_rate,
    // and the error must fall at every step.
    let n = errors.len() as f64;
    let ps: Vec<f64> = (1..=errors.len()).map(|p| p as f64).collect();
    let ls: Vec<f64> = errors.iter().map(|e| e.ln()).collect();
    let (mp, ml) = (ps.iter().sum::<f64>() / n, ls.iter().sum::<f64>() / n);
    let slope = ps.iter().zip(&ls).map(|(p, l)| (p - mp) * (l - ml)).sum::<f64>()
        / ps.iter().map(|p| (p - mp).powi(2)).sum::<f64>();
    println!("{name}: ln(error) slope per order = {slope:.2}");
    assert!(slope < -min_rate, "{name}: slope {slope} not exponential enough");
    for w in errors.windows(2) {
        assert!(w[1] < w[0], "{name}: error does not fall: {errors:?}");
    }
}

#[test]
fn annulus_interpolation_and_area_errors_fall_exponentially_with_p() {
    let case = cases::annulus_2d(0.5, 1.0, 12, 2);
    let rows = study(&case, PI * (1.0 - 0.25));
    assert_exponential("2D interpolation", &rows.iter().map(|r| r.0).collect::<Vec<_>>(), 1.0);
    assert_exponential("2D area", &rows.iter().map(|r| r.1).collect::<Vec<_>>(), 1.0);
    // Control: without curving the area error stays at the polygon's.
    let straight: Vec<f64> = rows.iter().map(|r| r.2).collect();
    assert!(straight[5] > 0.5 * straight[0], "straight-sided area error should not converge: {straight:?}");
}

#[test]
fn spherical_shell_interpolation_and_volume_errors_fall_exponentially_with_p() {
    let case = cases::spherical_shell_3d(0.5, 1.0, 2, 1);
    let rows = study(&case, 4.0 / 3.0 * PI * (1.0 - 0.125));
    assert_exponential("3D interpolation", &rows.iter().map(|r| r.0).collect::<Vec<_>>(), 0.8);
    assert_exponential("3D volume", &rows.iter().map(|r| r.1).collect::<Vec<_>>(), 0.8);
    let straight: Vec<f64> = rows.iter().map(|r| r.2).collect();
    assert!(straight[5] > 0.5 * straight[0], "straight-sided volume error should not converge: {straight:?}");
}
