//! End-to-end curving of the built-in cases: the sphere cavity and the cylinder
//! boundary layer come out valid, with every boundary node on its surface, at
//! p = 2..6; and of a coarse gmsh aerofoil whose leading edge is not a vertex,
//! valid at p = 4 and 8 with its nose reached.

use hocurve::cases::{self, Case};
use hocurve::curve::{curve, CurveOptions, CurvedMesh};
use hocurve::mapping::ElementCache;
use hocurve::mesh::NodeConstraint;
use hocurve::quadrature::simplex_rule;
use hocurve::quality;
use hocurve::reference::{LagrangeBasis, NodeSet};

fn run(case: &Case, order: usize, increments: usize, poisson: f64) -> CurvedMesh {
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
    let opts = CurveOptions { order, increments, poisson, ..Default::default() };
    curve(&mesh, &case.projector, &opts, &mut |_| true).unwrap_or_else(|e| panic!("{} p={order}: {e}", case.name))
}

/// Largest distance from a node classified on tag 1 to the circle/sphere of radius 0.5 at the origin.
fn max_off_surface(c: &CurvedMesh) -> (usize, f64) {
    let mut n = 0;
    let mut worst: f64 = 0.0;
    for (i, k) in c.mesh.constraint.iter().enumerate() {
        if let NodeConstraint::OnEntity { tag: 1, .. } = k {
            let x = c.mesh.node(i);
            let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
            worst = worst.max((r - 0.5).abs());
            n += 1;
        }
    }
    (n, worst)
}

#[test]
fn sphere_cavity_in_box_is_valid_and_on_the_sphere_for_p_2_to_6() {
    for p in 2..=6 {
        let case = if p <= 4 { cases::sphere_in_box_3d(3, 2) } else { cases::sphere_in_box_3d(2, 1) };
        let c = run(&case, p, 3, 0.45);
        let (n, off) = max_off_surface(&c);
        let q = &c.report.quality;
        println!(
            "sphere cavity p={p}: cells={} nodes={} dofs={} on-sphere nodes={n} max distance={off:.1e} min Q3={:.4} mean Q3={:.4} invalid={} ({:.2} s)",
            c.report.cells, c.report.nodes, c.report.dofs, q.min_q3, q.mean_q3, q.n_invalid, c.report.timings.total
        );
        assert!(n > 0);
        assert!(off < 1e-10, "p={p}: node {off:e} off the sphere");
        assert_eq!(q.n_invalid, 0, "p={p}: invalid elements");
        assert!(q.min_q3 > 0.0 && q.min_q3 <= 1.0);
    }
}

#[test]
fn cylinder_boundary_layer_is_valid_and_on_the_circle_for_p_2_to_6() {
    for stretching in [25.0, 100.0] {
        let case = cases::cylinder_channel_2d(24, 6, stretching);
        for p in 2..=6 {
            let c = run(&case, p, 20, 0.45);
            let (n, off) = max_off_surface(&c);
            let q = &c.report.quality;
            println!(
                "cylinder stretching={stretching} p={p}: cells={} nodes={} on-circle nodes={n} max distance={off:.1e} min Q3={:.4} mean Q3={:.4} invalid={}",
                c.report.cells, c.report.nodes, q.min_q3, q.mean_q3, q.n_invalid
            );
            assert!(n > 0);
            assert!(off < 1e-10, "stretching {stretching} p={p}: node {off:e} off the circle");
            assert_eq!(q.n_invalid, 0, "stretching {stretching} p={p}: invalid elements");
            if stretching == 100.0 && p == 4 {
                // Control: moving only the boundary nodes (no elastic solve) folds the layer.
                let n_naive = naive_invalid(&c);
                println!("  control: boundary-only displacement leaves {n_naive} invalid elements");
                assert!(n_naive > 0, "the case must be hard enough to need the solve");
            }
        }
    }
}

/// Invalid elements when only the boundary nodes are moved onto the curve.
fn naive_invalid(c: &CurvedMesh) -> usize {
    let m = &c.mesh;
    let dim = m.dim();
    let mut coords = c.straight.clone();
    for (i, k) in m.constraint.iter().enumerate() {
        if *k != NodeConstraint::Free {
            coords[i * dim..(i + 1) * dim].copy_from_slice(&m.coords[i * dim..(i + 1) * dim]);
        }
    }
    let nodes = NodeSet::new(m.simplex, m.order, m.spacing);
    let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(m.simplex, 2 * m.order));
    quality::summarize(&quality::cell_qualities(&cache, &coords, None, &m.cells, None)).n_invalid
}

/// `naca0012_coarse_gmsh.msh`: gmsh's triangles (Frontal-Delaunay) around a
/// NACA 0012 section of unit chord, leading edge at the origin, in the box
/// [-1, 2] × [-1, 1]; the section is a closed spline through 24 points of
/// its closed-trailing-edge formula (curve tag 5), meshed at size 1/12
/// there: 447 triangles. Its leading edge is not a vertex: one boundary
/// edge, from x = 0.0276 on the lower surface to the same x on the upper,
/// cuts off the nose. The closest points of that edge's nodes lie on either
/// surface, none near the nose: the curved edge skipped it at p = 2..6,
/// and at p = 8 and 10 no stage could make the cells valid.
#[test]
fn a_coarse_aerofoil_keeps_its_nose_and_curves_at_high_orders() {
    use hocurve::geometry::{Shape, ShapeProjector};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/naca0012_coarse_gmsh.msh");
    let mut mesh = hocurve::io::gmsh::to_linear_mesh(&hocurve::io::gmsh::read_msh(&path).unwrap()).unwrap();
    let mut projector = ShapeProjector::new();
    projector.insert(5, Shape::Naca4 { digits: [0, 0, 1, 2], chord: 1.0, origin: [0.0, 0.0] });
    mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    for order in [4, 8] {
        let opts = CurveOptions { order, ..Default::default() };
        let c = curve(&mesh, &projector, &opts, &mut |_| true).unwrap_or_else(|e| panic!("p = {order}: {e}"));
        let q = &c.report.quality;
        assert_eq!((q.n_certified_invalid, q.n_uncertain), (0, 0), "p = {order}");
        assert_eq!(c.report.edges_along_curves, 1, "p = {order}: the edge across the nose");
        // The curved boundary reaches the nose: at even orders the edge's
        // middle node goes to the leading edge (the edge is symmetric), to
        // within a hundredth of the nose's depth (0.0276); its closest point
        // was at x = 0.0142.
        let front = (0..c.mesh.n_nodes())
            .filter(|&n| matches!(c.mesh.constraint[n], NodeConstraint::OnEntity { tag: 5, .. }))
            .map(|n| c.mesh.node(n)[0])
            .fold(f64::INFINITY, f64::min);
        assert!(front < 3e-4, "p = {order}: the section's front node at x = {front}");
    }
}
