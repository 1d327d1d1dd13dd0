//! The repair stage end to end, on two small pieces of gmsh sphere cavities
//! (OCC, box [-2, 2]^3 less a sphere, cut out around the cells that made the
//! whole meshes fail; the cut faces are untagged, so they stay straight):
//!
//! * `sphere_cavity_cap.msh`: the 7 tets around cell 41 of the cavity of
//!   radius 0.70 (CharacteristicLengthMax 0.5, Min 0.1), a tet with all four
//!   vertices on the sphere whose two sphere faces meet at 54°, so the caps
//!   step keeps it; its bulge is 93 % of its height over one face. Curving
//!   fails at p = 2..4 ("cell 41 is inverted"); the repair removes it as a
//!   cap or, with caps kept, an edge removal replaces it.
//! * `sphere_cavity_shell.msh`: the 15 tets around cells 4 and 996 of the
//!   cavity of radius 1.10 (CharacteristicLengthMax 0.8): two adjacent tets
//!   with all vertices on the sphere, one of them a cap at 86°, the other
//!   with one sphere face bulging twice its height over it. No single flip is
//!   valid; both go as surface caps, one round after the other.
//!
//! And on a whole gmsh sphere cavity, `sphere_cavity_coarse_gmsh.msh`
//! (radius 0.8, CharacteristicLengthMax 0.7, Min 0.35), where one sphere
//! facet folds once curved: a surface flip.

use std::path::Path;

mod common;
use common::{c_handle, onto_counted, CountedShape};

use hocurve::curve::{curve, CurveOptions, Stage};
use hocurve::geometry::{facet_bulges, project_samples, Shape, ShapeProjector};
use hocurve::mesh::repair::{bad_cells, repair_with};
use hocurve::mesh::{validate_and_orient, LinearMesh};
use hocurve::session::Session;
use hocurve::Error;

fn load(name: &str, radius: f64) -> (LinearMesh, ShapeProjector) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name);
    let msh = hocurve::io::gmsh::read_msh(&path).unwrap();
    let mesh = hocurve::io::gmsh::to_linear_mesh(&msh).unwrap();
    let mut projector = ShapeProjector::new();
    projector.insert(7, Shape::parse(&format!("sphere:0,0,0,{radius}")).unwrap());
    (validate_and_orient(&mesh).unwrap().0, projector)
}

