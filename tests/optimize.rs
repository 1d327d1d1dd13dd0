//! The optimisation stage on meshes nobody here designed: gmsh 4.15's
//! default tet meshes of a spherical cavity in the box [-2, 2]³ with only
//! a few elements across the sphere's radius, surface tag 7:
//! `tests/data/sphere_cavity_coarse_gmsh.msh` (r = 0.8, made with
//! `Mesh.CharacteristicLengthMax` 0.7, `CharacteristicLengthMin` 0.35) and
//! `tests/data/sphere_cavity_r06_gmsh.msh` (r = 0.6, 0.6 and 0.3).

use std::path::Path;

mod common;
use common::{c_handle, CountedShape};

use hocurve::curve::OptimizeOptions;
use hocurve::geometry::{Shape, ShapeProjector};
use hocurve::mesh::{LinearMesh, NodeConstraint};
use hocurve::{curve, CurveOptions, CurvedMesh, Error, Formulation};

const RADIUS: f64 = 0.8;

fn coarse_sphere() -> (LinearMesh, ShapeProjector) {
    gmsh_sphere_cavity("sphere_cavity_coarse_gmsh.msh", RADIUS)
}

const RADIUS_06: f64 = 0.6;

fn coarse_sphere_06() -> (LinearMesh, ShapeProjector) {
    gmsh_sphere_cavity("sphere_cavity_r06_gmsh.msh", RADIUS_06)
}

/// A gmsh mesh of a sphere cavity (surface tag 7) from tests/data.
fn gmsh_sphere_cavity(file: &str, radius: f64) -> (LinearMesh, ShapeProjector) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(file);
    let msh = hocurve::io::gmsh::read_msh(&path).unwrap();
    let mut mesh = hocurve::io::gmsh::to_linear_mesh(&msh).unwrap();
    let mut projector = ShapeProjector::new();
    projector.insert(7, Shape::Sphere { center: [0.0; 3], radius });
    mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    (mesh, projector)
}

fn run(mesh: &LinearMesh, projector: &ShapeProjector, opts: &CurveOptions) -> hocurve::Result<CurvedMesh> {
    curve(mesh, projector, opts, &mut |_| true)
}

fn p3(optimize: bool) -> CurveOptions {
    let mut o = CurveOptions { order: 3, ..Default::default() };
    o.optimize.enabled = optimize;
    o
}

/// Every node on the sphere is on it, and no node on a straight wall (or any
/// vertex there) has moved.
fn assert_boundary_kept(c: &CurvedMesh) {
    assert_on_sphere(c, RADIUS);
}

fn assert_on_sphere(c: &CurvedMesh, radius: f64) {
    let m = &c.mesh;
    for n in 0..m.n_nodes() {
        let x = m.node(n);
        match m.constraint[n] {
            NodeConstraint::OnEntity { .. } => {
                let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                assert!((r - radius).abs() < 1e-12, "node {n} is {:.3e} off the sphere", r - radius);
            }
            NodeConstraint::Fixed => {
                assert_eq!(&m.coords[3 * n..3 * n + 3], &c.straight[3 * n..3 * n + 3], "fixed node {n} moved")
            }
            NodeConstraint::Free => {}
        }
    }
}

#[test]
fn optimisation_makes_valid_a_mesh_that_adaptive_stepping_cannot_keep_valid() {
    let (mesh, projector) = coarse_sphere_06();
    // Without the optimisation stage, ILE with adaptive stepping gives up.
    match run(&mesh, &projector, &p3(false)) {
        Err(Error::InvalidElement { message: m, .. }) => assert!(m.contains("adaptive stepping"), "{m}"),
        other => panic!("expected the elastic stage to fail, got {:?}", other.map(|c| c.report.quality)),
    }
    let c = run(&mesh, &projector, &p3(true)).unwrap();
    let r = &c.report;
    let stop = r.elastic_stop.as_ref().expect("the elastic stage stopped short of the full load");
    assert!(stop.load > 0.0 && stop.load < 1.0, "{stop:?}");
    assert!(r.optimization.ran && r.optimization.invalid_before > 0, "{:?}", r.optimization);
    assert_eq!(r.optimization.invalid_after, 0);
    assert_eq!(r.quality.n_certified_invalid, 0);
    assert_eq!(r.quality.n_uncertain, 0);
    assert!(r.quality.certified_min_q3 > 0.0 && r.quality.min_q3 > 0.05, "{:?}", r.quality);
    assert_on_sphere(&c, RADIUS_06);
}

