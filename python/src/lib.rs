//! `hocurve._native`: the engine's [`Session`] for Python.
//!
//! The Python package (`python/hocurve/`) wraps this module in its public
//! API; nothing here is meant to be called directly. Arrays come in as
//! numpy arrays and go out as new numpy arrays. A run releases the GIL and
//! takes it back only to call a Python projector or progress callback, and
//! to check for Ctrl-C between stages.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};

use hocurve::curve::{Formulation, Progress, Stage};
use hocurve::geometry::{Projector, Shape, ShapeProjector};
use hocurve::io;
use hocurve::material::MaterialModel;
use hocurve::mesh::LinearMesh;
use hocurve::reference::NodeSpacing;
use hocurve::session::{NodeOrdering, Session};
use hocurve::solver::SolverChoice;
use hocurve::Error;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyException, PyRuntimeError};
use pyo3::prelude::*;

pyo3::create_exception!(_native, HocurveError, PyException, "An error of hocurve, with its status.");

/// The Python exception of a hocurve error: `HocurveError(message)` with
/// `status` set to the kind of error (the Python layer maps it to its
/// subclasses).
fn py_error(py: Python<'_>, e: &Error) -> PyErr {
    let status = match e {
        Error::InvalidInput(_) => "invalid-input",
        Error::Projection(_) => "projection",
        Error::Solver { .. } => "solver",
        Error::InvalidElement { .. } => "invalid-element",
        Error::Io(_) => "io",
        Error::Cancelled => "cancelled",
        _ => "error",
    };
    let err = HocurveError::new_err((status, e.to_string()));
    if let Err(set) = err.value(py).setattr("status", status) {
        return set;
    }
    err
}

fn invalid(message: impl Into<String>) -> Error {
    Error::InvalidInput(message.into())
}

/// Indices of an (n, k) array, checked non-negative.
fn indices(a: &PyReadonlyArray2<'_, i64>, what: &str, k: usize) -> Result<Vec<usize>, Error> {
    let view = a.as_array();
    if view.ncols() != k {
        return Err(invalid(format!("{what} must have {k} columns, got {}", view.ncols())));
    }
    view.iter().map(|&i| usize::try_from(i).map_err(|_| invalid(format!("{what}: negative index {i}")))).collect()
}

fn tags(a: &PyReadonlyArray1<'_, i32>, what: &str, n: usize) -> Result<Vec<i32>, Error> {
    let t: Vec<i32> = a.as_array().iter().copied().collect();
    if t.len() != n {
        return Err(invalid(format!("{what}: {} tags for {n} entries", t.len())));
    }
    Ok(t)
}

/// A Python callable `f(entity_dim, tag, points) -> (k, 3) array` as the
/// engine's projector. Its exception, if it raises, is kept to be chained
/// to the error the run ends with.
struct PyProjector {
    f: Py<PyAny>,
    raised: Arc<Mutex<Option<PyErr>>>,
}

impl Projector for PyProjector {
    fn project(&self, entity_dim: usize, tag: i32, points: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
        Python::attach(|py| {
            let n = points.len();
            let flat: Vec<f64> = points.iter().flatten().copied().collect();
            let array = Array2::from_shape_vec((n, 3), flat).expect("n points of 3").into_pyarray(py);
            let call = || -> PyResult<()> {
                let got = self.f.call1(py, (entity_dim, tag, array))?;
                let np = py.import("numpy")?;
                let got = np.call_method1("ascontiguousarray", (got, "float64"))?;
                let got: PyReadonlyArray2<'_, f64> = got.extract().map_err(|_| {
                    PyRuntimeError::new_err(format!("the projector must return an ({n}, 3) array of floats"))
                })?;
                let view = got.as_array();
                if view.dim() != (n, 3) {
                    return Err(PyRuntimeError::new_err(format!(
                        "the projector returned shape {:?} for {n} points, expected ({n}, 3)",
                        view.shape()
                    )));
                }
                for (o, row) in out.iter_mut().zip(view.rows()) {
                    *o = [row[0], row[1], row[2]];
                }
                Ok(())
            };
            call().map_err(|e| {
                let message = format!("Python projector (entity {entity_dim}, tag {tag}): {e}");
                let mut slot = self.raised.lock().unwrap_or_else(|p| p.into_inner());
                slot.get_or_insert(e);
                message
            })
        })
    }
}

