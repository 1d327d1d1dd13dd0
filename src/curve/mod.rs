//! The one orchestrator: elevate, project, solve in load increments, measure.
//!
//! [`curve`] takes a linear mesh and a projector and returns a new curved
//! mesh; the input is never modified, so a failed run leaves nothing
//! half-curved. The load increments of the elastic stage are in
//! `stepping.rs`.

use std::borrow::Cow;
use std::time::Instant;

use crate::assembly::{LinearElasticKernel, MaterialKernel, TangentMode};
use crate::geometry::{place_boundary_nodes, BoundaryPlacement, Projector};
use crate::mapping::ElementCache;
use crate::material::{checked_fibres, make_material, LinearElastic, Material, MaterialModel};
use crate::mesh::{repair_with, HighOrderMesh, LinearMesh, RepairSummary, Topology};
use crate::optimize;
pub use crate::optimize::{OptimizeOptions, OptimizeReport};
use crate::quadrature::simplex_rule;
use crate::quality::{self, ElementQuality, MeshQuality};
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use crate::solver::{DirectOrdering, SolveLog, SolverChoice};
use crate::{Error, Result, SolverFailure};

mod parallel;
mod prepare;
mod stepping;

pub use crate::material::default_fibres;
pub use parallel::{Collective, ElasticBackend, Parallel};
pub use prepare::Prepared;
pub use stepping::{ElasticStop, StepBack, StepBackReason, DEFAULT_MAX_SPLITS, MAX_SPLITS};
// The elastic stage on its own, for the crate's tests.
#[cfg(feature = "internals")]
pub use stepping::{add_rate, solve_increments, solve_increments_from, Predictor};
#[cfg(not(feature = "internals"))]
pub(crate) use stepping::{solve_increments, solve_increments_from};
pub use stepping::{IncrementsReport, Stepping};

/// The solid-mechanics formulation (paper Table 1).
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Formulation {
    /// Classical linear elasticity: one solve on the straight mesh.
    Linear,
    /// Incremental linear elasticity: n solves, each on the updated geometry.
    Ile,
    /// Inconsistent incrementally linearised: c_0 on Ω_n, residual stresses.
    Iil,
    /// Consistent incrementally linearised: c_n + geometric stiffness, residual.
    Cil,
    /// Newton–Raphson on the hyperelastic problem in each increment.
    Nonlinear,
}

impl Formulation {
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Linear => "linear",
            Formulation::Ile => "ile",
            Formulation::Iil => "iil",
            Formulation::Cil => "cil",
            Formulation::Nonlinear => "nonlinear",
        }
    }
    pub fn parse(s: &str) -> Result<Formulation> {
        match s.to_ascii_lowercase().as_str() {
            "linear" => Ok(Formulation::Linear),
            "ile" => Ok(Formulation::Ile),
            "iil" => Ok(Formulation::Iil),
            "cil" => Ok(Formulation::Cil),
            "nonlinear" => Ok(Formulation::Nonlinear),
            _ => Err(Error::InvalidInput(format!(
                "unknown formulation '{s}' (expected linear, ile, iil, cil or nonlinear)"
            ))),
        }
    }
}

/// Everything that steers a run.
#[derive(Debug, Clone)]
pub struct CurveOptions {
    /// Polynomial order p, 1..=10.
    pub order: usize,
    pub spacing: NodeSpacing,
    pub formulation: Formulation,
    /// Young's modulus E (> 0); it does not change the mesh, only scales K.
    pub young: f64,
    /// Poisson's ratio ν in [0, 0.5).
    pub poisson: f64,
    /// Number of load increments n ≥ 1 (forced to 1 for `Linear`).
    pub increments: usize,
    /// Constitutive model; IIL, CIL and NONLINEAR need a hyperelastic one.
    pub material: MaterialModel,
    /// Newton–Raphson: converged when ‖R‖/‖R₀‖ < tolerance (default 1e-5).
    pub tolerance: f64,
    /// Newton–Raphson: iterations per increment before giving up (default 30).
    pub max_iterations: usize,
    /// Fibre direction per cell for the transversely isotropic models; by
    /// default −x inside and tangent to the boundary on boundary cells.
    pub fibres: Option<Vec<[f64; 3]>>,
    /// Linear solver of every increment (default: chosen by size).
    pub solver: SolverChoice,
    /// Fill-reducing ordering of the direct solver (default
    /// [`DirectOrdering::Auto`]: nested dissection or AMD, as measured).
    pub direct_ordering: DirectOrdering,
    /// Remove the boundary caps of a 3D mesh before curving (default on): tets
    /// with two faces on one smooth surface, which no curving keeps valid
    /// (see [`crate::mesh::caps`]). The curved mesh then has fewer cells.
    pub remove_caps: bool,
    /// When caps were removed (`remove_caps`, or the repair's caps) and the
    /// run still ends with a certified-invalid cell, run once more from the
    /// same linear mesh with the caps kept (default on): removing a cap turns
    /// its interior chord into a boundary edge, and on a coarse mesh under
    /// strong curvature that edge can bulge through the cells below it.
    /// [`CurveReport::caps_kept_after`] says when it happened.
    pub retry_keep_caps: bool,
    /// Repair the linear mesh before curving (default on): cells that cannot
    /// stay valid once curved with their vertices fixed (all vertices on one
    /// surface that bulges into the domain, or a boundary facet whose bulge
    /// exceeds half the height of the opposite vertex, itself on the
    /// boundary) are removed by local flips, which keep the boundary (see
    /// [`mod@crate::mesh::repair`]); with `remove_caps`, such caps whose faces
    /// meet at more than 45° that no flip fixes are removed too. Needs one
    /// projection of a few points per tagged facet (timed with `elevate`).
    pub repair: bool,
    /// Adaptive load stepping ([`solve_increments`]): step back and halve an
    /// increment that inverts a cell (certified check) or whose Newton
    /// iteration fails. None (default): on for the incremental formulations
    /// (ILE, IIL, CIL, NONLINEAR), off for `Linear`, the one-shot solve.
    pub adaptive: Option<bool>,
    /// Adaptive load stepping: halvings allowed per nominal increment, at most
    /// [`MAX_SPLITS`] (default [`DEFAULT_MAX_SPLITS`] = 6: down to 1/64 of a step).
    pub max_splits: usize,
    /// Static condensation of the cell-interior nodes (default on; cells
    /// have some from p = 4 in 3D, p = 3 in 2D): they are eliminated cell by
    /// cell ([`crate::assembly::condense`]), so the linear systems hold only
    /// the vertex, edge and face nodes; the mesh is the same to round-off.
    /// Measured (bench-one, 2026-11-23, medians of 3): 3D PCG 1.04× faster
    /// at p = 4, 1.23× at p = 5 and 1.35× at p = 6 for one increment (1.07×
    /// and 1.25× for ten); 2D direct 1.37× at p = 4 and 1.52× at p = 6;
    /// 7–38 % less memory.
    pub condense: bool,
    /// The optimisation stage after the elastic solve ([`crate::optimize`]):
    /// on by default, it untangles the cells the elastic curving leaves
    /// invalid and improves those below a Q3 threshold. With it on, an
    /// elastic solve that adaptive stepping cannot keep valid is finished
    /// instead of refused (see [`CurveReport::elastic_stop`]), and the
    /// optimisation then has to make it valid.
    pub optimize: OptimizeOptions,
    /// Where the elastic stage runs (default [`Parallel::Serial`]: here);
    /// a distributed run (`hocurve::distributed`, the `mpi` feature) sets
    /// its backend.
    pub parallel: Parallel,
}