#[test]
fn optimisation_raises_the_minimum_quality_of_a_valid_mesh_and_keeps_the_boundary() {
    let (mesh, projector) = coarse_sphere();
    // ILE at p = 3 leaves a valid mesh with a poor cell.
    let base = CurveOptions { order: 3, ..Default::default() };
    let mut without = base.clone();
    without.optimize.enabled = false;
    let off = run(&mesh, &projector, &without).unwrap();
    let on = run(&mesh, &projector, &base).unwrap();
    assert_eq!(off.report.quality.n_certified_invalid, 0);
    let (q_off, q_on) = (off.report.quality.min_q3, on.report.quality.min_q3);
    assert!(q_off < hocurve::optimize::DEFAULT_THRESHOLD, "the case no longer needs the stage: {q_off}");
    assert!(q_on > q_off + 0.05, "min Q3 {q_off} -> {q_on}");
    assert_eq!(on.report.optimization.min_q3_before, q_off);
    assert_eq!(on.report.quality.n_certified_invalid, 0);
    assert!(on.report.optimization.cells_touched > 0);
    // Nodes outside the patches did not move.
    let moved = (0..on.mesh.n_nodes()).filter(|&n| on.mesh.node(n) != off.mesh.node(n)).count();
    assert_eq!(moved, on.report.optimization.nodes_moved);
    assert_boundary_kept(&on);
}

#[test]
fn optimisation_gives_the_same_mesh_for_any_number_of_threads() {
    let (mesh, projector) = coarse_sphere();
    let opts = p3(true);
    let in_pool = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| run(&mesh, &projector, &opts).unwrap())
    };
    let (one, two) = (in_pool(1), in_pool(2));
    assert!(one.report.optimization.ran);
    assert!(one.mesh.coords == two.mesh.coords, "the curved meshes differ between 1 and 2 threads");
}

/// A tet of gmsh's mesh of a sphere cavity (r = 0.6 in [-1, 1]^3, four
/// elements across the radius) has two faces on the sphere whose normals
/// differ by 54°: once curved, det J vanishes along their shared edge
/// whatever the interior nodes do. Letting that edge's high-order node slide
/// on the sphere makes the cell valid.
#[test]
fn sliding_boundary_nodes_on_the_surface_makes_valid_what_interior_moves_cannot() {
    let (mesh, projector) = gmsh_sphere_cavity("sphere_cavity_cap_gmsh.msh", 0.6);
    // The repair stage would remove this tet before curving: leave it.
    let mut opts = CurveOptions { order: 2, repair: false, ..Default::default() };
    (opts.optimize.slide, opts.optimize.split) = (false, false);
    match run(&mesh, &projector, &opts) {
        Err(Error::InvalidElement { cell: Some(c), message: m }) => {
            // The failing cell is a field of the error, and the message names the same one.
            assert!(m.contains("after optimisation") && m.starts_with(&format!("cell {c} ")), "{m}")
        }
        other => panic!("expected interior moves alone to fail, got {:?}", other.map(|c| c.report.quality)),
    }
    opts.optimize.slide = true;
    let c = run(&mesh, &projector, &opts).unwrap();
    assert_eq!(c.report.quality.n_certified_invalid, 0);
    assert!(c.report.quality.certified_min_q3 > 0.0);
    // The boundary nodes where the projection put them: no adaptive
    // stepping, no optimisation (the mesh comes back with its invalid cell).
    let mut plain = CurveOptions { order: 2, adaptive: Some(false), repair: false, ..Default::default() };
    plain.optimize.enabled = false;
    let placed = run(&mesh, &projector, &plain).unwrap();
    assert!(placed.report.quality.n_certified_invalid > 0);
    let slid = (0..c.mesh.n_nodes())
        .filter(|&n| matches!(c.mesh.constraint[n], NodeConstraint::OnEntity { .. }))
        .filter(|&n| c.mesh.coords[3 * n..3 * n + 3] != placed.mesh.coords[3 * n..3 * n + 3])
        .count();
    assert!(slid > 0, "no boundary node slid");
    assert_on_sphere(&c, 0.6);
}

