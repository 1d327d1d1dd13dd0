//! The direct solver's fill-reducing orderings: the nested-dissection ordering
//! is a permutation that keeps each node's dofs together, and AMD and nested
//! dissection solve the same systems alike.

mod common;

use hocurve::assembly::DofMap;
use hocurve::cases::{self, Case};
use hocurve::mesh::{validate_and_orient, HighOrderMesh, Topology};
use hocurve::reference::{NodeSet, NodeSpacing};
use hocurve::solver::{
    nested_dissection, node_block_size, DirectOrdering, DirectSolver, LinearSolver, SparseCholesky, SymmetricCsc,
};

/// K_ff and a right-hand side of the straight order-p mesh of `case`.
fn system(case: &Case, p: usize) -> (SymmetricCsc, Vec<f64>, Vec<f64>) {
    let s = common::straight_system(case, p, false, false);
    (s.pattern().clone(), s.system.values().to_vec(), s.system.rhs().to_vec())
}

fn check_permutation(pattern: &SymmetricCsc, dim: usize) {
    assert_eq!(node_block_size(pattern), dim);
    let (fwd, inv) = nested_dissection(pattern).unwrap();
    let n = pattern.n;
    assert_eq!((fwd.len(), inv.len()), (n, n));
    let mut seen = vec![false; n];
    for (new, &old) in fwd.iter().enumerate() {
        assert!(old < n && !seen[old], "dof {old} twice or out of range");
        seen[old] = true;
        assert_eq!(inv[old], new);
    }
    // Each node's dofs stay consecutive, in order: new positions dim·k + j.
    for k in 0..n / dim {
        let o = fwd[dim * k];
        assert_eq!(o % dim, 0, "block {k} does not start at a node's first dof");
        for j in 0..dim {
            assert_eq!(fwd[dim * k + j], o + j);
        }
    }
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
    d / b.iter().map(|y| y * y).sum::<f64>().sqrt()
}

fn solve(pattern: &SymmetricCsc, values: &[f64], rhs: &[f64], o: DirectOrdering) -> (Vec<f64>, usize) {
    let mut solver = DirectSolver::try_new_with(pattern, o).unwrap();
    assert_ne!(solver.cholesky().ordering(), DirectOrdering::Auto);
    let nnz = solver.cholesky().factor_nnz();
    let mut x = vec![0.0; pattern.n];
    solver.solve(pattern, values, rhs, &mut x).unwrap();
    (x, nnz)
}

fn check_same_solution(case: &Case, p: usize, dim: usize) {
    let (pattern, values, rhs) = system(case, p);
    check_permutation(&pattern, dim);
    let (x_amd, nnz_amd) = solve(&pattern, &values, &rhs, DirectOrdering::Amd);
    let (x_nd, nnz_nd) = solve(&pattern, &values, &rhs, DirectOrdering::NestedDissection);
    let (x_auto, _) = solve(&pattern, &values, &rhs, DirectOrdering::Auto);
    let d = rel_diff(&x_nd, &x_amd);
    println!("{dim}D p = {p}: n = {}, nnz(L) AMD {nnz_amd}, ND {nnz_nd}, relative difference {d:.1e}", pattern.n);
    assert!(d < 1e-10, "AMD and ND solutions differ by {d:e}");
    assert!(rel_diff(&x_auto, &x_amd) < 1e-10);
    // The residual is at round-off too.
    let ax = pattern.sym_matvec(&values, &x_nd);
    assert!(rel_diff(&ax, &rhs) < 1e-10);
    // A sane ordering: not more than twice AMD's fill (a reversed permutation would be far worse).
    assert!(nnz_nd < 2 * nnz_amd, "ND fill {nnz_nd} vs AMD {nnz_amd}");
}

#[test]
fn amd_and_nested_dissection_solve_a_2d_system_alike() {
    check_same_solution(&cases::cylinder_channel_2d(16, 4, 10.0), 3, 2);
}

#[test]
fn amd_and_nested_dissection_solve_a_3d_system_alike() {
    check_same_solution(&cases::sphere_in_box_3d(2, 2), 2, 3);
}

#[test]
fn an_unblocked_pattern_is_ordered_dof_by_dof() {
    // 1D Laplacian, n = 7 (odd, so no 2- or 3-blocks).
    let n = 7;
    let mut col_ptr = vec![0];
    let mut row_idx = vec![];
    let mut values = vec![];
    for c in 0..n {
        row_idx.push(c as u32);
        values.push(2.0);
        if c + 1 < n {
            row_idx.push(c as u32 + 1);
            values.push(-1.0);
        }
        col_ptr.push(row_idx.len());
    }
    let a = SymmetricCsc { n, col_ptr, row_idx };
    assert_eq!(node_block_size(&a), 1);
    let (fwd, inv) = nested_dissection(&a).unwrap();
    let mut sorted = fwd.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, (0..n).collect::<Vec<_>>());
    for (new, &old) in fwd.iter().enumerate() {
        assert_eq!(inv[old], new);
    }
    let x_true: Vec<f64> = (0..n).map(|i| i as f64 - 2.5).collect();
    let b = a.sym_matvec(&values, &x_true);
    let chol = SparseCholesky::try_analyse_with(&a, DirectOrdering::NestedDissection).unwrap();
    let mut x = b.clone();
    chol.try_factor_solve_in_place(&a, &values, &mut x).unwrap();
    assert!(rel_diff(&x, &x_true) < 1e-12);
}

#[test]
fn orderings_parse() {
    assert_eq!(DirectOrdering::parse("ND").unwrap(), DirectOrdering::NestedDissection);
    assert_eq!(DirectOrdering::parse("amd").unwrap(), DirectOrdering::Amd);
    assert_eq!(DirectOrdering::default(), DirectOrdering::Auto);
    assert!(DirectOrdering::parse("rcm").is_err());
}

/// The pattern of the straight order-p mesh of `case`.
fn pattern(case: &Case, p: usize) -> SymmetricCsc {
    let (lin, _) = validate_and_orient(&case.mesh).unwrap();
    let topo = Topology::new(&lin).unwrap();
    let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
    let mesh = HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal).unwrap();
    DofMap::new(&mesh).pattern(&mesh)
}

#[test]
fn auto_picks_nested_dissection_where_it_was_measured_to_win() {
    // 3D: AMD on a coarse p = 2 mesh (7k unknowns) and on a p = 4 one at 17k; ND
    // on p = 2 at 17k (n² / nnz = 450 ≥ 300).
    let small = pattern(&cases::sphere_in_box_3d(3, 3), 2);
    assert_eq!(DirectOrdering::Auto.resolve(&small), DirectOrdering::Amd);
    let p4 = pattern(&cases::sphere_in_box_3d(2, 2), 4);
    assert_eq!(DirectOrdering::Auto.resolve(&p4), DirectOrdering::Amd);
    let large = pattern(&cases::sphere_in_box_3d(4, 4), 2);
    assert_eq!(DirectOrdering::Auto.resolve(&large), DirectOrdering::NestedDissection);
    // 2D: AMD at p = 2 whatever the size, ND at p = 4 from 50k unknowns.
    let p2 = pattern(&cases::cylinder_channel_2d(256, 8, 100.0), 2);
    assert_eq!(DirectOrdering::Auto.resolve(&p2), DirectOrdering::Amd);
    let p4 = pattern(&cases::cylinder_channel_2d(64, 8, 100.0), 4);
    assert_eq!(DirectOrdering::Auto.resolve(&p4), DirectOrdering::NestedDissection);
    assert_eq!(DirectOrdering::Amd.resolve(&p4), DirectOrdering::Amd);
}