impl CurveOptions {
    /// Whether adaptive load stepping runs: `adaptive`, or by default on
    /// unless the formulation is `Linear`.
    pub fn adaptive_enabled(&self) -> bool {
        self.adaptive.unwrap_or(self.formulation != Formulation::Linear)
    }
}

impl Default for CurveOptions {
    /// p = 2, optimal nodes, ILE with 10 increments, E = 1e5, ν = 0.45 (the
    /// paper finds ν near 0.45 and about ten increments give the best meshes).
    fn default() -> Self {
        CurveOptions {
            order: 2,
            spacing: NodeSpacing::Optimal,
            formulation: Formulation::Ile,
            young: 1e5,
            poisson: 0.45,
            increments: 10,
            material: MaterialModel::LinearElastic,
            tolerance: 1e-5,
            max_iterations: 30,
            fibres: None,
            solver: SolverChoice::Auto,
            direct_ordering: DirectOrdering::Auto,
            remove_caps: true,
            retry_keep_caps: true,
            repair: true,
            adaptive: None,
            max_splits: DEFAULT_MAX_SPLITS,
            condense: true,
            optimize: OptimizeOptions::default(),
            parallel: Parallel::Serial,
        }
    }
}

/// A stage of the run, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Elevate,
    Project,
    Increment,
    Quality,
    Optimize,
}

/// Progress of a run: `step` of `total` within `stage`.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub stage: Stage,
    pub step: usize,
    pub total: usize,
}

/// Wall-clock seconds of each phase.
#[derive(Debug, Clone, Default)]
pub struct Timings {
    pub total: f64,
    pub elevate: f64,
    pub project: f64,
    pub assembly: f64,
    /// Symbolic analysis, and the preconditioner that PCG builds for each
    /// matrix (its smoothers and coarse levels).
    pub setup: f64,
    /// The linear solves: PCG's iterations, or a direct solver's
    /// factorisation and substitutions.
    pub solve: f64,
    /// The quality measures and certified bounds of the elastic stage's
    /// mesh (the optimisation's own are in `optimize`).
    pub quality: f64,
    /// The validity check of adaptive load stepping after each increment.
    pub check: f64,
    /// The optimisation stage.
    pub optimize: f64,
}

/// What a run reports.
#[derive(Debug, Clone)]
pub struct CurveReport {
    pub order: usize,
    pub formulation: Formulation,
    pub material: MaterialModel,
    pub young: f64,
    pub poisson: f64,
    /// Nominal load increments asked for (1 for `Linear`).
    pub increments: usize,
    /// Whether adaptive load stepping ran, and its split limit.
    pub adaptive: bool,
    pub max_splits: usize,
    /// Load fraction reached by each accepted increment (the last is 1); its
    /// length is the number of increments taken.
    pub load_fractions: Vec<f64>,
    /// Increments rejected and split by adaptive load stepping.
    pub step_backs: Vec<StepBack>,
    pub nodes: usize,
    /// Unknowns: the free degrees of freedom.
    pub dofs: usize,
    /// Unknowns of the linear systems: `dofs` less the cell-interior ones
    /// when they are condensed ([`CurveOptions::condense`]).
    pub system_dofs: usize,
    pub cells: usize,
    /// Cells whose input orientation was negative and was flipped.
    pub reoriented_cells: usize,
    /// Boundary caps removed before curving (`CurveOptions::remove_caps`).
    pub removed_caps: usize,
    /// When the run was made a second time with the caps kept
    /// ([`CurveOptions::retry_keep_caps`]): the error that ended the first
    /// run, which had removed caps. The rest of the report is the second run's.
    pub caps_kept_after: Option<String>,
    /// When that second run with the caps kept ended invalid too, after a
    /// first run that had stopped after its first optimisation rounds: its
    /// error. The mesh and the rest of the report are then those of a third
    /// run, the first made again with every round ([`CurveOptions::retry_keep_caps`]).
    pub caps_kept_failed: Option<String>,
    /// What the repair did (`CurveOptions::repair`; all zero when off).
    pub repair: RepairSummary,
    /// For each cell of the curved mesh, an input cell: itself, or for a cell
    /// made by the repair, the input cell that contains its centroid.
    pub input_cell: Vec<usize>,
    pub projected_nodes: usize,
    /// Largest distance between a straight node and its projection.
    pub max_projection_distance: f64,
    /// Edges on curves whose nodes were placed along the curve instead of
    /// at their closest points, which were out of place (an edge cutting
    /// across a bend, such as a coarse aerofoil's nose).
    pub edges_along_curves: usize,
    pub quality: MeshQuality,
    pub timings: Timings,
    /// NONLINEAR: ‖R‖/‖R₀‖ after each Newton iteration, per increment.
    pub newton_history: Vec<Vec<f64>>,
    /// The linear solves: the solver, and per solve its iterations, which
    /// solver produced the solution and why it fell back.
    pub solves: SolveLog,
    /// Where the elastic stage stopped short of the full load, if it did:
    /// adaptive stepping could not keep a cell valid, so the remaining load
    /// was applied in one linear solve on the straight mesh and the
    /// optimisation stage took over.
    pub elastic_stop: Option<ElasticStop>,
    /// What the optimisation stage did.
    pub optimization: OptimizeReport,
}