/// The same tet, with the boundary nodes held: split at its centroid, its
/// pieces have interior edges through the bad edge's ends, and moving
/// their nodes makes it valid. The pieces map to the input cell of the
/// tet they came from, and the domain is the same.
#[test]
fn splitting_a_cell_interior_moves_cannot_fix_makes_it_valid() {
    let (mesh, projector) = gmsh_sphere_cavity("sphere_cavity_cap_gmsh.msh", 0.6);
    let mut opts = CurveOptions { order: 2, repair: false, ..Default::default() };
    opts.optimize.slide = false;
    // The first rounds alone leave it invalid.
    let mut first_rounds = opts.clone();
    first_rounds.optimize.later_rounds = false;
    match run(&mesh, &projector, &first_rounds) {
        Err(Error::InvalidElement { .. }) => {}
        Ok(c) => assert!(c.report.quality.n_certified_invalid > 0 && c.report.optimization.cells_split == 0),
        Err(e) => panic!("{e}"),
    }
    let c = run(&mesh, &projector, &opts).unwrap();
    let o = &c.report.optimization;
    assert!(o.cells_split > 0, "{o:?}");
    assert_eq!(c.report.quality.n_certified_invalid, 0);
    assert_eq!(c.mesh.n_cells(), mesh.n_cells() + 3 * o.cells_split);
    assert_eq!(c.report.input_cell.len(), c.mesh.n_cells());
    // Each input cell is covered once: its pieces' straight volumes add up to its volume.
    let volume = |x: &[f64], v: &[usize]| {
        let d = |a: usize| {
            [x[3 * v[a]] - x[3 * v[0]], x[3 * v[a] + 1] - x[3 * v[0] + 1], x[3 * v[a] + 2] - x[3 * v[0] + 2]]
        };
        let (a, b, e) = (d(1), d(2), d(3));
        (a[0] * (b[1] * e[2] - b[2] * e[1]) - a[1] * (b[0] * e[2] - b[2] * e[0]) + a[2] * (b[0] * e[1] - b[1] * e[0]))
            / 6.0
    };
    let mut sum = vec![0.0; mesh.n_cells()];
    for (k, &i) in c.report.input_cell.iter().enumerate() {
        sum[i] += volume(&c.straight, c.mesh.cell(k));
    }
    for (i, s) in sum.iter().enumerate() {
        let v = volume(&mesh.coords, &mesh.cells[4 * i..4 * i + 4]).abs();
        assert!((s - v).abs() < 1e-12 * v.max(1.0), "input cell {i}: {s} vs {v}");
    }
    assert_on_sphere(&c, 0.6);
}

/// No cell below the threshold: only the polish runs, on the cells near the
/// smallest Q3, and raises it without moving a node off the sphere.
#[test]
fn polishing_raises_the_smallest_quality_when_no_cell_is_below_the_threshold() {
    let (mesh, projector) = coarse_sphere();
    let mut opts = CurveOptions { order: 4, formulation: Formulation::Linear, ..Default::default() };
    opts.optimize.enabled = false;
    let off = run(&mesh, &projector, &opts).unwrap();
    let q_off = off.report.quality.min_q3;
    // Let the threshold sit just under the smallest Q3: no cell is a target.
    opts.optimize.enabled = true;
    opts.optimize.threshold = 0.9 * q_off;
    let on = run(&mesh, &projector, &opts).unwrap();
    let r = &on.report.optimization;
    assert_eq!(r.target_cells, 0);
    assert!(r.ran && r.cells_touched > 0 && r.cells_split == 0, "{r:?}");
    assert!(on.report.quality.min_q3 > q_off + 0.01, "min Q3 {q_off} -> {}", on.report.quality.min_q3);
    assert_eq!(on.report.quality.n_certified_invalid, 0);
    assert_boundary_kept(&on);
}

/// A mesh with nothing curved: every cell stays affine, Q3 = 1 up to
/// round-off, and the stage leaves it alone instead of polishing round-off.
#[test]
fn a_straight_mesh_comes_back_untouched_by_the_optimisation() {
    let mesh = common::kuhn_cube(2, 0.1);
    let projector = ShapeProjector::new();
    let mut opts = CurveOptions { order: 4, ..Default::default() };
    opts.optimize.enabled = false;
    let off = run(&mesh, &projector, &opts).unwrap();
    opts.optimize.enabled = true;
    let on = run(&mesh, &projector, &opts).unwrap();
    let r = &on.report.optimization;
    assert!(!r.ran && r.cells_touched == 0 && r.nodes_moved == 0, "{r:?}");
    assert_eq!(on.mesh.coords, off.mesh.coords);
    assert!(on.report.quality.min_q3 > 0.999_999, "{}", on.report.quality.min_q3);
}