fn stage_name(s: Stage) -> &'static str {
    match s {
        Stage::Elevate => "elevate",
        Stage::Project => "project",
        Stage::Increment => "increment",
        Stage::Quality => "quality",
        Stage::Optimize => "optimize",
    }
}

fn ordering(name: &str) -> PyResult<NodeOrdering> {
    match name {
        "gmsh" => Ok(NodeOrdering::Gmsh),
        "vtk" => Ok(NodeOrdering::Vtk),
        "native" => Ok(NodeOrdering::Native),
        other => Err(pyo3::exceptions::PyValueError::new_err(format!(
            "unknown node ordering '{other}' (gmsh, vtk or native)"
        ))),
    }
}

/// A curving session: the linear mesh, its settings and its current mesh.
#[pyclass(module = "hocurve._native")]
struct NativeMesh {
    session: Mutex<Session>,
    /// The exception a Python projector raised during the last run.
    raised: Arc<Mutex<Option<PyErr>>>,
    /// The settings of the next run ([`NativeMesh::configure`]).
    pending: Mutex<Option<hocurve::CurveOptions>>,
}

impl NativeMesh {
    /// The session, or an error if another thread is running it.
    fn lock(&self, py: Python<'_>) -> PyResult<MutexGuard<'_, Session>> {
        match self.session.try_lock() {
            Ok(s) => Ok(s),
            Err(TryLockError::Poisoned(p)) => Ok(p.into_inner()),
            Err(TryLockError::WouldBlock) => {
                Err(py_error(py, &invalid("the mesh is busy with a run in another thread")))
            }
        }
    }

    fn with<R>(&self, py: Python<'_>, f: impl FnOnce(&mut Session) -> Result<R, Error>) -> PyResult<R> {
        f(&mut *self.lock(py)?).map_err(|e| py_error(py, &e))
    }
}

#[pymethods]
impl NativeMesh {
    #[new]
    fn new(py: Python<'_>, vertices: PyReadonlyArray2<'_, f64>, cells: PyReadonlyArray2<'_, i64>) -> PyResult<Self> {
        let build = || -> Result<Session, Error> {
            let v = vertices.as_array();
            let dim = v.ncols();
            if dim != 2 && dim != 3 {
                return Err(invalid(format!("vertices must have 2 or 3 columns, got {dim}")));
            }
            let cells = indices(&cells, "cells", dim + 1)?;
            let linear = LinearMesh { dim, coords: v.iter().copied().collect(), cells, ..Default::default() };
            Session::try_new(linear)
        };
        let session = build().map_err(|e| py_error(py, &e))?;
        Ok(NativeMesh { session: Mutex::new(session), raised: Arc::default(), pending: Mutex::default() })
    }

    #[getter]
    fn dim(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |s| Ok(s.dim()))
    }

    fn set_boundary(
        &self,
        py: Python<'_>,
        facets: PyReadonlyArray2<'_, i64>,
        tags_: PyReadonlyArray1<'_, i32>,
    ) -> PyResult<()> {
        self.with(py, |s| {
            let d = s.dim();
            let f = indices(&facets, "facets", d)?;
            let t = tags(&tags_, "facet tags", f.len() / d)?;
            s.set_boundary(f, t)
        })
    }

    fn set_feature_edges(
        &self,
        py: Python<'_>,
        edges: PyReadonlyArray2<'_, i64>,
        tags_: PyReadonlyArray1<'_, i32>,
    ) -> PyResult<()> {
        self.with(py, |s| {
            let e = indices(&edges, "feature edges", 2)?;
            let t = tags(&tags_, "feature edge tags", e.len() / 2)?;
            s.set_feature_edges(e, t)
        })
    }