impl CurveReport {
    /// Accepted load increments (≥ `increments` when adaptive stepping split some).
    pub fn increments_taken(&self) -> usize {
        self.load_fractions.len()
    }
}

/// The result of a successful run.
#[derive(Debug, Clone)]
pub struct CurvedMesh {
    /// The curved mesh (node coordinates at the `spacing` reference positions).
    pub mesh: HighOrderMesh,
    /// The straight-sided positions of the same nodes.
    pub straight: Vec<f64>,
    pub cell_quality: Vec<ElementQuality>,
    pub report: CurveReport,
}

/// Check options before any work.
pub fn validate_options(opts: &CurveOptions) -> Result<LinearElastic> {
    if !(1..=10).contains(&opts.order) {
        return Err(Error::InvalidInput(format!("order must be between 1 and 10, got {}", opts.order)));
    }
    if opts.increments == 0 {
        return Err(Error::InvalidInput("the number of increments must be at least 1".into()));
    }
    if !(opts.tolerance.is_finite() && opts.tolerance > 0.0) || opts.max_iterations == 0 {
        return Err(Error::InvalidInput(format!(
            "Newton tolerance must be positive and iterations at least 1 (got {}, {})",
            opts.tolerance, opts.max_iterations
        )));
    }
    let hyperelastic =
        !matches!(opts.material, MaterialModel::LinearElastic | MaterialModel::TransverselyIsotropicLinear);
    if matches!(opts.formulation, Formulation::Iil | Formulation::Cil | Formulation::Nonlinear) && !hyperelastic {
        return Err(Error::InvalidInput(format!(
            "formulation {} needs a hyperelastic material (neo-hookean, mooney-rivlin, ni-mooney-rivlin or \
             transversely-isotropic), not '{}'",
            opts.formulation.name(),
            opts.material.name()
        )));
    }
    if opts.max_splits > MAX_SPLITS {
        return Err(Error::InvalidInput(format!("max_splits must be at most {MAX_SPLITS}, got {}", opts.max_splits)));
    }
    LinearElastic::try_from_young_poisson(opts.young, opts.poisson)
}

/// Curve `linear` onto the geometry of `projector`.
///
/// `progress` is called at each stage and increment; returning `false`
/// cancels the run with [`Error::Cancelled`].
pub fn curve(
    linear: &LinearMesh,
    projector: &dyn Projector,
    opts: &CurveOptions,
    progress: &mut dyn FnMut(&Progress) -> bool,
) -> Result<CurvedMesh> {
    let t0 = Instant::now();
    let prepared = Prepared::new(linear, opts)?;
    run_retrying(&prepared, &|o| Prepared::new(linear, o), projector, opts, progress, t0)
}

/// [`curve`] on a mesh already prepared ([`Prepared::new`]) for the order,
/// node spacing and cap removal of `opts`: the same result, without
/// validating, orienting and elevating the mesh again, and without the
/// second run with the caps kept ([`CurveOptions::retry_keep_caps`]), which
/// needs the linear mesh ([`crate::session::Session`] makes it).
pub fn curve_prepared(
    prepared: &Prepared,
    projector: &dyn Projector,
    opts: &CurveOptions,
    progress: &mut dyn FnMut(&Progress) -> bool,
) -> Result<CurvedMesh> {
    prepared.check_matches(opts)?;
    run_prepared(prepared, projector, opts, progress, Instant::now(), &mut RunFlags::default())
}