/// The largest distance from the sphere of the curved boundary between its
/// nodes: every cell face whose nodes all lie on the sphere, sampled at the
/// points of the order-2p lattice that are not nodes.
fn largest_distance_between_nodes(c: &CurvedMesh, radius: f64) -> f64 {
    use hocurve::reference::{LagrangeBasis, NodeSet, NodeSpacing};
    let m = &c.mesh;
    let basis = LagrangeBasis::new(&NodeSet::new(m.simplex, m.order, m.spacing));
    let nodes = basis.nodes();
    let lattice = NodeSet::new(m.simplex, 2 * m.order, NodeSpacing::Equispaced);
    let mut values = vec![0.0; basis.len()];
    let mut worst: f64 = 0.0;
    for cell in m.cells.chunks_exact(m.nodes_per_cell()) {
        for o in 0..4 {
            let on_face = |k: &[usize; 4]| k[o] == 0;
            let on_sphere = (0..nodes.len())
                .filter(|&a| on_face(&nodes.multi[a]))
                .all(|a| matches!(m.constraint[cell[a]], NodeConstraint::OnEntity { .. }) || a < 4);
            let vertices_on = (0..4).filter(|&v| v != o).all(|v| {
                let x = m.node(cell[v]);
                ((x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt() - radius).abs() < 1e-12
            });
            if !on_sphere || !vertices_on {
                continue;
            }
            for i in (0..lattice.len()).filter(|&i| on_face(&lattice.multi[i])) {
                basis.eval_into(&lattice.coords[i], &mut values);
                let mut x = [0.0; 3];
                for (a, &w) in values.iter().enumerate() {
                    let y = m.node(cell[a]);
                    (0..3).for_each(|d| x[d] += w * y[d]);
                }
                worst = worst.max(((x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt() - radius).abs());
            }
        }
    }
    worst
}

/// The polish slides boundary nodes along the sphere where that raises the
/// smallest Q3, but keeps a slide only if the boundary between the nodes
/// stays as close to the sphere as before: the largest distance does not
/// grow.
#[test]
fn the_polish_slides_boundary_nodes_without_moving_the_boundary_away_from_the_sphere() {
    let (mesh, projector) = coarse_sphere();
    let mut opts = CurveOptions { order: 4, formulation: Formulation::Linear, ..Default::default() };
    opts.optimize.enabled = false;
    let q_off = run(&mesh, &projector, &opts).unwrap().report.quality.min_q3;
    opts.optimize.enabled = true;
    opts.optimize.threshold = 0.9 * q_off;
    opts.optimize.slide = false;
    let fixed = run(&mesh, &projector, &opts).unwrap();
    opts.optimize.slide = true;
    let sliding = run(&mesh, &projector, &opts).unwrap();
    assert_boundary_kept(&sliding);
    let m = &sliding.mesh;
    let slid = (0..m.n_nodes())
        .filter(|&n| matches!(m.constraint[n], NodeConstraint::OnEntity { .. }) && m.node(n) != fixed.mesh.node(n))
        .count();
    let (d_fixed, d_sliding) =
        (largest_distance_between_nodes(&fixed, RADIUS), largest_distance_between_nodes(&sliding, RADIUS));
    let (q_fixed, q_sliding) = (fixed.report.quality.min_q3, sliding.report.quality.min_q3);
    eprintln!("{slid} nodes slid; min Q3 {q_fixed} -> {q_sliding}; largest distance {d_fixed:e} -> {d_sliding:e}");
    assert!(slid > 0, "no boundary node slid");
    assert!(d_fixed > 0.0 && d_sliding <= d_fixed * (1.0 + 1e-9), "{d_fixed:e} -> {d_sliding:e}");
    assert!(q_sliding >= q_fixed, "min Q3 {q_fixed} -> {q_sliding}");
}

/// `tests/data/torus_cavity_n4_gmsh.msh`: gmsh 4.15's mesh of the box
/// [-1, 1]³ less a torus of radii 0.5 and 0.35 (surface tag 7), four
/// elements per 2π of curvature (`Mesh.MeshSizeFromCurvature` 4,
/// `MeshSizeMax` 0.5, `MeshSizeMin` 0.02). At p = 2 the elastic stage stops
/// short and the optimisation must untangle cells next to each other (an
/// untangling stopped early, at a relative decrease of 1e-4 instead of
/// 1e-6, left a point inverted there).
#[test]
fn a_coarse_gmsh_torus_cavity_is_untangled_where_the_elastic_stage_stops_short() {
    let (mesh, projector) = coarse_torus_n4();
    let c = run(&mesh, &projector, &CurveOptions { order: 2, ..Default::default() }).unwrap();
    assert_eq!(c.report.quality.n_invalid, 0);
    assert!(c.report.elastic_stop.is_some(), "the elastic stage stopped short");
    assert!(c.report.optimization.invalid_before > 0);
    // Sliding in the tangent planes first (for slow projectors): here it
    // does not untangle alone, and the projected slides go on from where
    // it ended (not from where the interior nodes left the patch, which
    // gave the same mesh as without it): another mesh, as valid.
    let optimize = OptimizeOptions { tangent_first: true, ..Default::default() };
    let t = run(&mesh, &projector, &CurveOptions { order: 2, optimize, ..Default::default() }).unwrap();
    assert_eq!(t.report.quality.n_certified_invalid, 0);
    assert_ne!(t.mesh.coords, c.mesh.coords);
}

/// The torus R = 0.5, r = 0.35 about z (tag 7) and gmsh's coarse mesh of
/// the box less it, 4 elements per turn of curvature.
fn coarse_torus_n4() -> (LinearMesh, ShapeProjector) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/torus_cavity_n4_gmsh.msh");
    let mut mesh = hocurve::io::gmsh::to_linear_mesh(&hocurve::io::gmsh::read_msh(&path).unwrap()).unwrap();
    let mut projector = ShapeProjector::new();
    projector.insert(7, Shape::parse("torus:0,0,0,0.5,0.35").unwrap());
    mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    (mesh, projector)
}

/// The C ABI's setting for slow projectors reaches the optimisation: on
/// the coarse torus its sliding asks the projector for other points, and
/// both meshes are certified valid.
#[test]
fn the_c_abi_slides_in_the_tangent_planes_first_when_told() {
    use hocurve::ffi::*;
    let (mesh, _) = coarse_torus_n4();
    let run_c = |tangent_first: std::ffi::c_int| unsafe {
        let mut counted = CountedShape::new(Shape::parse("torus:0,0,0,0.5,0.35").unwrap());
        let mut m = c_handle(&mesh, &mut counted, 2);
        assert_eq!(hoc_mesh_set_tangent_first(m, 2), HOC_ERROR_INVALID_ARGUMENT);
        assert_eq!(hoc_mesh_set_tangent_first(m, tangent_first), HOC_OK);
        assert_eq!(hoc_mesh_run_increments(m, 10), HOC_OK);
        let mut q = std::mem::zeroed::<HocQuality>();
        assert_eq!(hoc_mesh_quality(m, &mut q), HOC_OK);
        assert_eq!(q.n_certified_invalid, 0);
        let mut nn = 0;
        assert_eq!(hoc_mesh_node_count(m, &mut nn), HOC_OK);
        let mut coords = vec![0.0; 3 * nn];
        assert_eq!(hoc_mesh_get_nodes(m, HOC_ORDERING_NATIVE, nn, coords.as_mut_ptr()), HOC_OK);
        hoc_mesh_destroy(&mut m);
        (coords, counted.points)
    };
    let (projected, calls) = run_c(0);
    let (tangent, tangent_calls) = run_c(1);
    assert_ne!(projected, tangent, "the setting did not change where the nodes slide");
    assert_ne!(calls, tangent_calls, "the setting did not change how the nodes slide");
}

/// The C ABI says where a run's time went: nothing before a run; after
/// it, every stage that ran took time, the optimisation's own figure is
/// within its stage, and the stages fit in the total.
#[test]
fn the_c_abi_says_where_the_time_went() {
    use hocurve::ffi::*;
    let (mesh, _) = coarse_torus_n4();
    unsafe {
        let mut counted = CountedShape::new(Shape::parse("torus:0,0,0,0.5,0.35").unwrap());
        let mut m = c_handle(&mesh, &mut counted, 2);
        let mut t = HocTimings { total: -1.0, ..Default::default() };
        assert_eq!(hoc_mesh_timings(m, std::ptr::null_mut()), HOC_ERROR_NULL_POINTER);
        assert_eq!(hoc_mesh_timings(m, &mut t), HOC_OK);
        assert_eq!(t.total, 0.0, "before any run");
        assert_eq!(hoc_mesh_run_increments(m, 10), HOC_OK);
        assert_eq!(hoc_mesh_timings(m, &mut t), HOC_OK);
        let mut o = std::mem::zeroed::<HocOptimization>();
        assert_eq!(hoc_mesh_optimization(m, &mut o), HOC_OK);
        hoc_mesh_destroy(&mut m);
        let stages = [
            t.repair_and_elevate,
            t.place_boundary,
            t.assembly,
            t.solver_setup,
            t.solve,
            t.check,
            t.optimize,
            t.quality,
        ];
        println!("{t:?}");
        assert!(stages[..7].iter().all(|&s| s > 0.0), "a stage that ran took no time: {t:?}");
        assert!(o.ran == 1 && t.optimize >= o.seconds, "{t:?}, optimisation {} s", o.seconds);
        assert!(stages.iter().sum::<f64>() <= t.total, "{t:?}");
    }
}

/// The elastic stage as one process's part of a distributed run
/// (`Parallel::Part`), with a collective of one process: every decision
/// goes through the agreement the MPI runs take, and the run must be
/// bitwise the serial one.
mod one_part {
    use std::sync::Arc;

    use hocurve::assembly::LinearElasticKernel;
    use hocurve::curve::{
        solve_increments_from, Collective, ElasticBackend, IncrementsReport, Parallel, Stage, Stepping, Timings,
    };
    use hocurve::material::LinearElastic;
    use hocurve::mesh::HighOrderMesh;
    use hocurve::reference::NodeSet;

    struct Alone;
    impl Collective for Alone {
        fn first(&self, local: Option<(u64, String)>) -> Option<(u64, String)> {
            local
        }
        fn global_cell(&self, local: usize) -> usize {
            local
        }
    }

    pub struct OnePart;
    impl ElasticBackend for OnePart {
        fn solve_increments(
            &self,
            mesh: &mut HighOrderMesh,
            material: LinearElastic,
            ubar: &[f64],
            stepping: &Stepping,
            rate: Option<&[f64]>,
            timings: &mut Timings,
            tick: &mut dyn FnMut(Stage, usize, usize) -> hocurve::Result<()>,
        ) -> hocurve::Result<IncrementsReport> {
            let kernel =
                LinearElasticKernel::for_nodes(&NodeSet::new(mesh.simplex, mesh.order, mesh.spacing), material);
            let part = Stepping { parallel: Parallel::Part(Arc::new(Alone)), ..stepping.clone() };
            solve_increments_from(mesh, &kernel, ubar, part, rate, timings, tick)
        }
    }
}

#[test]
fn the_elastic_stage_as_one_part_of_a_distributed_run_is_the_serial_one() {
    // p = 3 on the coarse cavity of radius 0.6: adaptive stepping steps
    // back, then stops short, and the optimisation finishes the mesh.
    let (mesh, projector) = coarse_sphere_06();
    let serial = run(&mesh, &projector, &p3(true)).unwrap();
    let mut opts = p3(true);
    opts.parallel = hocurve::curve::Parallel::Lead(std::sync::Arc::new(one_part::OnePart));
    let part = run(&mesh, &projector, &opts).unwrap();
    assert!(!serial.report.step_backs.is_empty() && serial.report.elastic_stop.is_some());
    assert_eq!(serial.report.step_backs, part.report.step_backs);
    assert_eq!(serial.report.load_fractions, part.report.load_fractions);
    // The same to rounding: the serial run solves its later increments from
    // the cells' products, a distributed one from the assembled matrix.
    assert!(serial.report.solves.by_products > 0 && part.report.solves.by_products == 0);
    let off = serial.mesh.coords.iter().zip(&part.mesh.coords).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(off < 1e-9, "{off:e}");
    // The other formulations are refused, not run serially.
    opts.formulation = Formulation::Cil;
    opts.material = hocurve::material::MaterialModel::NeoHookean;
    let refused = run(&mesh, &projector, &opts).unwrap_err();
    assert!(refused.to_string().contains("distributed run"), "{refused}");
}
