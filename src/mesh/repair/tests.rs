//! Each flip on a small hand-built configuration, through [`repair`]: the
//! cells cover the same region, the boundary facets are unchanged, every
//! cell is positively oriented, and the input-cell map is exact.

use std::collections::HashMap;

use super::geom::{barycentric, facet_key, orient, FacetKey};
use super::surface::SQUEEZE_FRACTION;
use super::*;

fn points(m: &LinearMesh, c: &[usize]) -> Vec<[f64; 3]> {
    c.iter().map(|&v| m.vertex(v)).collect()
}

fn measure(m: &LinearMesh) -> f64 {
    m.cells.chunks(m.dim + 1).map(|c| orient(m.dim, &points(m, c)).abs()).sum()
}

/// Facets with one cell, sorted.
fn boundary(m: &LinearMesh) -> Vec<FacetKey> {
    let d = m.dim;
    let mut count: HashMap<FacetKey, usize> = HashMap::new();
    for c in m.cells.chunks(d + 1) {
        for k in 0..=d {
            let f: Vec<usize> = (0..=d).filter(|&j| j != k).map(|j| c[j]).collect();
            *count.entry(facet_key(&f)).or_default() += 1;
        }
    }
    let mut b: Vec<FacetKey> = count.into_iter().filter(|&(_, n)| n == 1).map(|(f, _)| f).collect();
    b.sort_unstable();
    b
}

/// Repair `m` with `bulge` and check the invariants of the module docs.
fn repaired(m: &LinearMesh, bulge: &[f64]) -> Repaired {
    let r = repair(m, bulge);
    let d = m.dim;
    let out = &r.mesh;
    assert!((measure(out) - measure(m)).abs() < 1e-12 * measure(m), "measure changed");
    assert_eq!(boundary(out), boundary(m), "boundary changed");
    assert_eq!((&out.facets, &out.facet_tags, &out.coords), (&m.facets, &m.facet_tags, &m.coords));
    assert_eq!(r.input_cell.len(), out.n_cells());
    let n_kept = out.n_cells() - r.summary.cells_added;
    for (i, c) in out.cells.chunks(d + 1).enumerate() {
        let x = points(out, c);
        assert!(orient(d, &x) > 0.0, "cell {i} {c:?} is not positively oriented");
        let src = r.input_cell[i];
        let input = &m.cells[src * (d + 1)..(src + 1) * (d + 1)];
        if i < n_kept {
            assert_eq!(c, input, "an untouched cell keeps its vertices and maps to itself");
        } else {
            let mut g = [0.0; 3];
            for p in &x {
                for k in 0..3 {
                    g[k] += p[k] / (d + 1) as f64;
                }
            }
            let l = barycentric(d, &points(m, input), g);
            assert!(l[..=d].iter().all(|&l| l > -1e-12), "centroid of new cell {i} outside input cell {src}: {l:?}");
        }
    }
    assert_eq!(out.n_cells(), m.n_cells() - r.summary.cells_removed + r.summary.cells_added);
    r
}

fn tet_mesh(coords: &[[f64; 3]], cells: &[[usize; 4]], facets: &[[usize; 3]]) -> LinearMesh {
    let m = LinearMesh {
        dim: 3,
        coords: coords.iter().flatten().copied().collect(),
        cells: cells.iter().flatten().copied().collect(),
        facets: facets.iter().flatten().copied().collect(),
        facet_tags: vec![1; facets.len()],
        ..Default::default()
    };
    crate::mesh::validate_and_orient(&m).unwrap().0
}

#[test]
fn two_three_gives_the_boundary_facet_a_deeper_apex() {
    // Boundary facet xyz at z = 0; the apex o of its cell is 0.1 above it;
    // the cell across the face oxy has its apex e 0.9 above it.
    let (x, y, z, o, e) = (0, 1, 2, 3, 4);
    let m = tet_mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.9, 0.0], [0.5, 1.0, 0.1], [0.5, 0.6, 0.9]],
        &[[x, y, z, o], [o, x, y, e]],
        &[[x, y, z]],
    );
    // A bulge of 0.2 into the cell: twice the height of o, a fifth of e's.
    let r = repaired(&m, &[0.2]);
    let s = r.summary;
    assert_eq!((s.bad_cells, s.bulge_cells, s.flips_23, s.bad_cells_left), (1, 1, 1, 0), "{s:?}");
    assert_eq!((s.cells_removed, s.cells_added, r.mesh.n_cells()), (2, 3, 3));
    let on_facet = r.mesh.cells.chunks(4).find(|c| [x, y, z].iter().all(|v| c.contains(v))).unwrap();
    assert!(on_facet.contains(&e), "{on_facet:?}");
    // No bulge: nothing to do.
    let r = repaired(&m, &[0.0]);
    assert_eq!((r.summary, r.input_cell), (RepairSummary::default(), vec![0, 1]));
    // A bulge the other way (out of the domain) is harmless too.
    assert_eq!(repaired(&m, &[-0.5]).summary, RepairSummary::default());
}