/// [`run_prepared`]; when it ends with a certified-invalid cell after
/// removing caps and `opts.retry_keep_caps`, once more from `reprepare`d
/// with the caps kept. The first run then stops after the optimisation's
/// first rounds ([`crate::optimize::OptimizeOptions::later_rounds`]): the
/// later rounds of a run that the caps-kept one rescues were most of its
/// time (a coarse gmsh torus cavity at p = 3: 14 s of 16). If the
/// caps-kept run fails too, the first is made a third time with every
/// round, as it was before, and its result (or error) stands, the report
/// saying why ([`CurveReport::caps_kept_failed`]). An error of the last
/// run says the others' too.
pub(crate) fn run_retrying(
    prepared: &Prepared,
    reprepare: &dyn Fn(&CurveOptions) -> Result<Prepared>,
    projector: &dyn Projector,
    opts: &CurveOptions,
    progress: &mut dyn FnMut(&Progress) -> bool,
    t0: Instant,
) -> Result<CurvedMesh> {
    let kept = CurveOptions { remove_caps: false, ..opts.clone() };
    let run = |attempt: Attempt, flags: &mut RunFlags| match attempt {
        Attempt::First => run_prepared(prepared, projector, opts, progress, t0, flags),
        Attempt::CapsKept => run_prepared(&reprepare(&kept)?, projector, &kept, progress, Instant::now(), flags),
        Attempt::FirstInFull => run_prepared(prepared, projector, opts, progress, Instant::now(), flags),
    };
    let mut curved = retry_plan(run, opts.retry_keep_caps)?;
    // After more than one run, the stages' times are the last run's; the total counts them all.
    curved.report.timings.total = t0.elapsed().as_secs_f64();
    Ok(curved)
}

/// The runs of [`run_retrying`].
#[derive(Debug, Clone, Copy, PartialEq)]
enum Attempt {
    /// The first run; with `quick` set, it stops after the optimisation's
    /// first rounds if it removed caps ([`RunFlags`]).
    First,
    /// The same linear mesh with the caps kept.
    CapsKept,
    /// The first run again, with every round.
    FirstInFull,
}

/// A curving result that says which runs of [`run_retrying`] failed before it.
trait Retried {
    fn note(&mut self, caps_kept_after: Option<String>, caps_kept_failed: Option<String>);
}

impl Retried for CurvedMesh {
    fn note(&mut self, caps_kept_after: Option<String>, caps_kept_failed: Option<String>) {
        self.report.caps_kept_after = caps_kept_after;
        self.report.caps_kept_failed = caps_kept_failed;
    }
}

/// The order of the runs of [`run_retrying`], given `run` (one run,
/// telling back what it did in its flags) and whether to `retry` with the
/// caps kept.
fn retry_plan<T: Retried>(mut run: impl FnMut(Attempt, &mut RunFlags) -> Result<T>, retry: bool) -> Result<T> {
    let mut first_run = RunFlags { quick: true, ..RunFlags::default() };
    let first = match run(Attempt::First, &mut first_run) {
        Err(e @ Error::InvalidElement { .. }) if first_run.caps_removed && retry => e.to_string(),
        done => return done,
    };
    let (cell, message) = match run(Attempt::CapsKept, &mut RunFlags::default()) {
        Ok(mut done) => {
            done.note(Some(first), None);
            return Ok(done);
        }
        Err(Error::InvalidElement { cell, message }) => (cell, message),
        Err(e) => return Err(e),
    };
    if !first_run.deferred {
        return Err(Error::InvalidElement {
            cell,
            message: format!("{message} (in a second run with the caps kept; the first had ended: {first})"),
        });
    }
    // The first run stopped before its later rounds: once more with them.
    match run(Attempt::FirstInFull, &mut RunFlags::default()) {
        Ok(mut done) => {
            done.note(None, Some(format!("invalid element: {message}")));
            Ok(done)
        }
        Err(Error::InvalidElement { cell, message: last }) => {
            Err(Error::InvalidElement { cell, message: format!("{last} (and in a run with the caps kept: {message})") })
        }
        Err(e) => Err(e),
    }
}

/// What [`run_prepared`] is told and tells about one run of [`run_retrying`].
#[derive(Debug, Default, Clone, Copy)]
struct RunFlags {
    /// Told: a first run that a caps-kept one may follow, whose
    /// optimisation stops after its first rounds if it removed caps.
    quick: bool,
    /// Told back: caps were removed, by the preparation or the repair.
    caps_removed: bool,
    /// Told back: the optimisation stopped before its later rounds with
    /// cells still invalid.
    deferred: bool,
}

/// The stages of [`curve`] from a prepared mesh, timed from `t0`.
fn run_prepared(
    prepared: &Prepared,
    projector: &dyn Projector,
    opts: &CurveOptions,
    progress: &mut dyn FnMut(&Progress) -> bool,
    t0: Instant,
    flags: &mut RunFlags,
) -> Result<CurvedMesh> {
    let material = validate_options(opts)?;
    let mut tick = |stage: Stage, step: usize, total: usize| -> Result<()> {
        if progress(&Progress { stage, step, total }) {
            Ok(())
        } else {
            Err(Error::Cancelled)
        }
    };
    let mut run = Run {
        opts,
        projector,
        timings: Timings::default(),
        tick: &mut tick,
        second_start: true,
        defer_later: false,
        deferred: false,
    };

    // 1-2. Repair and elevate.
    let elevated = run.elevate(prepared)?;
    run.timings.elevate = t0.elapsed().as_secs_f64();
    flags.caps_removed = elevated.fixes.removed_caps + elevated.fixes.repair.surface_caps > 0;
    // A run that removed caps and ends invalid is made again with them kept
    // (run_retrying), which rescues what the second start would try: measured
    // on 15 such runs, the same meshes in about half the time without it.
    let retried = flags.caps_removed && opts.retry_keep_caps;
    run.second_start = !retried;
    run.defer_later = retried && flags.quick;

    // 3. Project the boundary nodes.
    let placement = run.project(&elevated)?;

    // 4. Solve in increments.
    let setup = ElasticSetup::new(&elevated, material, opts)?;
    let Elevated { mesh, straight, input_cell, fixes, .. } = elevated;
    let elastic = run.solve_elastic(mesh, &straight, &placement.displacement, &setup)?;

    // 5. Quality, and the optimisation of the cells that need it.
    let done = run.optimise(elastic, &straight, &placement.displacement, &setup, &input_cell);
    flags.deferred = run.deferred;
    let done = done?;
    run.timings.total = t0.elapsed().as_secs_f64();
    Ok(done.into_curved(opts, setup.increments, fixes, &placement, run.timings))
}

