//! Certified validity: the Bernstein bounds of det J never claim more than the
//! samples show, and they catch an element inverted between samples.

use hocurve::cases;
use hocurve::curve::{curve, CurveOptions, Formulation};
use hocurve::quality::{element_quality, sampling_cache, JacobianBernstein, Verdict};
use hocurve::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};
use hocurve::{linalg, mapping};

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64) / ((1u64 << 53) as f64)
}

/// Nodes of the reference simplex moved by `s` times `dir` (vertices fixed).
fn element(basis: &LagrangeBasis, dir: &[f64], s: f64) -> Vec<f64> {
    let d = basis.simplex().dim();
    basis.nodes().coords.iter().enumerate().flat_map(|(i, x)| (0..d).map(move |c| x[c] + s * dir[i * d + c])).collect()
}

fn random_dir(basis: &LagrangeBasis, seed: &mut u64) -> Vec<f64> {
    let d = basis.simplex().dim();
    (0..basis.len() * d).map(|k| if k < (d + 1) * d { 0.0 } else { 2.0 * lcg(seed) - 1.0 }).collect()
}

/// min det J on a fine equispaced lattice of order `n` (a dense probe, not a proof).
fn fine_min_det(basis: &LagrangeBasis, xe: &[f64], n: usize) -> f64 {
    let d = basis.simplex().dim();
    let mut g = vec![0.0; basis.len() * d];
    let mut m = f64::INFINITY;
    for i in 0..=n {
        for j in 0..=n - i {
            let xi = [i as f64 / n as f64, j as f64 / n as f64, 0.0];
            basis.eval_grad_into(&xi, &mut g);
            m = m.min(linalg::det(d, &mapping::jacobian(d, xe, &g)));
        }
    }
    m
}

#[test]
fn certified_minimum_never_exceeds_the_sampled_one() {
    let mut seed = 2016;
    let mut counts = [0usize; 3];
    let mut n = 0;
    for (simplex, p, count) in [
        (Simplex::Tri, 2, 800),
        (Simplex::Tri, 4, 600),
        (Simplex::Tri, 10, 100),
        (Simplex::Tet, 2, 600),
        (Simplex::Tet, 3, 400),
        (Simplex::Tet, 8, 40),
        (Simplex::Tet, 9, 30),
        (Simplex::Tet, 10, 30),
    ] {
        let basis = LagrangeBasis::new(&NodeSet::new(simplex, p, NodeSpacing::Optimal));
        let cache = sampling_cache(&basis);
        let jb = JacobianBernstein::new(&basis);
        for _ in 0..count {
            let dir = random_dir(&basis, &mut seed);
            let xe = element(&basis, &dir, 0.25 * lcg(&mut seed));
            let sampled = element_quality(&cache, &xe, &xe, None);
            let c = jb.certify(&xe);
            assert!(
                c.q3_lower() <= sampled.q3 + 1e-12,
                "{simplex:?} p={p}: certified {c:?} above sampled {}",
                sampled.q3
            );
            if sampled.q3 <= 0.0 {
                assert_eq!(c.verdict, Verdict::Invalid, "{simplex:?} p={p}: sampled invalid, certified {c:?}");
            }
            counts[c.verdict as usize] += 1;
            n += 1;
        }
    }
    println!("{n} random elements: {} certified valid, {} invalid, {} uncertain", counts[0], counts[1], counts[2]);
    assert!(counts[0] > 0 && counts[1] > 0, "the sample should hold both valid and invalid elements");
}

#[test]
fn an_element_inverted_between_the_samples_is_caught() {
    let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tri, 3, NodeSpacing::Optimal));
    let cache = sampling_cache(&basis);
    let jb = JacobianBernstein::new(&basis);
    let mut seed = 11;
    for attempt in 0..2000 {
        let dir = random_dir(&basis, &mut seed);
        // Smallest scale at which the dense probe finds det J ≤ 0.
        let steps = 400;
        let Some(k) =
            (1..=steps).find(|&k| fine_min_det(&basis, &element(&basis, &dir, k as f64 / steps as f64), 60) <= 0.0)
        else {
            continue;
        };
        let xe = element(&basis, &dir, k as f64 / steps as f64);
        let sampled = element_quality(&cache, &xe, &xe, None);
        if sampled.q3 <= 0.0 {
            continue;
        }
        let c = jb.certify(&xe);
        println!(
            "attempt {attempt}: dense probe min det J {:.3e}, sampled Q3 {:.4} (valid), certified {:?}",
            fine_min_det(&basis, &xe, 60),
            sampled.q3,
            c.verdict
        );
        assert!(sampled.is_valid(), "the sampled check misses it");
        assert_eq!(c.verdict, Verdict::Invalid, "the certified check catches it");
        return;
    }
    panic!("no element inverted only between samples was found");
}

/// A random point of the reference simplex, barycentric (uniform on the simplex).
fn random_lambda(d: usize, seed: &mut u64) -> [f64; 4] {
    let mut l = [0.0; 4];
    for x in l.iter_mut().take(d + 1) {
        *x = -lcg(seed).ln();
    }
    let s: f64 = l.iter().sum();
    l.map(|x| x / s)
}