    fn set_straight(&self, py: Python<'_>, entity_dim: usize, tags_: Vec<i32>) -> PyResult<()> {
        self.with(py, |s| s.set_straight_tags(entity_dim, &tags_))
    }

    /// The built-in analytic shapes: (tag, shape in the command line's syntax).
    fn set_shapes(&self, py: Python<'_>, shapes: Vec<(i32, String)>) -> PyResult<()> {
        self.with(py, |s| {
            let mut p = ShapeProjector::new();
            for (tag, shape) in &shapes {
                p.insert(*tag, Shape::parse(shape)?);
            }
            s.set_projector(Some(Box::new(p)));
            Ok(())
        })
    }

    fn set_projector(&self, py: Python<'_>, f: Py<PyAny>) -> PyResult<()> {
        let raised = Arc::clone(&self.raised);
        self.with(py, |s| {
            s.set_projector(Some(Box::new(PyProjector { f, raised })));
            Ok(())
        })
    }

    /// Every setting of the next run at once, validated here and applied by
    /// [`NativeMesh::run`] only if that run succeeds.
    #[allow(clippy::too_many_arguments)]
    fn configure(
        &self,
        py: Python<'_>,
        order: usize,
        spacing: &str,
        formulation: &str,
        material: Option<&str>,
        young: f64,
        poisson: f64,
        tolerance: f64,
        max_iterations: usize,
        adaptive: Option<bool>,
        max_splits: usize,
        remove_caps: bool,
        retry: bool,
        repair: bool,
        condense: bool,
        optimize: bool,
        tangent_first: bool,
        solver: &str,
        threads: usize,
    ) -> PyResult<()> {
        self.with(py, |s| {
            let spacing = match spacing {
                "optimal" => NodeSpacing::Optimal,
                "equispaced" => NodeSpacing::Equispaced,
                other => return Err(invalid(format!("unknown spacing '{other}' (optimal or equispaced)"))),
            };
            let formulation = Formulation::parse(formulation)?;
            // As the command line: linear for LINEAR/ILE, neo-Hookean for the others.
            let material = match material {
                Some(m) => MaterialModel::parse(m)?,
                None if matches!(formulation, Formulation::Iil | Formulation::Cil | Formulation::Nonlinear) => {
                    MaterialModel::NeoHookean
                }
                None => MaterialModel::LinearElastic,
            };
            // Validated now, applied by the next run (with it, or not at all).
            let mut opts = hocurve::CurveOptions {
                order,
                spacing,
                formulation,
                material,
                young,
                poisson,
                tolerance,
                max_iterations,
                adaptive,
                max_splits,
                remove_caps,
                retry_keep_caps: retry,
                repair,
                condense,
                solver: SolverChoice::parse(solver)?,
                ..s.options().clone()
            };
            opts.optimize.enabled = optimize;
            opts.optimize.tangent_first = tangent_first;
            hocurve::curve::validate_options(&opts)?;
            s.set_threads(threads)?;
            *self.pending.lock().unwrap_or_else(|p| p.into_inner()) = Some(opts);
            Ok(())
        })
    }