#[test]
fn three_two_removes_the_edge_through_a_triangle() {
    // Three tets around the edge de, which crosses the triangle abc.
    let (d, e, a, b, c) = (0, 1, 2, 3, 4);
    let s3 = 3f64.sqrt() / 2.0;
    let m = tet_mesh(
        &[[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [-0.5, s3, 0.0], [-0.5, -s3, 0.0]],
        &[[d, e, a, b], [d, e, b, c], [d, e, c, a]],
        &[[d, a, b]],
    );
    // The height of e over dab is 0.90, that of c 1.35.
    let r = repaired(&m, &[0.5]);
    let s = r.summary;
    assert_eq!((s.bad_cells, s.flips_32, s.flips_23, s.bad_cells_left), (1, 1, 0, 0), "{s:?}");
    assert_eq!((s.cells_removed, s.cells_added), (3, 2));
    let mut cells: Vec<Vec<usize>> = r.mesh.cells.chunks(4).map(|c| c.to_vec()).collect();
    for c in &mut cells {
        c.sort_unstable();
    }
    cells.sort();
    assert_eq!(cells, vec![vec![0, 2, 3, 4], vec![1, 2, 3, 4]]);
}

#[test]
fn edge_removal_retriangulates_a_ring_of_five() {
    // Five tets around the edge de; the cell (d, e, r0, r1) has a boundary
    // facet (d, r0, r1) that bulges 0.45 into it. Over that facet, e and the
    // ring's r2 and r4 (which a 2-3 flip would bring) are 0.71 high, r3 1.15:
    // only the edge removal that makes the ring triangle (r0, r1, r3) will do.
    let ring: Vec<[f64; 3]> = (0..5)
        .map(|i| {
            let t = 2.0 * std::f64::consts::PI * i as f64 / 5.0;
            [t.cos(), t.sin(), 0.0]
        })
        .collect();
    let mut coords = vec![[0.1, 0.0, 0.6], [0.0, 0.1, -0.3]];
    coords.extend(&ring);
    let cells: Vec<[usize; 4]> = (0..5).map(|i| [0, 1, 2 + i, 2 + (i + 1) % 5]).collect();
    let m = tet_mesh(&coords, &cells, &[[0, 2, 3]]);
    let r = repaired(&m, &[0.45]);
    let s = r.summary;
    assert_eq!((s.bad_cells, s.edge_removals, s.bad_cells_left), (1, 1, 0), "{s:?}");
    assert_eq!((s.cells_removed, s.cells_added, r.mesh.n_cells()), (5, 6, 6));
    assert!(!r.mesh.cells.chunks(4).any(|c| c.contains(&0) && c.contains(&1)), "edge de is gone");
    assert!(r.mesh.cells.chunks(4).any(|c| [0, 2, 3, 5].iter().all(|v| c.contains(v))), "apex r3 over the facet");
}

#[test]
fn a_tet_with_all_vertices_on_a_curved_surface_is_flipped_away() {
    // A sphere cavity |x| > 1: the boundary facet abc is a chord near the
    // south pole s, and the cell (a, b, c, s) under it lies between the chord
    // and the sphere, the shell that curving removes. Its neighbour across
    // abs has its apex o further out, on the line from c through abs.
    let p = |th: f64, ph: f64| [th.sin() * ph.cos(), th.sin() * ph.sin(), -th.cos()];
    let (a, b, c, s, o) = (0, 1, 2, 3, 4);
    let mut x = vec![p(0.5, 0.0), p(0.5, 2.1), p(0.5, 4.2), p(0.0, 0.0)];
    let g = [0, 1, 2].map(|k| (x[a][k] + x[b][k] + x[s][k]) / 3.0);
    x.push([0, 1, 2].map(|k| x[c][k] + 10.0 * (g[k] - x[c][k])));
    // abc, and the two faces of the shell tet on the sphere, are tagged.
    let m = tet_mesh(&x, &[[a, b, c, s], [a, b, s, o]], &[[a, b, c], [b, c, s], [c, a, s]]);
    // The bulges as the repair stage measures them: sample points projected onto the sphere.
    let samples = bulge_samples(&m);
    let projected: Vec<[f64; 3]> = samples
        .points
        .iter()
        .map(|y| {
            let l = (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]).sqrt();
            y.map(|v| v / l)
        })
        .collect();
    let bulge = facet_bulges(&m, &samples, &projected);
    // abc bulges into its cell by 1 - cos(0.5) at its centroid; the others bulge away from theirs.
    assert!((bulge[0] - (1.0 - 0.5f64.cos())).abs() < 1e-3 && bulge[1] < 0.0 && bulge[2] < 0.0, "{bulge:?}");
    let bad = bad_cells(&m, &bulge);
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(bad[0].0 == 0 && bad[0].1.surface && bad[0].1.bulge, "{bad:?}");
    let r = repaired(&m, &bulge);
    let sum = r.summary;
    assert_eq!((sum.surface_cells, sum.flips_23, sum.bad_cells_left), (1, 1, 0), "{sum:?}");
    // Were no facet at its vertices bulging into the domain, the cell would be fine.
    assert!(bad_cells(&m, &[-bulge[0], bulge[1], bulge[2]]).is_empty());
}