/// One run of [`curve`]: its options and projector, the time each stage
/// takes, and the progress callback (an error from it cancels the run).
struct Run<'a> {
    opts: &'a CurveOptions,
    projector: &'a dyn Projector,
    timings: Timings,
    tick: &'a mut dyn FnMut(Stage, usize, usize) -> Result<()>,
    /// Whether an elastic stage that stopped short, leaving the optimisation
    /// with invalid cells, is started a second time ([`Run::optimise`]).
    second_start: bool,
    /// Whether the optimisation stops after its first rounds
    /// ([`run_retrying`]) if the elastic stage stopped short, and whether
    /// it did so with cells still invalid.
    defer_later: bool,
    deferred: bool,
}

impl Run<'_> {
    /// Stages 1-2: repair the prepared mesh as the options ask, and elevate
    /// it to order p (the prepared elevation, when the repair changed nothing).
    fn elevate<'p>(&mut self, prepared: &'p Prepared) -> Result<Elevated<'p>> {
        let (opts, projector) = (self.opts, self.projector);
        (self.tick)(Stage::Elevate, 0, 1)?;
        let n_input_cells = prepared.n_input_cells();
        let (reoriented, removed_caps) = (prepared.reoriented_cells(), n_input_cells - prepared.input_cell().len());
        let repaired = match opts.repair {
            true => {
                let mut projections = crate::geometry::SampleProjections::default();
                Some(repair_with(prepared.linear(), opts.remove_caps, |m, s| projections.project(m.dim, s, projector))?)
            }
            false => None,
        };
        let repair = repaired.as_ref().map_or_else(RepairSummary::default, |r| r.summary);
        let fixes = InputFixes { reoriented, removed_caps, repair };
        let Some(r) = repaired.filter(|r| r.mesh != *prepared.linear()) else {
            let mesh = prepared.straight_mesh().clone();
            return Ok(Elevated {
                linear: Cow::Borrowed(prepared.linear()),
                topo: Cow::Borrowed(prepared.topology()),
                nodes: prepared.nodes().clone(),
                straight: mesh.coords.clone(),
                mesh,
                n_input_cells,
                input_cell: prepared.input_cell().to_vec(),
                fixes,
            });
        };
        let input_cell = r.input_cell.iter().map(|&c| prepared.input_cell()[c]).collect();
        let topo = Topology::new(&r.mesh)?;
        let nodes = NodeSet::new(topo.simplex, opts.order, opts.spacing);
        let mesh = HighOrderMesh::elevate(&r.mesh, &topo, &nodes, opts.spacing)?;
        let straight = mesh.coords.clone();
        let (linear, topo) = (Cow::Owned(r.mesh), Cow::Owned(topo));
        Ok(Elevated { linear, topo, nodes, mesh, straight, n_input_cells, input_cell, fixes })
    }

    /// Stage 3: place the boundary nodes of the elevated mesh on the geometry.
    fn project(&mut self, elevated: &Elevated) -> Result<BoundaryPlacement> {
        let t = Instant::now();
        (self.tick)(Stage::Project, 0, 1)?;
        let placement = place_boundary_nodes(&elevated.mesh, &elevated.linear, self.projector)?;
        self.timings.project = t.elapsed().as_secs_f64();
        Ok(placement)
    }

    /// Stage 4: move `mesh` (straight-sided at `straight`) by the boundary
    /// displacement `ubar` in load increments. When adaptive stepping stops
    /// short, the rest of the load is added in one linear elastic solve on
    /// the straight mesh, which is kept for a second start.
    fn solve_elastic(
        &mut self,
        mut mesh: HighOrderMesh,
        straight: &[f64],
        ubar: &[f64],
        setup: &ElasticSetup,
    ) -> Result<Elastic> {
        let (timings, tick) = (&mut self.timings, &mut *self.tick);
        let mut solved = if setup.linear_iso {
            solve_increments(&mut mesh, &setup.linear_kernel, ubar, setup.stepping.clone(), timings, tick)?
        } else {
            let (model, fibres) = (setup.model.as_ref(), &setup.fibres);
            let kernel = MaterialKernel::new(&mesh, straight, &setup.cache, model, setup.mode, fibres);
            solve_increments(&mut mesh, &kernel, ubar, setup.stepping.clone(), timings, tick)?
        };
        // The straight mesh, kept for a second start of the optimisation.
        let straight_mesh =
            solved.stopped.is_some().then(|| HighOrderMesh { coords: straight.to_vec(), ..mesh.clone() });
        if let (Some(stop), Some(reference)) = (solved.stopped.clone(), &straight_mesh) {
            // The remaining load in one linear elastic solve on the straight
            // mesh, which is always valid: the boundary reaches its target and
            // the optimisation stage untangles what this leaves inverted.
            let mut reference = reference.clone();
            let rate = solved.first_rate.as_deref();
            self.linear_solve(&mut reference, ubar, 1.0 - stop.load, rate, setup, &mut solved.solves)?;
            for ((x, r), s) in mesh.coords.iter_mut().zip(&reference.coords).zip(straight) {
                *x += r - s;
            }
        }
        Ok(Elastic { mesh, solved, straight_mesh })
    }

    /// Move `mesh`, straight-sided, by one linear elastic solve of the load
    /// `ubar`·`scale`, given `rate`, the elastic stage's first solution per
    /// unit load on this geometry. When that solve had this very matrix
    /// (ILE with an isotropic material: the linear kernel on the straight
    /// mesh), the answer is `rate`·`scale` and nothing is solved again;
    /// otherwise the solve starts from it, and goes to `log`.
    fn linear_solve(
        &mut self,
        mesh: &mut HighOrderMesh,
        ubar: &[f64],
        scale: f64,
        rate: Option<&[f64]>,
        setup: &ElasticSetup,
        log: &mut SolveLog,
    ) -> Result<()> {
        if let (true, Some(rate)) = (setup.linear_iso, rate) {
            if stepping::add_rate(mesh, ubar, rate, scale, setup.stepping.condense) {
                return Ok(());
            }
        }
        let load: Vec<f64> = ubar.iter().map(|u| u * scale).collect();
        let start: Option<Vec<f64>> = rate.map(|r| r.iter().map(|x| x * scale).collect());
        let (finish, kernel) = (setup.finish_stepping.clone(), &setup.linear_kernel);
        let (timings, tick) = (&mut self.timings, &mut *self.tick);
        let done = solve_increments_from(mesh, kernel, &load, finish, start.as_deref(), timings, tick)?;
        log.append(done.solves);
        Ok(())
    }

    /// Stage 5: the quality of the elastic stage's mesh, and the optimisation
    /// of the cells that need it. When the elastic stage stopped short and
    /// its mesh is left with invalid cells, a second start (the whole load
    /// `ubar` in one linear solve on the straight mesh, then the
    /// optimisation) is kept if it leaves fewer.
    fn optimise(
        &mut self,
        elastic: Elastic,
        straight: &[f64],
        ubar: &[f64],
        setup: &ElasticSetup,
        input_cell: &[usize],
    ) -> Result<Optimised> {
        let (opts, projector) = (self.opts, self.projector);
        let Elastic { mesh, mut solved, straight_mesh } = elastic;
        let t = Instant::now();
        (self.tick)(Stage::Quality, 0, 1)?;
        let ti = opts.material.is_transversely_isotropic().then_some(&setup.fibres[..]);
        let cache = quality::sampling_cache(&setup.basis);
        let certified = solved.certified.take().filter(|_| solved.stopped.is_none());
        self.timings.quality = t.elapsed().as_secs_f64();
        let t = Instant::now();
        (self.tick)(Stage::Optimize, 0, 1)?;
        // Only a run whose elastic stage stopped short ends in an error with
        // invalid cells left: the one that a caps-kept run may follow.
        let defer = self.defer_later && solved.stopped.is_some();
        let first_rounds = OptimizeOptions { later_rounds: false, ..opts.optimize.clone() };
        let optimize = if defer { &first_rounds } else { &opts.optimize };
        let optimiser = Optimiser { straight, basis: &setup.basis, cache: &cache, opts: optimize, projector, ti };
        let mut done = optimiser.finish(mesh, certified)?;
        let mut quality_seconds = done.quality_seconds;
        self.deferred = defer && done.invalid() > 0;
        let mut restarted = false;
        // (Stopped at load 0, the first start was already that.)
        let stopped_after_0 = solved.stopped.as_ref().is_some_and(|s| s.load > 0.0);
        if let (Some(mut second), true) = (straight_mesh, self.second_start && done.invalid() > 0 && stopped_after_0) {
            // A second start: the whole load in one linear solve on the straight
            // mesh, then the optimisation; kept if it leaves fewer invalid cells.
            self.linear_solve(&mut second, ubar, 1.0, solved.first_rate.as_deref(), setup, &mut solved.solves)?;
            let other = optimiser.finish(second, None)?;
            quality_seconds += other.quality_seconds;
            if other.invalid() < done.invalid() {
                (done, restarted) = (other, true);
            }
        }
        let Finished { mesh, straight, mut cell_quality, certified, optimization, parent, .. } = done;
        // Cells split by the optimisation come from the cell at `parent`.
        let input_cell: Vec<usize> = parent.iter().map(|&c| input_cell[c]).collect();
        let fibres: Vec<_> = parent.iter().map(|&c| setup.fibres[c]).collect();
        let ti = ti.map(|_| &fibres[..]);
        if optimization.ran && ti.is_some() {
            // Q4, Q5 of the moved cells need their fibres.
            cell_quality = quality::cell_qualities(&cache, &mesh.coords, Some(&straight), &mesh.cells, ti);
        }
        // The measures of the mesh the elastic stage left count as quality.
        self.timings.quality += quality_seconds;
        self.timings.optimize = t.elapsed().as_secs_f64() - quality_seconds;
        let mut q = quality::summarize(&cell_quality);
        quality::add_certified(&mut q, &certified);
        if let Some(stop) = &mut solved.stopped {
            stop.restarted = restarted;
            if q.n_certified_invalid > 0 {
                let c = certified.iter().position(|c| c.verdict == quality::Verdict::Invalid).unwrap_or(0);
                return Err(Error::invalid_element(
                    Some(c),
                    format!(
                    "cell {c} is inverted (certified: det J <= 0 somewhere in it) after optimisation, with {} cells \
                     invalid in all; the elastic stage had stopped at load {:.4}: {}",
                    q.n_certified_invalid, stop.load, stop.detail
                ),
                ));
            }
        }
        Ok(Optimised { mesh, straight, cell_quality, quality: q, optimization, input_cell, solved })
    }
}