    /// Curve in `increments` load increments, the GIL released.
    /// `progress(stage, step, total)` is called between stages; a false
    /// return cancels. Ctrl-C cancels too (KeyboardInterrupt is raised).
    #[pyo3(signature = (increments, progress=None))]
    fn run(&self, py: Python<'_>, increments: usize, progress: Option<Py<PyAny>>) -> PyResult<()> {
        let mut s = self.lock(py)?;
        self.raised.lock().unwrap_or_else(|p| p.into_inner()).take();
        // Ctrl-C: Python runs its signal handlers on the main thread only,
        // so the calling thread watches for them while a thread of ours
        // runs the session; the progress callback then cancels the run.
        let cancel = Arc::new(AtomicBool::new(false));
        let failed: Arc<Mutex<Option<PyErr>>> = Arc::default();
        let (stop, slot) = (Arc::clone(&cancel), Arc::clone(&failed));
        s.set_progress(Some(Box::new(move |p: &Progress| {
            if stop.load(Ordering::Relaxed) {
                return false;
            }
            let Some(f) = &progress else { return true };
            Python::attach(|py| {
                let go_on = f
                    .call1(py, (stage_name(p.stage), p.step, p.total))
                    .and_then(|r| Ok(r.is_none(py) || r.is_truthy(py)?));
                go_on.unwrap_or_else(|e| {
                    slot.lock().unwrap_or_else(|p| p.into_inner()).get_or_insert(e);
                    false
                })
            })
        })));
        let opts = self.pending.lock().unwrap_or_else(|p| p.into_inner()).take();
        let opts = opts.unwrap_or_else(|| s.options().clone());
        let session: &mut Session = &mut s;
        let result = py.detach(|| {
            let watcher = std::thread::current();
            std::thread::scope(|scope| {
                let run = std::thread::Builder::new()
                    .name("hocurve-run".into())
                    .spawn_scoped(scope, || {
                        let r = session.run_with(opts, increments);
                        watcher.unpark();
                        r
                    })
                    .map_err(|e| format!("cannot start the run's thread: {e}"))?;
                while !run.is_finished() {
                    std::thread::park_timeout(std::time::Duration::from_millis(50));
                    if let Err(e) = Python::attach(|py| py.check_signals()) {
                        failed.lock().unwrap_or_else(|p| p.into_inner()).get_or_insert(e);
                        cancel.store(true, Ordering::Relaxed);
                    }
                }
                run.join().map_err(|_| "internal error: the run panicked; the mesh is unchanged".to_string())
            })
        });
        s.set_progress(None);
        drop(s);
        match result {
            Err(internal) => Err(PyRuntimeError::new_err(internal)),
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => {
                if let Some(raised) = failed.lock().unwrap_or_else(|p| p.into_inner()).take() {
                    return Err(raised);
                }
                let err = py_error(py, &e);
                if let Some(cause) = self.raised.lock().unwrap_or_else(|p| p.into_inner()).take() {
                    err.set_cause(py, Some(cause));
                }
                Err(err)
            }
        }
    }