#[test]
fn two_two_flips_the_interior_edge_of_a_flat_triangle() {
    // Boundary edge ab (tagged, bulging 0.2 inward); c only 0.1 above it.
    let (a, b, c, d) = (0, 1, 2, 3);
    let m = LinearMesh {
        dim: 2,
        coords: vec![0.0, 0.0, 1.0, 0.0, 0.05, 0.1, 0.9, 1.0],
        cells: vec![a, b, c, c, b, d],
        facets: vec![a, b],
        facet_tags: vec![5],
        ..Default::default()
    };
    let (m, _) = crate::mesh::validate_and_orient(&m).unwrap();
    let r = repaired(&m, &[0.2]);
    let s = r.summary;
    assert_eq!((s.bad_cells, s.flips_22, s.bad_cells_left, r.mesh.n_cells()), (1, 1, 0, 2), "{s:?}");
    assert!(r.mesh.cells.chunks(3).any(|t| [a, b, d].iter().all(|v| t.contains(v))));
}

#[test]
fn a_triangle_with_all_vertices_on_a_concave_curve_is_flipped_away() {
    // 2D: a, b, c on the circle |x - (0, 1)| = 1 (the domain outside it,
    // above), d above: the triangle abc lies inside the disc.
    let q = |t: f64| [t.sin(), 1.0 - t.cos()];
    let (a, b, c, d) = (0, 1, 2, 3);
    let (pa, pb, pc) = (q(-0.6), q(0.0), q(0.6));
    let m = LinearMesh {
        dim: 2,
        coords: vec![pa[0], pa[1], pb[0], pb[1], pc[0], pc[1], 0.0, 2.5],
        cells: vec![a, b, c, a, c, d],
        facets: vec![a, b, b, c],
        facet_tags: vec![1, 1],
        ..Default::default()
    };
    let (m, _) = crate::mesh::validate_and_orient(&m).unwrap();
    // The circle bulges by 1 - cos(0.3) over each chord, toward the cells (up).
    let beta = 1.0 - 0.3f64.cos();
    let r = repaired(&m, &[beta, beta]);
    assert_eq!((r.summary.surface_cells, r.summary.flips_22, r.summary.bad_cells_left), (1, 1, 0), "{:?}", r.summary);
    // The same curve bulging out of the domain: the triangle is fine.
    assert_eq!(repaired(&m, &[-beta, -beta]).summary.bad_cells, 0);
}

#[test]
fn a_bad_cell_that_no_flip_improves_is_left_and_the_repair_stops() {
    // A single tet: nothing to flip.
    let m =
        tet_mesh(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.2, 0.2, 0.1]], &[[0, 1, 2, 3]], &[[0, 1, 2]]);
    let r = repaired(&m, &[0.3]);
    assert_eq!((r.summary.bad_cells, r.summary.flips(), r.summary.bad_cells_left), (1, 0, 1));
    assert_eq!(r.input_cell, vec![0]);
}

#[test]
fn a_facet_bulging_toward_an_interior_vertex_is_left_to_the_solve() {
    // Four triangles around the interior vertex o, 0.1 above the tagged edge ab
    // that bulges 0.3 toward it: o is free in the solve, which moves it.
    let (a, b, c, d, o) = (0, 1, 2, 3, 4);
    let m = LinearMesh {
        dim: 2,
        coords: vec![0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.5, 0.1],
        cells: vec![a, b, o, b, c, o, c, d, o, d, a, o],
        facets: vec![a, b],
        facet_tags: vec![1],
        ..Default::default()
    };
    let (m, _) = crate::mesh::validate_and_orient(&m).unwrap();
    assert!(bad_cells(&m, &[0.3]).is_empty());
    assert_eq!(repaired(&m, &[0.3]).summary, RepairSummary::default());
}