fn on_sphere(m: &LinearMesh, v: usize, radius: f64) -> bool {
    let x = m.vertex(v);
    ((x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt() - radius).abs() < 1e-9
}

/// Height of vertex `o` over the plane of (a, b, c).
fn height(m: &LinearMesh, [a, b, c]: [usize; 3], o: usize) -> f64 {
    let [xa, xb, xc, xo] = [a, b, c, o].map(|v| m.vertex(v));
    let s = |p: [f64; 3], q: [f64; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let (u, w, r) = (s(xb, xa), s(xc, xa), s(xo, xa));
    let n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
    (n[0] * r[0] + n[1] * r[1] + n[2] * r[2]).abs() / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// With the repair, the defaults; without it, the elastic stage alone (the
/// optimisation stage off), to show what the repair itself fixes.
fn opts(repair: bool) -> CurveOptions {
    let mut o = CurveOptions { order: 4, repair, ..Default::default() };
    o.optimize.enabled = repair;
    o
}

#[test]
fn a_mesh_that_fails_to_curve_curves_after_the_repair() {
    let (mesh, projector) = load("sphere_cavity_cap.msh", 0.70);
    match curve(&mesh, &projector, &opts(false), &mut |_| true) {
        Err(Error::InvalidElement { cell: Some(c), message: m }) => {
            assert!(m.contains("after halving the step 6 times") && m.starts_with(&format!("cell {c} ")), "{m}")
        }
        other => panic!("expected the run to fail without repair, got {:?}", other.map(|c| c.report.quality)),
    }
    // By default the bad cell, a cap at 54°, is removed as a cap.
    let c = curve(&mesh, &projector, &opts(true), &mut |_| true).unwrap();
    let r = &c.report;
    assert_eq!((r.repair.bad_cells, r.repair.surface_cells, r.repair.surface_caps), (1, 1, 1), "{:?}", r.repair);
    assert_eq!((r.repair.flips(), r.repair.cells_removed, r.repair.cells_added), (0, 1, 0));
    assert_eq!((r.cells, &r.input_cell[..]), (6, &[1, 2, 3, 4, 5, 6][..]));
    assert_eq!((r.quality.n_invalid, r.quality.n_certified_invalid), (0, 0));
}

#[test]
fn with_caps_kept_an_edge_removal_repairs_the_same_mesh() {
    let (mesh, projector) = load("sphere_cavity_cap.msh", 0.70);
    let c = curve(&mesh, &projector, &CurveOptions { remove_caps: false, ..opts(true) }, &mut |_| true).unwrap();
    let r = &c.report;
    assert_eq!((r.repair.bad_cells, r.repair.surface_cells, r.repair.edge_removals), (1, 1, 1), "{:?}", r.repair);
    assert_eq!((r.repair.cells_removed, r.repair.cells_added, r.repair.bad_cells_left), (4, 4, 0));
    assert_eq!((r.cells, r.input_cell.len()), (7, 7));
    assert_eq!((r.quality.n_invalid, r.quality.n_certified_invalid), (0, 0));
    // Untouched cells come first and map to themselves (vertex nodes come
    // first in a cell and are the input vertices).
    let npc = c.mesh.nodes_per_cell();
    for (i, &src) in r.input_cell.iter().enumerate() {
        let vertices = &c.mesh.cells[i * npc..i * npc + 4];
        if i < 3 {
            assert_eq!(vertices, &mesh.cells[4 * src..4 * src + 4]);
        }
        assert!(src < mesh.n_cells());
    }
}

#[test]
fn cells_inside_the_shell_of_a_sphere_cavity_are_found_and_removed() {
    let radius = 1.10;
    let (mesh, projector) = load("sphere_cavity_shell.msh", radius);
    let bulge = facet_bulges(&mesh, &projector).unwrap();
    let bad = bad_cells(&mesh, &bulge);
    assert_eq!(bad.iter().map(|b| b.0).collect::<Vec<_>>(), vec![0, 1], "{bad:?}");
    // Both have all four vertices on the sphere.
    for &(c, a) in &bad {
        assert!(a.surface && mesh.cells[4 * c..4 * c + 4].iter().all(|&v| on_sphere(&mesh, v, radius)));
    }
    // Cell 1 (996 of the whole mesh) has a sphere facet bulging more than its height over it.
    let facets: Vec<[usize; 3]> = mesh.facets.chunks(3).map(|f| [f[0], f[1], f[2]]).collect();
    let cell = &mesh.cells[4..8];
    let (k, f) = facets.iter().enumerate().find(|(_, f)| f.iter().all(|v| cell.contains(v))).unwrap();
    let apex = *cell.iter().find(|v| !f.contains(v)).unwrap();
    assert!(bulge[k] > height(&mesh, *f, apex), "bulge {} height {}", bulge[k], height(&mesh, *f, apex));

    let r = repair_with(&mesh, true, |m, s| project_samples(m.dim, s, &projector)).unwrap();
    let s = r.summary;
    assert_eq!((s.surface_caps, s.cells_removed, s.cells_added, s.bad_cells_left), (2, 2, 0, 0), "{s:?}");
    assert_eq!(r.input_cell, (2..15).collect::<Vec<_>>());
    assert!(bad_cells(&r.mesh, &facet_bulges(&r.mesh, &projector).unwrap()).is_empty());
    // The flipped surface edges: every sphere facet still has its vertices on the sphere.
    assert!(r.mesh.facets.iter().all(|&v| on_sphere(&r.mesh, v, radius)));

    // Curving fails without the repair and succeeds with it.
    assert!(matches!(curve(&mesh, &projector, &opts(false), &mut |_| true), Err(Error::InvalidElement { .. })));
    let c = curve(&mesh, &projector, &opts(true), &mut |_| true).unwrap();
    assert_eq!((c.report.cells, c.report.quality.n_certified_invalid), (13, 0));
    assert_eq!(c.report.repair, s);
}

#[test]
fn the_session_repairs_at_each_run_and_maps_the_new_cells() {
    let (mesh, projector) = load("sphere_cavity_cap.msh", 0.70);
    let mut s = Session::try_new(mesh.clone()).unwrap();
    s.set_order(3, hocurve::reference::NodeSpacing::Optimal).unwrap();
    s.set_projector(Some(Box::new(projector)));
    s.set_repair(false);
    s.set_optimize(false);
    assert!(s.run(10).is_err());
    s.set_repair(true);
    s.set_optimize(true);
    s.run(10).unwrap();
    let report = s.report().unwrap();
    assert_eq!((report.repair.surface_caps, report.cells), (1, 6));
    assert_eq!(s.input_cells(), &[1, 2, 3, 4, 5, 6]);
    assert_eq!(s.input_cells(), &report.input_cell[..]);
    // With the caps kept, the run flips instead; input cells still map the current mesh.
    s.set_remove_caps(false).unwrap();
    assert_eq!(s.input_cells(), &[0, 1, 2, 3, 4, 5, 6], "a straight mesh again");
    s.run(10).unwrap();
    assert_eq!(s.report().unwrap().repair.edge_removals, 1);
    assert_eq!(s.input_cells().len(), s.mesh().n_cells());
    assert!(s.input_cells().iter().all(|&c| c < mesh.n_cells()));
    assert_eq!(s.quality().n_certified_invalid, 0);
}

#[test]
fn the_c_abi_turns_the_repair_on_and_off_and_reports_it() {
    use hocurve::ffi::*;
    let (mesh, _) = load("sphere_cavity_cap.msh", 0.70);
    let cells: Vec<i64> = mesh.cells.iter().map(|&v| v as i64).collect();
    let facets: Vec<i64> = mesh.facets.iter().map(|&v| v as i64).collect();
    unsafe {
        let mut m = std::ptr::null_mut();
        assert_eq!(hoc_mesh_create(3, mesh.n_vertices(), mesh.coords.as_ptr(), 7, cells.as_ptr(), &mut m), HOC_OK);
        assert_eq!(hoc_mesh_set_boundary(m, mesh.n_facets(), facets.as_ptr(), mesh.facet_tags.as_ptr()), HOC_OK);
        let mut sphere = CountedShape::new(Shape::Sphere { center: [0.0; 3], radius: 0.70 });
        assert_eq!(hoc_mesh_set_projector(m, Some(onto_counted), &mut sphere as *mut CountedShape as *mut _), HOC_OK);
        assert_eq!(hoc_mesh_set_order(m, 2, HOC_SPACING_OPTIMAL), HOC_OK);
        // Caps kept: the repair flips (by default it would remove the cell as a cap).
        assert_eq!(hoc_mesh_set_remove_caps(m, 0), HOC_OK);
        assert_eq!(hoc_mesh_set_repair(m, 2), HOC_ERROR_INVALID_ARGUMENT);
        assert_eq!(hoc_mesh_set_repair(m, 0), HOC_OK);
        assert_eq!(hoc_mesh_run_increments(m, 10), HOC_ERROR_INVALID_ELEMENT);
        let mut r = HocRepair::default();
        assert_eq!(hoc_mesh_repair_summary(m, &mut r), HOC_OK);
        assert_eq!((r.removed_caps, r.bad_cells, r.edge_removals), (0, 0, 0), "nothing before a successful run");
        assert_eq!(hoc_mesh_repair_summary(m, std::ptr::null_mut()), HOC_ERROR_NULL_POINTER);
        assert_eq!(hoc_mesh_set_repair(m, 1), HOC_OK);
        assert_eq!(hoc_mesh_run_increments(m, 10), HOC_OK);
        assert_eq!(hoc_mesh_repair_summary(m, &mut r), HOC_OK);
        assert_eq!((r.bad_cells, r.surface_cells, r.edge_removals, r.bad_cells_left), (1, 1, 1, 0));
        assert_eq!((r.cells_removed, r.cells_added), (4, 4));
        let (mut nc, mut npc) = (0, 0);
        assert_eq!(hoc_mesh_cell_count(m, &mut nc, &mut npc), HOC_OK);
        let mut input = vec![-1i64; nc];
        assert_eq!(hoc_mesh_get_input_cells(m, nc, input.as_mut_ptr()), HOC_OK);
        assert_eq!(&input[..3], &[2, 4, 5], "cell 0 and three of its neighbours were replaced");
        assert!(input.iter().all(|&c| (0..7).contains(&c)));
        let mut q = std::mem::zeroed::<HocQuality>();
        assert_eq!(hoc_mesh_quality(m, &mut q), HOC_OK);
        assert_eq!(q.n_certified_invalid, 0);
        hoc_mesh_destroy(&mut m);
    }
}

/// A 2D domain whose boundary runs along the line y = 0 (tag 1) into the
/// circle of radius 2 about (0, 2) (tag 2), tangentially at O = (0, 0),
/// closed by three straight sides. Triangle (A, O, B) has both its boundary
/// edges at O; curved, they leave O along the same tangent.
fn smooth_hinge() -> (LinearMesh, ShapeProjector) {
    let b = 2.0 - 3f64.sqrt();
    let mesh = LinearMesh {
        dim: 2,
        coords: vec![-1.0, 0.0, 0.0, 0.0, 1.0, b, 1.0, 1.5, -1.0, 1.5],
        cells: vec![0, 1, 2, 0, 2, 3, 0, 3, 4],
        facets: vec![0, 1, 1, 2, 2, 3, 3, 4, 4, 0],
        facet_tags: vec![1, 2, 3, 4, 5],
        feature_edges: vec![],
        feature_edge_tags: vec![],
    };
    let mut projector = ShapeProjector::new();
    for (tag, shape) in [
        (1, "line:0,0,0,1,0,0"),
        (2, "circle:0,2,2"),
        (3, "line:1,0,0,0,1,0"),
        (4, "line:0,1.5,0,1,0,0"),
        (5, "line:-1,0,0,0,1,0"),
    ] {
        projector.insert(tag, Shape::parse(shape).unwrap());
    }
    (mesh, projector)
}

#[test]
fn a_cell_squeezed_by_a_smooth_boundary_is_split_and_curves_well() {
    let (mesh, projector) = smooth_hinge();
    for order in 2..=4 {
        // Without the repair (and the optimisation), det J at O tends to 0:
        // min Q3 0.007 at p = 2, inverted at p = 3 and 4.
        match curve(&mesh, &projector, &CurveOptions { order, ..opts(false) }, &mut |_| true) {
            Ok(c) => assert!(c.report.quality.min_q3 < 0.05, "p = {order}: {}", c.report.quality.min_q3),
            Err(e) => assert!(matches!(e, Error::InvalidElement { cell: Some(0), .. }), "p = {order}: {e}"),
        }
        // The repair splits A–B at its midpoint, the cap and the cell above it in two each.
        let c = curve(&mesh, &projector, &CurveOptions { order, ..opts(true) }, &mut |_| true).unwrap();
        let r = &c.report;
        assert_eq!((r.repair.edge_splits, r.repair.cells_removed, r.repair.cells_added), (1, 2, 4), "{:?}", r.repair);
        assert_eq!((r.cells, &r.input_cell[..]), (5, &[2, 0, 0, 1, 1][..]));
        assert_eq!(r.quality.n_certified_invalid, 0);
        assert!(r.quality.min_q3 > 0.75, "p = {order}: {}", r.quality.min_q3);
    }
}

/// On gmsh's coarse sphere cavity the only change of the repair is one
/// surface flip: a sphere facet whose chord's midpoint, once on the sphere,
/// comes most of the way to its third vertex. Without it, ILE at p = 3 with
/// adaptive stepping gives up; with it, the elastic stage alone gives a
/// valid mesh, with every boundary vertex still on the sphere.
#[test]
fn a_surface_flip_makes_valid_a_sphere_cavity_the_elastic_stage_cannot_curve() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/sphere_cavity_coarse_gmsh.msh");
    let mut mesh = hocurve::io::gmsh::to_linear_mesh(&hocurve::io::gmsh::read_msh(&path).unwrap()).unwrap();
    let mut projector = ShapeProjector::new();
    projector.insert(7, Shape::Sphere { center: [0.0; 3], radius: 0.8 });
    mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    let mut o = CurveOptions { order: 3, repair: false, ..Default::default() };
    o.optimize.enabled = false;
    match curve(&mesh, &projector, &o, &mut |_| true) {
        Err(Error::InvalidElement { message: m, .. }) => assert!(m.contains("adaptive stepping"), "{m}"),
        other => panic!("expected the elastic stage to fail, got {:?}", other.map(|c| c.report.quality)),
    }
    o.repair = true;
    let c = curve(&mesh, &projector, &o, &mut |_| true).unwrap();
    let r = &c.report;
    let mut expected =
        hocurve::mesh::RepairSummary { surface_flips: 1, cells_removed: 2, cells_added: 2, ..Default::default() };
    expected.bad_cells = r.repair.bad_cells;
    assert_eq!(r.repair, expected);
    assert_eq!((r.quality.n_certified_invalid, r.quality.n_uncertain), (0, 0));
    assert!(r.quality.certified_min_q3 > 0.0);
    let (m, _) = validate_and_orient(&mesh).unwrap();
    let repaired = repair_with(&m, true, |m, s| project_samples(m.dim, s, &projector)).unwrap();
    let facets = repaired.mesh.facets.chunks(3).zip(&repaired.mesh.facet_tags);
    assert!(facets.filter(|(_, &t)| t == 7).all(|(f, _)| f.iter().all(|&v| on_sphere(&repaired.mesh, v, 0.8))));
    // The C ABI reports it.
    use hocurve::ffi::*;
    let mut sphere = CountedShape::new(Shape::Sphere { center: [0.0; 3], radius: 0.8 });
    unsafe {
        let mut h = c_handle(&m, &mut sphere, 3);
        assert_eq!(hoc_mesh_run_increments(h, 10), HOC_OK);
        let mut s = HocRepair::default();
        assert_eq!(hoc_mesh_repair_summary(h, &mut s), HOC_OK);
        assert_eq!((s.surface_flips, s.cells_removed, s.cells_added), (1, 2, 2));
        hoc_mesh_destroy(&mut h);
    }
}

/// `torus_cavity_coarse_gmsh.msh`: gmsh's mesh of the box [-1, 1]^3 less a
/// torus (R = 0.6, r = 0.3 about z), h = 0.5 with 4 elements per turn of
/// curvature (`scripts/gen_corpus.py`, 579 tets). With its caps removed, the
/// chords that become boundary edges bulge through the cells below them at
/// p = 2 and no stage makes the mesh valid; with the caps kept it curves.
fn coarse_torus() -> (LinearMesh, ShapeProjector) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/torus_cavity_coarse_gmsh.msh");
    let mut mesh = hocurve::io::gmsh::to_linear_mesh(&hocurve::io::gmsh::read_msh(&path).unwrap()).unwrap();
    let mut projector = ShapeProjector::new();
    projector.insert(7, Shape::parse("torus:0,0,0,0.6,0.3").unwrap());
    mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    (mesh, projector)
}

/// Every node held on the torus (tag 7) is on it.
fn assert_on_torus(mesh: &hocurve::mesh::HighOrderMesh) {
    let mut held = 0;
    for n in 0..mesh.n_nodes() {
        if let hocurve::mesh::NodeConstraint::OnEntity { tag: 7, .. } = mesh.constraint[n] {
            let x = &mesh.coords[3 * n..3 * n + 3];
            let d = (((x[0] * x[0] + x[1] * x[1]).sqrt() - 0.6).powi(2) + x[2] * x[2]).sqrt() - 0.3;
            assert!(d.abs() < 1e-9, "node {n} is {d:e} off the torus");
            held += 1;
        }
    }
    assert!(held > 0);
}

#[test]
fn a_run_that_removed_caps_and_ends_invalid_is_made_again_with_the_caps_kept() {
    let (mesh, projector) = coarse_torus();
    let mut stages = Vec::new();
    let c = curve(&mesh, &projector, &CurveOptions::default(), &mut |p| {
        stages.push(p.stage);
        true
    })
    .unwrap();
    // Two runs, and the first does not start its elastic stage again after
    // its optimisation (the second start): the retry with the caps kept
    // stands in for it.
    let runs: Vec<usize> = (0..stages.len()).filter(|&i| stages[i] == Stage::Elevate).collect();
    assert_eq!(runs.len(), 2, "{stages:?}");
    let first = &stages[..runs[1]];
    let optimise = first.iter().position(|&s| s == Stage::Optimize).expect("the first run optimised");
    assert!(!first[optimise..].contains(&Stage::Increment), "{first:?}");
    let r = &c.report;
    assert_eq!(r.caps_kept_failed, None);
    let first = r.caps_kept_after.as_deref().expect("the run was made once");
    assert!(first.starts_with("invalid element: cell ") && first.contains("after optimisation"), "{first}");
    // The report is the second run's: no cap removed, every cell valid.
    assert_eq!((r.removed_caps, r.repair.surface_caps), (0, 0));
    assert_eq!((r.quality.n_certified_invalid, r.quality.n_uncertain), (0, 0));
    assert!(r.quality.certified_min_q3 > 0.0);
    assert_eq!(r.input_cell.len(), c.mesh.n_cells());
    assert_on_torus(&c.mesh);
}

#[test]
fn the_c_abi_makes_the_run_again_with_the_caps_kept_unless_told_not_to() {
    use hocurve::ffi::*;
    let (mesh, _) = coarse_torus();
    let (m, _) = validate_and_orient(&mesh).unwrap();
    let mut torus = CountedShape::new(Shape::parse("torus:0,0,0,0.6,0.3").unwrap());
    unsafe {
        let mut h = c_handle(&m, &mut torus, 2);
        let mut caps = HocRepair::default();
        assert_eq!(hoc_mesh_repair_summary(h, &mut caps), HOC_OK);
        assert!(caps.removed_caps > 0, "the preparation removes caps");
        assert_eq!(hoc_mesh_run_increments(h, 10), HOC_OK);
        let (mut kept, mut len) = (0, 0usize);
        let mut message = [0 as std::ffi::c_char; 16];
        assert_eq!(hoc_mesh_retry(h, &mut kept, &mut len, message.len(), message.as_mut_ptr()), HOC_OK);
        assert_eq!(kept, 1);
        assert!(len > 15);
        // Cut to the buffer, NUL-terminated.
        let cut = std::ffi::CStr::from_ptr(message.as_ptr()).to_str().unwrap();
        assert_eq!(cut, "invalid element");
        let mut s = HocRepair::default();
        assert_eq!(hoc_mesh_repair_summary(h, &mut s), HOC_OK);
        assert_eq!(s.removed_caps, 0, "the run that stood kept the caps");
        let mut q = std::mem::MaybeUninit::<HocQuality>::uninit();
        assert_eq!(hoc_mesh_quality(h, q.as_mut_ptr()), HOC_OK);
        assert_eq!(q.assume_init().n_certified_invalid, 0);
        let mut n_nodes = 0;
        assert_eq!(hoc_mesh_node_count(h, &mut n_nodes), HOC_OK);
        let mut before = vec![0.0; 3 * n_nodes];
        assert_eq!(hoc_mesh_get_nodes(h, HOC_ORDERING_NATIVE, n_nodes, before.as_mut_ptr()), HOC_OK);
        // Without the retry the run fails, and the mesh stays as it was.
        assert_eq!(hoc_mesh_set_retry(h, 0), HOC_OK);
        assert_eq!(hoc_mesh_run_increments(h, 10), HOC_ERROR_INVALID_ELEMENT);
        let err = std::ffi::CStr::from_ptr(hoc_mesh_last_error(h)).to_str().unwrap();
        assert!(err.contains("after optimisation") && !err.contains("second run"), "{err}");
        let mut after = vec![0.0; 3 * n_nodes];
        assert_eq!(hoc_mesh_get_nodes(h, HOC_ORDERING_NATIVE, n_nodes, after.as_mut_ptr()), HOC_OK);
        assert_eq!(before, after);
        assert_eq!(hoc_mesh_retry(h, &mut kept, &mut len, 0, std::ptr::null_mut()), HOC_OK);
        assert_eq!(kept, 1, "the last successful run's retry");
        hoc_mesh_destroy(&mut h);
    }
}

/// A projector that counts the points it is asked for.
struct Counting<'a>(&'a ShapeProjector, std::sync::atomic::AtomicUsize);