    /// Node coordinates of the current mesh, (n, dim), for cells in `ordering`.
    fn nodes<'py>(&self, py: Python<'py>, ordering_: &str) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let o = ordering(ordering_)?;
        let (dim, flat) = self.with(py, |s| Ok((s.dim(), s.nodes(o).into_owned())))?;
        let n = flat.len() / dim;
        Ok(Array2::from_shape_vec((n, dim), flat).expect("n nodes of dim").into_pyarray(py))
    }

    /// Cell connectivity of the current mesh, (cells, nodes per cell).
    fn cells<'py>(&self, py: Python<'py>, ordering_: &str) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let o = ordering(ordering_)?;
        let (npc, flat) = self.with(py, |s| Ok((s.mesh().nodes_per_cell(), s.cells(o))))?;
        let flat: Vec<i64> = flat.into_iter().map(|i| i as i64).collect();
        let m = flat.len() / npc;
        Ok(Array2::from_shape_vec((m, npc), flat).expect("cells of npc nodes").into_pyarray(py))
    }

    /// Per node of the current mesh: (entity dim, tag) of the geometry it
    /// lies on, (-1, 0) for an interior node, (-2, 0) for a node held fixed.
    fn node_entities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        use hocurve::mesh::NodeConstraint;
        let flat = self.with(py, |s| {
            Ok(s.mesh()
                .constraint
                .iter()
                .flat_map(|c| match *c {
                    NodeConstraint::Free => [-1, 0],
                    NodeConstraint::Fixed => [-2, 0],
                    NodeConstraint::OnEntity { dim, tag } => [dim as i64, tag as i64],
                })
                .collect::<Vec<i64>>())
        })?;
        let n = flat.len() / 2;
        Ok(Array2::from_shape_vec((n, 2), flat).expect("pairs").into_pyarray(py))
    }

    /// Q1, Q2, Q3 of each cell of the current mesh, (cells, 3).
    fn cell_quality<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat = self.with(py, |s| Ok(s.cell_quality().iter().flat_map(|q| [q.q1, q.q2, q.q3]).collect()))?;
        let flat: Vec<f64> = flat;
        let m = flat.len() / 3;
        Ok(Array2::from_shape_vec((m, 3), flat).expect("triples").into_pyarray(py))
    }

    /// For each cell of the current mesh, the index of the input cell it comes from.
    fn input_cells<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let v: Vec<i64> = self.with(py, |s| Ok(s.input_cells().iter().map(|&c| c as i64).collect()))?;
        Ok(v.into_pyarray(py))
    }

    /// The JSON report of the last run (the command line's), or None before one.
    fn report_json(&self, py: Python<'_>) -> PyResult<Option<String>> {
        self.with(py, |s| {
            let spacing = s.options().spacing;
            Ok(s.report().map(|r| io::report::curve_report_json(r, spacing, None)))
        })
    }

    /// The quality of the current mesh as JSON (the report's quality fields).
    fn quality_json(&self, py: Python<'_>) -> PyResult<String> {
        self.with(py, |s| Ok(format!("{{\n{}\n}}", io::report::quality_json(s.quality()))))
    }

    /// Write the current mesh (`.msh` or `.vtu`) with its cell qualities.
    fn write(&self, py: Python<'_>, path: std::path::PathBuf) -> PyResult<()> {
        self.with(py, |s| {
            io::check_mesh_extension(&path)?;
            io::write_mesh(&path, s.mesh(), Some(s.cell_quality()))
        })
    }
}

/// One of the command line's demonstration cases as arrays: vertices,
/// cells, facets and their tags, feature edges and their tags, the shapes
/// (tag, shape in the command line's syntax) and a description.
type DemoArrays<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<i64>>,
    Bound<'py, PyArray2<i64>>,
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray2<i64>>,
    Bound<'py, PyArray1<i32>>,
    Vec<(i32, String)>,
    String,
);

/// `cylinder-2d` and `sphere-3d`, exactly as `hocurve demo` curves them.
#[pyfunction]
fn demo_case<'py>(py: Python<'py>, name: &str) -> PyResult<DemoArrays<'py>> {
    let case = match name {
        "cylinder-2d" => hocurve::cases::cylinder_channel_2d(48, 8, 100.0),
        "sphere-3d" => hocurve::cases::sphere_in_box_3d(3, 3),
        other => {
            return Err(py_error(py, &invalid(format!("unknown demo case '{other}' (cylinder-2d or sphere-3d)"))));
        }
    };
    let m = &case.mesh;
    let d = m.dim;
    let ints = |v: &[usize], k: usize| {
        let flat: Vec<i64> = v.iter().map(|&i| i as i64).collect();
        Array2::from_shape_vec((v.len() / k, k), flat).expect("rows of k").into_pyarray(py)
    };
    let coords = Array2::from_shape_vec((m.coords.len() / d, d), m.coords.clone()).expect("rows of dim");
    let shapes = case.projector.iter().map(|(&(_, tag), shape)| (tag, shape.to_string())).collect();
    Ok((
        coords.into_pyarray(py),
        ints(&m.cells, d + 1),
        ints(&m.facets, d),
        m.facet_tags.clone().into_pyarray(py),
        ints(&m.feature_edges, 2),
        m.feature_edge_tags.clone().into_pyarray(py),
        shapes,
        case.description,
    ))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeMesh>()?;
    m.add_function(wrap_pyfunction!(demo_case, m)?)?;
    m.add("HocurveError", m.py().get_type::<HocurveError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