/// The linear mesh made ready for curving and elevated to order p.
struct Elevated<'p> {
    /// The linear mesh, oriented, without its caps and repaired as asked.
    linear: Cow<'p, LinearMesh>,
    topo: Cow<'p, Topology>,
    nodes: NodeSet,
    /// The elevated mesh, still straight-sided.
    mesh: HighOrderMesh,
    /// Its node coordinates.
    straight: Vec<f64>,
    /// Cells of the input mesh.
    n_input_cells: usize,
    /// For each cell of `linear`, an input cell.
    input_cell: Vec<usize>,
    fixes: InputFixes,
}

/// What was done to the input mesh before curving.
#[derive(Clone, Copy)]
struct InputFixes {
    /// Cells whose input orientation was negative and was flipped.
    reoriented: usize,
    removed_caps: usize,
    repair: RepairSummary,
}

/// What the elastic stage solves with, set up from the options.
struct ElasticSetup {
    /// Nominal load increments (1 for `Linear`).
    increments: usize,
    basis: LagrangeBasis,
    /// The element cache of the material kernel (a rule of degree 2p).
    cache: ElementCache,
    model: Box<dyn Material>,
    /// Unit fibre direction per cell.
    fibres: Vec<[f64; 3]>,
    stepping: Stepping,
    mode: TangentMode,
    /// `Linear` or ILE with an isotropic material: the linear elastic kernel solves.
    linear_iso: bool,
    /// The fast linear elastic kernel.
    linear_kernel: LinearElasticKernel,
    /// One linear elastic solve: the rest of the load after adaptive stepping
    /// stopped short, or the whole load for a second start.
    finish_stepping: Stepping,
}

