//! Certified validity (issue 7): the Bernstein bounds of det J never claim more
//! than the samples show, and they catch an element inverted between samples.

use hocurve::mapping;
use hocurve::quality::{element_quality, sampling_cache, JacobianBernstein, Verdict};
use hocurve::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};

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
            m = m.min(mapping::det(d, &mapping::jacobian(d, xe, &g)));
        }
    }
    m
}

#[test]
fn certified_minimum_never_exceeds_the_sampled_one() {
    let mut seed = 2016;
    let mut counts = [0usize; 3];
    let mut n = 0;
    for (simplex, p, count) in
        [(Simplex::Tri, 2, 800), (Simplex::Tri, 4, 600), (Simplex::Tet, 2, 600), (Simplex::Tet, 3, 400)]
    {
        let basis = LagrangeBasis::new(&NodeSet::new(simplex, p, NodeSpacing::Optimal));
        let cache = sampling_cache(&basis);
        let jb = JacobianBernstein::new(&basis).unwrap();
        for _ in 0..count {
            let dir = random_dir(&basis, &mut seed);
            let xe = element(&basis, &dir, 0.25 * lcg(&mut seed));
            let sampled = element_quality(&cache, &xe, None);
            let c = jb.certify(&basis, &xe);
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
    let jb = JacobianBernstein::new(&basis).unwrap();
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
        let sampled = element_quality(&cache, &xe, None);
        if sampled.q3 <= 0.0 {
            continue;
        }
        let c = jb.certify(&basis, &xe);
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