#[test]
fn exact_bernstein_coefficients_reproduce_det_j_at_every_order() {
    // Both node families: the optimal (warp & blend) nodes the curving uses
    // and the equispaced ones of gmsh files (`hocurve quality`).
    let mut seed = 1977;
    for spacing in [NodeSpacing::Optimal, NodeSpacing::Equispaced] {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            let d = simplex.dim();
            for p in 1..=10 {
                let basis = LagrangeBasis::new(&NodeSet::new(simplex, p, spacing));
                let jb = JacobianBernstein::new(&basis);
                assert_eq!(jb.len(), (1..=d).map(|k| (d * (p - 1) + k) as f64 / k as f64).product::<f64>() as usize);
                let mut coef = vec![0.0; jb.len()];
                let mut g = vec![0.0; basis.len() * d];
                for _ in 0..3 {
                    let xe = element(&basis, &random_dir(&basis, &mut seed), 0.15);
                    jb.coefficients_into(&xe, &mut coef);
                    let (cmin, cmax) =
                        coef.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &c| (a.min(c), b.max(c)));
                    let (mut smin, mut smax, mut err, mut scale) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, 0.0f64);
                    for _ in 0..200 {
                        let l = random_lambda(d, &mut seed);
                        basis.eval_grad_into(&[l[1], l[2], l[3]], &mut g);
                        let want = linalg::det(d, &mapping::jacobian(d, &xe, &g));
                        err = err.max((jb.eval(&coef, &l) - want).abs());
                        scale = scale.max(want.abs());
                        smin = smin.min(want);
                        smax = smax.max(want);
                    }
                    // Round-off: the conversion to Bernstein form of degree 10 on
                    // 286 nodes loses a few digits, no more.
                    println!("{spacing:?} {simplex:?} p={p}: error {err:.2e}, |det J| {scale:.2e}");
                    assert!(
                        err <= 1e-10 * scale.max(1.0),
                        "{spacing:?} {simplex:?} p={p}: error {err:.2e} (|det J| {scale:.2e})"
                    );
                    let tol = 1e-12 * scale.max(1.0);
                    assert!(
                        cmin <= smin + tol && cmax >= smax - tol,
                        "{simplex:?} p={p}: [{cmin}, {cmax}] does not hold [{smin}, {smax}]"
                    );
                    // The vertex coefficients are the values at the vertices.
                    for k in 0..=d {
                        let mut l = [0.0; 4];
                        l[k] = 1.0;
                        let i = jb.multi_indices().iter().position(|a| a[k] == d * (p - 1)).unwrap();
                        assert!((coef[i] - jb.eval(&coef, &l)).abs() <= 1e-12 * scale.max(1.0));
                    }
                }
            }
        }
    }
}

#[test]
fn high_order_tets_are_certified_with_finite_bounds() {
    // Orders 8..10 in 3D were out of reach of the lattice expansion (NaN).
    // A smooth curved map x = ξ + ε sin(π(ξ·k + c)) interpolated at the nodes:
    // valid, with det J between about 0.7 and 1.3; and the same pushed to
    // ε = 0.2, where it folds.
    for p in 8..=10 {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tet, p, NodeSpacing::Optimal));
        let cache = sampling_cache(&basis);
        let jb = JacobianBernstein::new(&basis);
        let smooth = |eps: f64| -> Vec<f64> {
            let pi = std::f64::consts::PI;
            let coords = &basis.nodes().coords;
            coords
                .iter()
                .flat_map(|x| {
                    (0..3).map(move |c| x[c] + eps * (pi * (x[0] + 2.0 * x[1] - x[2] + 0.3 * c as f64)).sin())
                })
                .collect()
        };
        let xe = smooth(0.03);
        let c = jb.certify(&xe);
        let sampled = element_quality(&cache, &xe, &xe, None);
        println!("p={p}: certified {c:?}, Q3 >= {:.4}; sampled Q3 {:.4}", c.q3_lower(), sampled.q3);
        assert_eq!(c.verdict, Verdict::Valid, "p={p}: {c:?}");
        assert!(c.q3_lower() > 0.0 && c.q3_lower() <= sampled.q3 + 1e-12, "p={p}");
        let folded = smooth(0.2);
        assert!(element_quality(&cache, &folded, &folded, None).q3 <= 0.0, "the test element should fold");
        assert_eq!(jb.certify(&folded).verdict, Verdict::Invalid, "p={p}");
    }
}

#[test]
fn a_curved_sphere_shell_at_order_8_is_certified_end_to_end() {
    // Before the exact expansion, order 8 in 3D reported NaN here.
    let case = cases::spherical_shell_3d(0.5, 1.0, 2, 1);
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|dim, tag| case.projector.get(dim, tag).is_some());
    let opts = CurveOptions { order: 8, formulation: Formulation::Linear, ..Default::default() };
    let curved = curve(&mesh, &case.projector, &opts, &mut |_| true).unwrap();
    let q = &curved.report.quality;
    println!(
        "p=8, {} cells: sampled min Q3 {:.4} ({} invalid), certified min Q3 {:.4} ({} invalid, {} uncertain)",
        curved.report.cells, q.min_q3, q.n_invalid, q.certified_min_q3, q.n_certified_invalid, q.n_uncertain
    );
    assert!(q.certified_min_q3.is_finite(), "certified min Q3 {}", q.certified_min_q3);
    assert!(q.certified_min_q3 <= q.min_q3 + 1e-12, "certified {} above sampled {}", q.certified_min_q3, q.min_q3);
    assert_eq!(q.n_invalid, 0);
    assert_eq!(q.n_certified_invalid + q.n_uncertain, 0);
    assert!(q.certified_min_q3 > 0.0);
}