impl ElasticSetup {
    /// The set-up of `opts` on `elevated`, with `material` the linear material of `opts`.
    fn new(elevated: &Elevated, material: LinearElastic, opts: &CurveOptions) -> Result<ElasticSetup> {
        let simplex = elevated.topo.simplex;
        let increments = if opts.formulation == Formulation::Linear { 1 } else { opts.increments };
        let basis = LagrangeBasis::new(&elevated.nodes);
        let rule = simplex_rule(simplex, 2 * opts.order);
        let cache = ElementCache::new(&basis, &rule);
        let model = make_material(opts.material, opts.young, opts.poisson)?;
        let fibres = match &opts.fibres {
            Some(f) => {
                let f = checked_fibres(f, elevated.n_input_cells)?;
                elevated.input_cell.iter().map(|&c| f[c]).collect()
            }
            None => default_fibres(&elevated.linear, &elevated.topo),
        };
        let stepping = Stepping {
            increments,
            residual: matches!(opts.formulation, Formulation::Iil | Formulation::Cil),
            newton: (opts.formulation == Formulation::Nonlinear).then_some((opts.tolerance, opts.max_iterations)),
            solver: opts.solver.clone(),
            direct_ordering: opts.direct_ordering,
            adaptive: opts.adaptive_enabled(),
            max_splits: opts.max_splits,
            condense: opts.condense,
            finish: opts.optimize.enabled,
            parallel: opts.parallel.clone(),
        };
        let mode = match opts.formulation {
            Formulation::Cil | Formulation::Nonlinear => TangentMode::Consistent,
            _ => TangentMode::Initial,
        };
        let linear_iso = matches!(opts.formulation, Formulation::Linear | Formulation::Ile)
            && !opts.material.is_transversely_isotropic();
        let linear_kernel = LinearElasticKernel::for_nodes(&elevated.nodes, material);
        let finish_stepping = Stepping { increments: 1, adaptive: false, finish: false, ..stepping.clone() };
        Ok(ElasticSetup {
            increments,
            basis,
            cache,
            model,
            fibres,
            stepping,
            mode,
            linear_iso,
            linear_kernel,
            finish_stepping,
        })
    }
}

/// The mesh after the elastic stage.
struct Elastic {
    mesh: HighOrderMesh,
    solved: IncrementsReport,
    /// When adaptive stepping stopped short: the straight mesh, for a second
    /// start of the optimisation.
    straight_mesh: Option<HighOrderMesh>,
}

/// What measures and optimises a curved mesh.
struct Optimiser<'a> {
    /// The straight-sided positions of the nodes.
    straight: &'a [f64],
    basis: &'a LagrangeBasis,
    /// The sampling cache of the quality measures.
    cache: &'a ElementCache,
    opts: &'a OptimizeOptions,
    projector: &'a dyn Projector,
    /// The fibres of each cell, for a transversely isotropic material.
    ti: Option<&'a [[f64; 3]]>,
}

impl Optimiser<'_> {
    /// Measure `mesh` (with the certified verdicts when known) and optimise it.
    fn finish(&self, mut mesh: HighOrderMesh, certified: Option<Vec<quality::CertifiedJacobian>>) -> Result<Finished> {
        let mut straight = self.straight.to_vec();
        if let Some(i) = mesh.coords.iter().position(|x| !x.is_finite()) {
            return Err(Error::solver(
                SolverFailure::NonFinite,
                format!("the solution is not finite at node {}", i / mesh.dim()),
            ));
        }
        let t = Instant::now();
        // Q1, Q2 against the straight mesh's elements (the curving may move vertices).
        let mut cell_quality = quality::cell_qualities(self.cache, &mesh.coords, Some(&straight), &mesh.cells, self.ti);
        let mut certified = certified.unwrap_or_else(|| quality::certify_cells(self.basis, &mesh.coords, &mesh.cells));
        let quality_seconds = t.elapsed().as_secs_f64();
        let (optimization, parent) = optimize::optimize(
            &mut mesh,
            &mut straight,
            self.basis,
            self.cache,
            self.opts,
            Some(self.projector),
            &mut cell_quality,
            &mut certified,
        );
        Ok(Finished { mesh, straight, cell_quality, certified, optimization, parent, quality_seconds })
    }
}

/// The mesh after the quality and optimisation stages.
struct Finished {
    mesh: HighOrderMesh,
    straight: Vec<f64>,
    cell_quality: Vec<ElementQuality>,
    certified: Vec<quality::CertifiedJacobian>,
    optimization: OptimizeReport,
    /// For each cell of `mesh`, the cell before the optimisation split any.
    parent: Vec<usize>,
    /// The time its quality measures and certified bounds took, before
    /// the optimisation.
    quality_seconds: f64,
}

