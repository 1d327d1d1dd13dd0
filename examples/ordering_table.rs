//! AMD against nested dissection (METIS) for the direct solver, on the
//! `hocurve bench` cases: K_ff of the straight order-p mesh, then for each
//! ordering, interleaved over `reps` rounds, the symbolic analysis time, the
//! factor's nonzeros and the numeric factorisation + solve time (min and
//! median over the rounds).
//!
//! `cargo run --release --example ordering_table -- <dim> <size> <p> [reps] [amd,nd]`
//! (2D: `cylinder_channel_2d(size, 8, 100)`; 3D: `sphere_in_box_3d(size, size)`).

mod common;

use std::time::Instant;

use hocurve::assembly::{DofMap, LinearElasticKernel, System};
use hocurve::cases;
use hocurve::mapping::ElementCache;
use hocurve::material::LinearElastic;
use hocurve::mesh::{validate_and_orient, HighOrderMesh, Topology};
use hocurve::quadrature::simplex_rule;
use hocurve::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use hocurve::solver::{DirectOrdering, SparseCholesky};

fn stats(v: &mut [f64]) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[0], v[v.len() / 2])
}

fn main() -> hocurve::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: &str| a.get(i).cloned().unwrap_or_else(|| d.to_string());
    let dim: usize = arg(1, "2").parse().expect("dim");
    let size: usize = arg(2, "32").parse().expect("size");
    let p: usize = arg(3, "2").parse().expect("p");
    let reps: usize = arg(4, "3").parse().expect("reps");
    let orderings: Vec<DirectOrdering> =
        arg(5, "amd,nd").split(',').map(DirectOrdering::parse).collect::<hocurve::Result<_>>()?;
    let case = if dim == 2 { cases::cylinder_channel_2d(size, 8, 100.0) } else { cases::sphere_in_box_3d(size, size) };
    let (lin, _) = validate_and_orient(&case.mesh)?;
    let topo = Topology::new(&lin)?;
    let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
    let mesh = HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal)?;
    let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(topo.simplex, 2 * p));
    let kernel = LinearElasticKernel { cache, material: LinearElastic::try_from_young_poisson(1.0, 0.45)? };
    let prescribed: Vec<f64> = (0..mesh.coords.len()).map(|i| 0.01 * (i as f64 * 0.1).sin()).collect();
    let mut system = System::new(&mesh, DofMap::new(&mesh));
    system.assemble(&mesh, &mesh.coords, &kernel, &prescribed, false)?;
    let (pattern, values, rhs) = (system.pattern(), system.values(), system.rhs());
    let base_mb = common::peak_rss_mb();
    let k = orderings.len();
    let (mut sym_t, mut num_t, mut nnz) = (vec![vec![]; k], vec![vec![]; k], vec![0usize; k]);
    let mut sol: Vec<Vec<f64>> = vec![vec![]; k];
    for _ in 0..reps {
        for (i, &o) in orderings.iter().enumerate() {
            let t = Instant::now();
            let chol = SparseCholesky::try_analyse_with(pattern, o)?;
            sym_t[i].push(t.elapsed().as_secs_f64());
            nnz[i] = chol.factor_nnz();
            let mut x = rhs.to_vec();
            let t = Instant::now();
            chol.try_factor_solve_in_place(pattern, values, &mut x)?;
            num_t[i].push(t.elapsed().as_secs_f64());
            sol[i] = x;
        }
    }
    let norm = sol[0].iter().map(|v| v * v).sum::<f64>().sqrt();
    for i in 0..k {
        let diff = sol[i].iter().zip(&sol[0]).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt() / norm;
        let (smin, smed) = stats(&mut sym_t[i]);
        let (nmin, nmed) = stats(&mut num_t[i]);
        println!(
            "dim={dim} p={p} size={size} n={} nnzA={} ordering={} nnzL={} symbolic_min={smin:.4} symbolic_med={smed:.4} \
             factor_solve_min={nmin:.4} factor_solve_med={nmed:.4} rel_diff={diff:.1e} base_MB={base_mb:.0} peak_MB={:.0}",
            pattern.n,
            pattern.nnz(),
            orderings[i].name(),
            nnz[i],
            common::peak_rss_mb()
        );
    }
    Ok(())
}