impl hocurve::geometry::Projector for Counting<'_> {
    fn project(&self, dim: usize, tag: i32, points: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
        self.1.fetch_add(points.len(), std::sync::atomic::Ordering::Relaxed);
        self.0.project(dim, tag, points, out)
    }
}

#[test]
fn each_bulge_sample_goes_to_the_projector_once_however_often_it_is_measured() {
    let (mut mesh, projector) = load("sphere_cavity_coarse_gmsh.msh", 0.8);
    mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    let samples = hocurve::mesh::repair::bulge_samples(&mesh);
    let counting = Counting(&projector, Default::default());
    let asked = || counting.1.load(std::sync::atomic::Ordering::Relaxed);
    let mut projections = hocurve::geometry::SampleProjections::default();
    let first = projections.project(mesh.dim, &samples, &counting).unwrap();
    // Each edge midpoint is a sample of both its facets, and is asked for once.
    let distinct: std::collections::HashSet<_> =
        samples.points.iter().zip(&samples.entities).map(|(x, e)| (*e, x.map(f64::to_bits))).collect();
    assert!(distinct.len() < samples.points.len() * 3 / 4, "{} of {}", distinct.len(), samples.points.len());
    assert_eq!(asked(), distinct.len());
    // The answers are those of each point projected alone.
    for ((x, &(dim, tag)), y) in samples.points.iter().zip(&samples.entities).zip(&first) {
        let mut alone = [[0.0; 3]];
        hocurve::geometry::Projector::project(&projector, dim, tag, &[*x], &mut alone).unwrap();
        assert_eq!(alone[0], *y);
    }
    // Measured again: nothing new to project, the same answers.
    assert_eq!(projections.project(mesh.dim, &samples, &counting).unwrap(), first);
    assert_eq!(asked(), distinct.len());
    // The repair of this mesh flips a surface edge and measures again.
    let n = asked();
    let mut again = hocurve::geometry::SampleProjections::default();
    let r = repair_with(&mesh, true, |m, s| again.project(m.dim, s, &counting)).unwrap();
    assert!(r.summary.surface_flips > 0, "{:?}", r.summary);
    let cold = Counting(&projector, Default::default());
    let r2 = repair_with(&mesh, true, |m, s| project_samples(m.dim, s, &cold)).unwrap();
    assert_eq!((r.mesh, r.input_cell), (r2.mesh, r2.input_cell));
    assert!(asked() - n < cold.1.load(std::sync::atomic::Ordering::Relaxed), "fewer points asked for across rounds");
}
