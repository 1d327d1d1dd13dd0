//! Q3 of an element whose vertices' straight tet is inverted although the
//! curved element is valid everywhere: a thin spherical shell with one layer,
//! where removing the boundary caps adds interior vertices that the curving
//! moves. Q3 was once normalised by the vertices' affine map, which flipped
//! its sign on 48 valid cells (sampled Q3 = −1 under a certified 0.60).
//! Q1 and Q2 are measured against the straight mesh's element, vertices
//! included.

use hocurve::cases;
use hocurve::curve::{curve, CurveOptions, Formulation};
use hocurve::quality;
use hocurve::reference::{LagrangeBasis, NodeSet};

#[test]
fn sampled_q3_agrees_with_the_certified_bound_when_vertices_move() {
    let case = cases::spherical_shell_3d(0.5, 0.6, 2, 1);
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|dim, tag| case.projector.get(dim, tag).is_some());
    let opts = CurveOptions {
        order: 4,
        increments: 1,
        formulation: Formulation::Ile,
        adaptive: Some(false),
        ..Default::default()
    };
    let curved = curve(&mesh, &case.projector, &opts, &mut |_| true).unwrap();
    let q = &curved.report.quality;
    println!(
        "sampled min Q3 {:.4}, {} invalid; certified min Q3 {:.4}, {} invalid",
        q.min_q3, q.n_invalid, q.certified_min_q3, q.n_certified_invalid
    );
    // The case does move vertices: some cell's vertices differ from their straight position.
    let m = &curved.mesh;
    let moved = (0..m.n_cells()).any(|c| {
        m.cell(c)[..4].iter().any(|&n| (0..3).any(|k| (m.coords[3 * n + k] - curved.straight[3 * n + k]).abs() > 1e-6))
    });
    assert!(moved, "no vertex moved: the case no longer tests what it should");
    // Q1, Q2 of the run are measured against the straight mesh's elements,
    // not against straight elements through the moved vertices.
    let basis = LagrangeBasis::new(&NodeSet::new(m.simplex, m.order, m.spacing));
    let cache = quality::sampling_cache(&basis);
    let straight = quality::cell_qualities(&cache, &m.coords, Some(&curved.straight), &m.cells, None);
    let through_vertices = quality::cell_qualities(&cache, &m.coords, None, &m.cells, None);
    let same = curved.cell_quality.iter().zip(&straight).all(|(a, b)| (a.q1, a.q2, a.q3) == (b.q1, b.q2, b.q3));
    assert!(same, "the run's Q1..Q3 are not those against the straight mesh");
    let changed = straight.iter().zip(&through_vertices).filter(|(a, b)| (a.q1 - b.q1).abs() > 1e-6).count();
    println!("{changed} of {} cells have another Q1 against the straight mesh", m.n_cells());
    assert!(changed > 0);
    assert_eq!(q.n_certified_invalid, 0);
    assert_eq!(q.n_invalid, 0, "a cell certified valid everywhere was sampled invalid");
    assert!(q.certified_min_q3 <= q.min_q3, "certified {} above sampled {}", q.certified_min_q3, q.min_q3);
    assert!(q.certified_min_q3 > 0.0);
}