impl Finished {
    fn invalid(&self) -> usize {
        self.certified.iter().filter(|c| c.verdict != quality::Verdict::Valid).count()
    }
}

/// The outcome of the whole pipeline, before it is reported.
struct Optimised {
    mesh: HighOrderMesh,
    straight: Vec<f64>,
    cell_quality: Vec<ElementQuality>,
    quality: MeshQuality,
    optimization: OptimizeReport,
    /// For each cell of `mesh`, an input cell.
    input_cell: Vec<usize>,
    solved: IncrementsReport,
}

impl Optimised {
    /// The curved mesh and the report of the run that made it.
    fn into_curved(
        self,
        opts: &CurveOptions,
        increments: usize,
        fixes: InputFixes,
        placement: &BoundaryPlacement,
        timings: Timings,
    ) -> CurvedMesh {
        let Optimised { mesh, straight, cell_quality, quality, optimization, input_cell, solved } = self;
        let report = CurveReport {
            order: opts.order,
            formulation: opts.formulation,
            material: opts.material,
            young: opts.young,
            poisson: opts.poisson,
            increments,
            adaptive: opts.adaptive_enabled(),
            max_splits: opts.max_splits,
            load_fractions: solved.load_fractions,
            step_backs: solved.step_backs,
            nodes: mesh.n_nodes(),
            dofs: solved.n_free,
            system_dofs: solved.n_system,
            cells: mesh.n_cells(),
            reoriented_cells: fixes.reoriented,
            removed_caps: fixes.removed_caps,
            caps_kept_after: None,
            caps_kept_failed: None,
            repair: fixes.repair,
            input_cell,
            projected_nodes: placement.projected_nodes,
            max_projection_distance: placement.max_distance,
            edges_along_curves: placement.edges_along_curves,
            quality,
            timings,
            newton_history: solved.newton_history,
            solves: solved.solves,
            elastic_stop: solved.stopped,
            optimization,
        };
        CurvedMesh { mesh, straight, cell_quality, report }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A result that says which run made it and what it was told.
    #[derive(Debug, PartialEq)]
    struct Made {
        by: Attempt,
        after: Option<String>,
        failed: Option<String>,
    }

    impl Retried for Made {
        fn note(&mut self, caps_kept_after: Option<String>, caps_kept_failed: Option<String>) {
            (self.after, self.failed) = (caps_kept_after, caps_kept_failed);
        }
    }

    /// How a scripted run ends: valid, or invalid, with what it tells back.
    #[derive(Clone, Copy)]
    enum Ends {
        Valid,
        Invalid { caps_removed: bool, deferred: bool },
    }

    /// The runs made, and the result, for runs scripted by `script` (per attempt).
    fn plan(script: impl Fn(Attempt) -> Ends, retry: bool) -> (Vec<Attempt>, Result<Made>) {
        let mut made = Vec::new();
        let result = retry_plan(
            |attempt, flags: &mut RunFlags| {
                made.push(attempt);
                assert_eq!(flags.quick, attempt == Attempt::First, "only the first run is quick");
                match script(attempt) {
                    Ends::Valid => Ok(Made { by: attempt, after: None, failed: None }),
                    Ends::Invalid { caps_removed, deferred } => {
                        (flags.caps_removed, flags.deferred) = (caps_removed, deferred);
                        Err(Error::invalid_element(Some(1), format!("{attempt:?} failed")))
                    }
                }
            },
            retry,
        );
        (made, result)
    }

    #[test]
    fn a_quick_first_run_is_made_again_in_full_only_when_the_caps_kept_run_fails_too() {
        use Attempt::*;
        let removed = |deferred| Ends::Invalid { caps_removed: true, deferred };
        // Valid at once: one run.
        let (made, r) = plan(|_| Ends::Valid, true);
        assert_eq!((made, r.unwrap()), (vec![First], Made { by: First, after: None, failed: None }));
        // Caps removed and invalid: the caps-kept run rescues it.
        let (made, r) = plan(|a| if a == First { removed(true) } else { Ends::Valid }, true);
        let r = r.unwrap();
        assert_eq!((made, r.by, r.failed), (vec![First, CapsKept], CapsKept, None));
        assert!(r.after.unwrap().contains("First failed"));
        // It fails too, after a first run that stopped before its later rounds: the first in full.
        let (made, r) = plan(|a| if a == FirstInFull { Ends::Valid } else { removed(true) }, true);
        let r = r.unwrap();
        assert_eq!((made, r.by, r.after), (vec![First, CapsKept, FirstInFull], FirstInFull, None));
        assert!(r.failed.unwrap().contains("CapsKept failed"));
        // All three fail: the error says the last two.
        let (made, r) = plan(|_| removed(true), true);
        assert_eq!(made, vec![First, CapsKept, FirstInFull]);
        let m = r.unwrap_err().to_string();
        assert!(m.contains("FirstInFull failed") && m.contains("CapsKept failed"), "{m}");
        // A first run that had no later rounds to skip is not made again.
        let (made, r) = plan(|_| removed(false), true);
        assert_eq!(made, vec![First, CapsKept]);
        let m = r.unwrap_err().to_string();
        assert!(m.contains("CapsKept failed") && m.contains("First failed"), "{m}");
        // No retry, or no cap removed: the first run's error.
        for (script, retry) in [(removed(true), false), (Ends::Invalid { caps_removed: false, deferred: false }, true)]
        {
            let (made, r) = plan(|_| script, retry);
            assert_eq!(made, vec![First]);
            assert!(r.unwrap_err().to_string().contains("First failed"));
        }
    }
}
