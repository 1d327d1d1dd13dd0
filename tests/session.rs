//! Session semantics: setters validate, failed runs leave the mesh bitwise
//! unchanged, cancellation works, results do not depend on the thread count.

use hocurve::cases;
use hocurve::curve::Progress;
use hocurve::geometry::Projector;
use hocurve::reference::NodeSpacing;
use hocurve::session::{Session, MAX_THREADS};
use hocurve::Error;

/// Projects onto the circle r = 0.5, then spoils the answer as asked.
struct Faulty(&'static str);

impl Projector for Faulty {
    fn project(&self, _: usize, _: i32, pts: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
        if self.0 == "error" {
            return Err("CAD kernel said no".into());
        }
        for (o, p) in out.iter_mut().zip(pts) {
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            *o = [0.5 * p[0] / r, 0.5 * p[1] / r, 0.0];
            match self.0 {
                "nan" => o[0] = f64::NAN,
                "far" => o[0] += 100.0,
                _ => {}
            }
        }
        Ok(())
    }
}

fn session() -> Session {
    let case = cases::annulus_2d(0.5, 1.0, 12, 2);
    let mut s = Session::try_new(case.mesh.clone()).unwrap();
    let (facets, tags): (Vec<Vec<usize>>, Vec<i32>) = case
        .mesh
        .facets
        .chunks_exact(2)
        .zip(&case.mesh.facet_tags)
        .filter(|(_, &t)| t == 1)
        .map(|(f, &t)| (f.to_vec(), t))
        .unzip();
    s.set_boundary(facets.concat(), tags).unwrap();
    s.set_order(3, NodeSpacing::Optimal).unwrap();
    s
}

#[test]
fn failed_runs_leave_the_mesh_bitwise_unchanged() {
    for (mode, expect) in [("error", "projection"), ("nan", "non-finite"), ("far", "more than the size")] {
        let mut s = session();
        s.set_projector(Some(Box::new(Faulty(mode))));
        let before = s.mesh().coords.clone();
        let e = s.run(2).unwrap_err();
        assert!(matches!(e, Error::Projection(_)), "{mode}: {e}");
        assert!(e.to_string().contains(expect), "{mode}: {e}");
        assert_eq!(before, s.mesh().coords, "{mode}: mesh changed");
        assert!(s.report().is_none());
    }
}

#[test]
fn a_failed_run_with_new_settings_keeps_the_mesh_and_the_settings() {
    let mut s = session();
    s.set_projector(Some(Box::new(Faulty("ok"))));
    s.run(2).unwrap();
    let (coords, report, opts) = (s.mesh().coords.clone(), s.report().cloned().unwrap(), s.options().clone());
    s.set_projector(Some(Box::new(Faulty("error"))));
    // A new order (another mesh to curve) and a new material, then a failure.
    let next = hocurve::CurveOptions { order: 4, poisson: 0.3, ..opts.clone() };
    assert!(matches!(s.run_with(next.clone(), 2), Err(Error::Projection(_))));
    assert_eq!(s.mesh().coords, coords);
    assert_eq!(s.mesh().order, 3);
    assert_eq!(s.report().unwrap().quality.min_q3, report.quality.min_q3);
    assert_eq!((s.options().order, s.options().poisson), (opts.order, opts.poisson));
    // With a working projector the same settings are kept with the mesh.
    s.set_projector(Some(Box::new(Faulty("ok"))));
    s.run_with(next.clone(), 2).unwrap();
    assert_eq!((s.mesh().order, s.options().order, s.options().poisson), (4, 4, 0.3));
}

#[test]
fn cancelling_from_the_progress_callback_stops_the_run() {
    let mut s = session();
    s.set_projector(Some(Box::new(Faulty("ok"))));
    let before = s.mesh().coords.clone();
    s.set_progress(Some(Box::new(|p: &Progress| p.step < 2)));
    assert_eq!(s.run(5).unwrap_err(), Error::Cancelled);
    assert_eq!(before, s.mesh().coords);
    s.set_progress(None);
    s.run(5).unwrap();
    assert_ne!(before, s.mesh().coords);
    assert_eq!(s.quality().n_invalid, 0);
}

#[test]
fn bad_settings_are_rejected_and_change_nothing() {
    let mut s = session();
    let before = s.mesh().coords.clone();
    assert!(s.set_order(0, NodeSpacing::Optimal).is_err());
    assert!(s.set_order(11, NodeSpacing::Optimal).is_err());
    assert!(s.set_boundary(vec![0, 99999], vec![1]).is_err());
    assert!(s.run(0).is_err());
    assert_eq!(s.options().order, 3);
    assert_eq!(before, s.mesh().coords);
    // Tagged boundary without a projector is an error, not a silent straight mesh.
    assert!(matches!(s.run(1), Err(Error::InvalidInput(m)) if m.contains("no projector")));
}

#[test]
fn results_are_bitwise_identical_for_any_thread_count() {
    let mut a = session();
    let mut b = session();
    a.set_projector(Some(Box::new(Faulty("ok"))));
    b.set_projector(Some(Box::new(Faulty("ok"))));
    a.set_threads(1).unwrap();
    b.set_threads(2).unwrap();
    a.run(3).unwrap();
    b.run(3).unwrap();
    // Coloured assembly is deterministic: bitwise the same.
    assert_eq!(a.mesh().coords, b.mesh().coords);
}

#[test]
fn a_thread_count_above_the_limit_is_refused_and_changes_nothing() {
    let mut s = session();
    s.set_threads(2).unwrap();
    for n in [MAX_THREADS + 1, 1 << 31, usize::MAX] {
        assert!(matches!(s.set_threads(n), Err(Error::InvalidInput(m)) if m.contains("at most")), "{n}");
        assert_eq!(s.threads(), 2);
    }
    s.set_threads(MAX_THREADS).unwrap();
    assert_eq!(s.threads(), MAX_THREADS);
}

/// Leaves every point where it is.
struct Identity;

impl Projector for Identity {
    fn project(&self, _: usize, _: i32, pts: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
        out.copy_from_slice(pts);
        Ok(())
    }
}

#[test]
fn boundary_caps_are_removed_when_the_boundary_is_set_and_can_be_kept() {
    use hocurve::mesh::LinearMesh;
    // A flat cap (0, 1, 2, 3) under the ridge 01 (both faces tag 1) on two tets.
    let mesh = LinearMesh {
        dim: 3,
        coords: vec![0.0, 0.0, 0.05, 1.0, 0.0, 0.05, 0.5, 1.0, 0.0, 0.5, -1.0, 0.0, 0.5, 0.0, -1.0],
        cells: vec![0, 1, 2, 3, 0, 2, 3, 4, 1, 2, 3, 4],
        facets: vec![],
        facet_tags: vec![],
        feature_edges: vec![],
        feature_edge_tags: vec![],
    };
    let mut s = Session::try_new(mesh).unwrap();
    assert_eq!(s.mesh().n_cells(), 3);
    s.set_boundary(vec![0, 1, 2, 0, 1, 3, 0, 2, 4, 1, 2, 4, 0, 3, 4, 1, 3, 4], vec![1, 1, 2, 2, 3, 3]).unwrap();
    assert_eq!(s.mesh().n_cells(), 2);
    assert_eq!(s.input_cells(), &[1, 2]);
    // Fibres are given per input cell whatever was removed.
    s.set_fibres(Some(vec![[1.0, 0.0, 0.0]; 3])).unwrap();
    s.set_order(2, NodeSpacing::Optimal).unwrap();
    s.set_projector(Some(Box::new(Identity)));
    s.run(1).unwrap();
    let report = s.report().unwrap();
    assert_eq!((report.removed_caps, report.cells), (1, 2));
    assert_eq!(report.input_cell, vec![1, 2]);
    assert_eq!(s.quality().n_invalid, 0);
    s.set_remove_caps(false).unwrap();
    assert_eq!(s.mesh().n_cells(), 3);
    assert_eq!(s.input_cells(), &[0, 1, 2]);
    assert!(s.report().is_none(), "changing the cells discards the curved result");
}

/// The annulus of [`session`] as a plain mesh: only the inner circle tagged.
fn annulus_inner_tagged() -> hocurve::mesh::LinearMesh {
    let mut mesh = cases::annulus_2d(0.5, 1.0, 12, 2).mesh;
    mesh.retain_tags(|_, t| t == 1);
    mesh
}

#[test]
fn a_session_curves_its_prepared_mesh_as_curve_does_the_mesh_given() {
    use hocurve::curve::{curve, curve_prepared, CurveOptions, Prepared};
    let mut s = session();
    s.set_projector(Some(Box::new(Faulty("ok"))));
    s.run(2).unwrap();
    let mesh = annulus_inner_tagged();
    let opts = CurveOptions { order: 3, increments: 2, ..Default::default() };
    let direct = curve(&mesh, &Faulty("ok"), &opts, &mut |_| true).unwrap();
    assert_eq!(s.mesh().coords, direct.mesh.coords, "the session's run differs from curve()");
    // One preparation, curved twice: the same mesh each time.
    let prepared = Prepared::new(&mesh, &opts).unwrap();
    for _ in 0..2 {
        let again = curve_prepared(&prepared, &Faulty("ok"), &opts, &mut |_| true).unwrap();
        assert_eq!(again.mesh.coords, direct.mesh.coords);
    }
    // Bad options are refused when preparing, as when curving.
    let e = Prepared::new(&mesh, &CurveOptions { order: 11, ..opts.clone() }).unwrap_err();
    assert!(matches!(&e, Error::InvalidInput(m) if m.contains("order must be between 1 and 10")), "{e}");
    // A preparation for another order is refused, not silently used.
    let e = curve_prepared(&prepared, &Faulty("ok"), &CurveOptions { order: 4, ..opts }, &mut |_| true).unwrap_err();
    assert!(matches!(&e, Error::InvalidInput(m) if m.contains("prepared for order 3")), "{e}");
}

#[test]
fn the_report_counts_the_cells_the_session_reoriented() {
    let mut mesh = annulus_inner_tagged();
    mesh.cells.swap(0, 1); // cell 0 now negatively oriented
    let mut s = Session::try_new(mesh).unwrap();
    s.set_order(2, NodeSpacing::Optimal).unwrap();
    s.set_projector(Some(Box::new(Faulty("ok"))));
    s.run(1).unwrap();
    assert_eq!(s.report().unwrap().reoriented_cells, 1);
}