/// A patch of the cylinder r = 1 (tag 7) as the crankshaft's gmsh mesh has
/// it: the facets (a, b, c) and (a, b, d) share a chord ab across 43° whose
/// midpoint, once on the cylinder, comes within a few percent of c. Two
/// tets on ab around an interior vertex x; the other boundary faces are
/// planes (tag 1).
fn cylinder_patch(c_angle: f64, d_angle: f64, d_z: f64) -> LinearMesh {
    let p = |deg: f64, r: f64, z: f64| [r * deg.to_radians().cos(), r * deg.to_radians().sin(), z];
    let x = [p(0.0, 1.0, 0.036), p(43.3, 1.0, 0.0), p(c_angle, 1.0, 0.0), p(d_angle, 1.0, d_z), p(22.0, 0.8, 0.05)];
    let (a, b, c, d, o) = (0, 1, 2, 3, 4);
    let mut m = tet_mesh(
        &x,
        &[[a, b, c, o], [a, b, o, d]],
        &[[a, b, c], [a, b, d], [a, c, o], [b, c, o], [a, o, d], [b, o, d]],
    );
    m.facet_tags = vec![7, 7, 1, 1, 1, 1];
    m
}

/// Samples on the cylinder (tag 7) go radially onto it; the others stay.
fn onto_cylinder(_: &LinearMesh, s: &BulgeSamples) -> Result<Vec<[f64; 3]>, ()> {
    Ok(s.points
        .iter()
        .zip(&s.entities)
        .map(|(y, &e)| {
            let r = if e == (2, 7) { y[0].hypot(y[1]) } else { 1.0 };
            [y[0] / r, y[1] / r, y[2]]
        })
        .collect())
}

fn squeeze_of(m: &LinearMesh, f: [usize; 3]) -> f64 {
    let s = bulge_samples(m);
    let y = onto_cylinder(m, &s).unwrap();
    surface::squeezes(m, &s, &y)[&facet_key(&f)].value
}

#[test]
fn a_surface_edge_whose_facet_folds_once_curved_is_flipped() {
    let m = cylinder_patch(21.8, 32.3, 0.103);
    let (a, b, c, d) = (0, 1, 2, 3);
    let before = squeeze_of(&m, [a, b, c]);
    assert!(before > 0.9 && before < 1.0, "{before}");
    let r = repair_with(&m, true, onto_cylinder).unwrap();
    assert_eq!(r.summary.surface_flips, 1, "{:?}", r.summary);
    let mut cyl: Vec<FacetKey> =
        r.mesh.facets.chunks(3).zip(&r.mesh.facet_tags).filter(|(_, &t)| t == 7).map(|(f, _)| facet_key(f)).collect();
    cyl.sort_unstable();
    assert_eq!(cyl, vec![facet_key(&[a, c, d]), facet_key(&[b, c, d])]);
    // The boundary is the new facets and the planes; the cells are valid.
    let mut facets: Vec<FacetKey> = r.mesh.facets.chunks(3).map(facet_key).collect();
    facets.sort_unstable();
    assert_eq!(boundary(&r.mesh), facets);
    for c in r.mesh.cells.chunks(4) {
        assert!(orient(3, &points(&r.mesh, c)) > 0.0);
    }
    assert_eq!((r.summary.cells_removed, r.summary.cells_added, r.input_cell.len()), (2, 2, 2));
    assert!(r.input_cell.iter().all(|&i| i < 2));
    let after = squeeze_of(&r.mesh, [a, c, d]).max(squeeze_of(&r.mesh, [b, c, d]));
    assert!(after < SQUEEZE_FRACTION, "{after}");
    // With ab on a feature curve it stays.
    let mut m = m;
    (m.feature_edges, m.feature_edge_tags) = (vec![a, b], vec![3]);
    assert_eq!(repair_with(&m, true, onto_cylinder).unwrap().summary.surface_flips, 0);
}

#[test]
fn a_surface_flip_that_would_not_lower_the_squeeze_is_refused() {
    // c before a, d between a and b: the flip is valid, but the new chord
    // cd, across 45°, would squeeze a c d more.
    let m = cylinder_patch(-15.0, 30.0, 0.05);
    let (a, b, c, d) = (0, 1, 2, 3);
    let before = squeeze_of(&m, [a, b, c]).max(squeeze_of(&m, [a, b, d]));
    assert!(before > SQUEEZE_FRACTION);
    let s = bulge_samples(&m);
    let y = onto_cylinder(&m, &s).unwrap();
    let origin = vec![vec![0], vec![1]];
    let bulge = facet_bulges(&m, &s, &y);
    let squeeze = surface::squeezes(&m, &s, &y);
    let round = surface::flip_round(&m, &bulge, &squeeze, &origin, &Default::default()).expect("a valid flip");
    assert_eq!(round.flips.len(), 1);
    let after = squeeze_of(&round.mesh, [a, c, d]).max(squeeze_of(&round.mesh, [b, c, d]));
    assert!(after >= before, "{after} < {before}");
    let r = repair_with(&m, true, onto_cylinder).unwrap();
    assert_eq!(r.summary.surface_flips, 0, "{:?}", r.summary);
    assert_eq!(r.mesh, m);
}
