//! High-order numbering and boundary classification on small meshes.

mod common;

use hocurve::mesh::{validate_and_orient, HighOrderMesh, LinearMesh, NodeConstraint, Topology};
use hocurve::reference::{NodeSet, NodeSpacing};
use hocurve::Error;

fn elevate(m: &LinearMesh, p: usize) -> hocurve::Result<(HighOrderMesh, NodeSet)> {
    let (m, _) = validate_and_orient(m)?;
    let topo = Topology::new(&m)?;
    let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
    Ok((HighOrderMesh::elevate(&m, &topo, &nodes, NodeSpacing::Optimal)?, nodes))
}

/// Every cell, recomputing each of its nodes from its own vertices, finds the
/// global coordinate stored for that node: shared nodes are shared correctly.
#[test]
fn shared_nodes_agree_from_every_cell_2d_and_3d() {
    for (mesh, p) in [(common::square_mesh(3), 5), (common::cube_mesh(2), 4), (common::cube_mesh(2), 6)] {
        let (ho, nodes) = elevate(&mesh, p).unwrap();
        let dim = ho.dim();
        let mut used = vec![false; ho.n_nodes()];
        for c in 0..ho.n_cells() {
            let cell = ho.cell(c);
            let xv: Vec<[f64; 3]> = cell[..=dim].iter().map(|&v| ho.node(v)).collect();
            for (a, &g) in cell.iter().enumerate() {
                used[g] = true;
                let xi = nodes.coords[a];
                let l0 = 1.0 - xi[..dim].iter().sum::<f64>();
                for d in 0..dim {
                    let x = l0 * xv[0][d] + (0..dim).map(|i| xi[i] * xv[i + 1][d]).sum::<f64>();
                    assert!((x - ho.node(g)[d]).abs() < 1e-13, "cell {c} node {a} (global {g})");
                }
            }
        }
        assert!(used.iter().all(|&u| u), "every node belongs to a cell");
        // Euler-type count: n_nodes = V + (p−1)E + (p−1)(p−2)/2 F + interior.
        let topo = Topology::new(&validate_and_orient(&mesh).unwrap().0).unwrap();
        let per_face = (p - 1) * (p - 2) / 2;
        let expect = if dim == 2 {
            mesh.n_vertices() + (p - 1) * topo.edges.len() + per_face * mesh.n_cells()
        } else {
            mesh.n_vertices()
                + (p - 1) * topo.edges.len()
                + per_face * topo.faces.len()
                + (p - 1) * (p - 2) * (p - 3) / 6 * mesh.n_cells()
        };
        assert_eq!(ho.n_nodes(), expect);
    }
}

/// A cube whose top face is surface 1 and sides surface 2: nodes on the top
/// are on surface 1, edges between top and sides stay fixed unless they are
/// given as a feature curve, vertices are fixed, the rest is free.
#[test]
fn classification_of_faces_edges_and_feature_curves() {
    let mut mesh = common::cube_mesh(2);
    let (o, _) = validate_and_orient(&mesh).unwrap();
    let topo = Topology::new(&o).unwrap();
    let z = |v: usize| o.coords[v * 3 + 2];
    let x = |v: usize| o.coords[v * 3];
    for &f in &topo.boundary_facets {
        let vs = topo.faces[f];
        if vs.iter().all(|&v| z(v) == 1.0) {
            mesh.facets.extend_from_slice(&vs);
            mesh.facet_tags.push(1);
        } else if vs.iter().all(|&v| x(v) == 0.0) {
            mesh.facets.extend_from_slice(&vs);
            mesh.facet_tags.push(2);
        }
    }
    let p = 3;
    let (ho, _) = elevate(&mesh, p).unwrap();
    let count = |c: NodeConstraint| ho.constraint.iter().filter(|&&k| k == c).count();
    let on1 = count(NodeConstraint::OnEntity { dim: 2, tag: 1 });
    let on2 = count(NodeConstraint::OnEntity { dim: 2, tag: 2 });
    assert!(on1 > 0 && on2 > 0);
    for (i, k) in ho.constraint.iter().enumerate() {
        let y = ho.node(i);
        match k {
            NodeConstraint::OnEntity { dim: 2, tag: 1 } => {
                assert!((y[2] - 1.0).abs() < 1e-15 && y[0] > 0.0)
            }
            NodeConstraint::OnEntity { dim: 2, tag: 2 } => {
                assert!(y[0].abs() < 1e-15 && y[2] < 1.0)
            }
            _ => {}
        }
    }
    // The edge x = 0, z = 1 joins the two surfaces: its nodes are fixed...
    let on_ridge = |i: usize| {
        let y = ho.node(i);
        y[0].abs() < 1e-15 && (y[2] - 1.0).abs() < 1e-15
    };
    let ridge: Vec<usize> = (ho.n_vertices..ho.n_nodes()).filter(|&i| on_ridge(i)).collect();
    assert_eq!(ridge.len(), 2 * (p - 1));
    assert!(ridge.iter().all(|&i| ho.constraint[i] == NodeConstraint::Fixed));
    // ...unless the ridge is a feature curve.
    let ridge_edges: Vec<[usize; 2]> =
        topo.edges.iter().filter(|e| e.iter().all(|&v| x(v) == 0.0 && z(v) == 1.0)).copied().collect();
    assert_eq!(ridge_edges.len(), 2);
    for e in &ridge_edges {
        mesh.feature_edges.extend_from_slice(e);
        mesh.feature_edge_tags.push(7);
    }
    let (ho, _) = elevate(&mesh, p).unwrap();
    assert!(ridge.iter().all(|&i| ho.constraint[i] == NodeConstraint::OnEntity { dim: 1, tag: 7 }));
    assert!((0..ho.n_vertices).all(|v| ho.constraint[v] != NodeConstraint::Free || {
        let y = ho.node(v);
        y.iter().all(|&c| c > 0.0 && c < 1.0)
    }));
}

#[test]
fn facets_that_are_not_on_the_boundary_or_tagged_twice_are_rejected() {
    let mut mesh = common::cube_mesh(2);
    let (o, _) = validate_and_orient(&mesh).unwrap();
    let topo = Topology::new(&o).unwrap();
    let interior = (0..topo.faces.len()).find(|f| !topo.boundary_facets.contains(f)).unwrap();
    mesh.facets.extend_from_slice(&topo.faces[interior]);
    mesh.facet_tags.push(1);
    assert!(matches!(elevate(&mesh, 2), Err(Error::InvalidInput(m)) if m.contains("not a boundary facet")));
    let mut mesh = common::cube_mesh(2);
    let b = topo.faces[topo.boundary_facets[0]];
    mesh.facets.extend_from_slice(&b);
    mesh.facets.extend_from_slice(&[b[2], b[0], b[1]]);
    mesh.facet_tags.extend_from_slice(&[1, 2]);
    assert!(matches!(elevate(&mesh, 2), Err(Error::InvalidInput(m)) if m.contains("tagged twice")));
    let mut mesh = common::cube_mesh(2);
    let interior_edge = topo.edges.iter().find(|e| e.iter().any(|&v| !topo.boundary_vertex[v])).unwrap();
    mesh.feature_edges.extend_from_slice(interior_edge);
    mesh.feature_edge_tags.push(3);
    assert!(matches!(elevate(&mesh, 2), Err(Error::InvalidInput(m)) if m.contains("not an edge of the boundary")));
}
