//! The node orderings of `hocurve::reference::ordering` against the reference
//! coordinates gmsh and VTK themselves report (tests/data, written by
//! scripts/gen_reference_orderings.py).

use hocurve::reference::ordering::{
    gmsh_element_shape, gmsh_element_type, gmsh_multi_indices, gmsh_type_info, vtk_multi_indices,
};
use hocurve::reference::Simplex;
use std::path::PathBuf;

/// One element of a reference file: simplex, order, optional gmsh type, coordinates.
struct Block {
    simplex: Simplex,
    order: usize,
    gmsh_type: Option<i32>,
    coords: Vec<[f64; 3]>,
}

fn data(name: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join("data").join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn read_blocks(name: &str) -> Vec<Block> {
    let text = data(name);
    let mut blocks: Vec<Block> = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let t: Vec<&str> = line.split_whitespace().collect();
        let simplex = match t[0] {
            "tri" => Some(Simplex::Tri),
            "tet" => Some(Simplex::Tet),
            _ => None,
        };
        if let Some(simplex) = simplex {
            blocks.push(Block {
                simplex,
                order: t[1].parse().unwrap(),
                gmsh_type: t.get(3).map(|s| s.parse().unwrap()),
                coords: Vec::with_capacity(t[2].parse().unwrap()),
            });
        } else {
            let x: Vec<f64> = t.iter().map(|s| s.parse().unwrap()).collect();
            blocks.last_mut().unwrap().coords.push([x[0], x[1], x[2]]);
        }
    }
    blocks
}

/// Multi-index of a reference point of an order-p element: a_i = round(p ξ_i), a_0 = p − Σ.
fn multi_index(simplex: Simplex, p: usize, x: [f64; 3]) -> [usize; 4] {
    let d = simplex.dim();
    let mut a = [0; 4];
    for i in 0..d {
        let v = x[i] * p as f64;
        assert!((v - v.round()).abs() < 1e-9, "{x:?} is not equispaced at p = {p}");
        a[i + 1] = v.round() as usize;
    }
    a[0] = p - a[1..=d].iter().sum::<usize>();
    a
}

fn check(file: &str, ours: fn(Simplex, usize) -> Vec<[usize; 4]>) {
    let blocks = read_blocks(file);
    for simplex in [Simplex::Tri, Simplex::Tet] {
        for p in 1..=10 {
            let b = blocks
                .iter()
                .find(|b| b.simplex == simplex && b.order == p)
                .unwrap_or_else(|| panic!("{file}: no {simplex:?} of order {p}"));
            assert_eq!(b.coords.len(), simplex.n_nodes(p));
            let theirs: Vec<[usize; 4]> = b.coords.iter().map(|&x| multi_index(simplex, p, x)).collect();
            assert_eq!(ours(simplex, p), theirs, "{file}: {simplex:?} order {p}");
        }
    }
}

#[test]
fn gmsh_multi_indices_match_gmsh_reference_nodes() {
    check("gmsh_reference_nodes.txt", gmsh_multi_indices);
}

#[test]
fn vtk_multi_indices_match_vtk_parametric_coords() {
    check("vtk_reference_nodes.txt", vtk_multi_indices);
}

#[test]
fn gmsh_element_types_match_gmsh() {
    for b in read_blocks("gmsh_reference_nodes.txt") {
        let t = b.gmsh_type.expect("gmsh blocks carry their element type");
        assert_eq!(gmsh_element_type(b.simplex, b.order), Some(t));
        assert_eq!(gmsh_type_info(t), Some((b.simplex, b.order)));
    }
}

#[test]
fn gmsh_element_shapes_match_gmsh() {
    let text = data("gmsh_element_types.txt");
    let mut n = 0;
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
        let t: Vec<&str> = line.split_whitespace().collect();
        let ty: i32 = t[0].parse().unwrap();
        let dim: usize = t[1].parse().unwrap();
        let nodes: usize = t[3].parse().unwrap();
        assert_eq!(gmsh_element_shape(ty), Some((dim, nodes)), "type {ty} ({})", t[4]);
        n += 1;
    }
    assert!(n > 100);
}
