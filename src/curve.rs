//! The one orchestrator: elevate, project, solve in load increments, measure.
//!
//! [`curve`] takes a linear mesh and a projector and returns a new curved
//! mesh; the input is never modified, so a failed run leaves nothing
//! half-curved.

use std::collections::BTreeMap;
use std::time::Instant;

use crate::assembly::{
    assemble_into, multigrid_levels, Assembled, AssemblyPlan, DofMap, ElementKernel, LinearElasticKernel,
    MaterialKernel, TangentMode,
};
use crate::geometry::Projector;
use crate::mapping::ElementCache;
use crate::material::{make_material, LinearElastic, MaterialModel};
use crate::mesh::{
    remove_boundary_caps, repair_with, validate_and_orient, HighOrderMesh, LinearMesh, NodeConstraint, RepairSummary,
    Topology,
};
use crate::optimize::{self, OptimizeOptions, OptimizeReport};
use crate::quadrature::simplex_rule;
use crate::quality::{self, ElementQuality, MeshQuality};
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use crate::solver::{
    DirectOrdering, DirectSolver, ExternalAdapter, FallbackReason, IterativeParams, IterativeSolver, LinearSolver,
    SolveStats, SolvedBy, SolverChoice, SymmetricCsc, AUTO_DIRECT_MAX_DOFS,
};
use crate::{Error, Result};

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
            repair: true,
            adaptive: None,
            max_splits: DEFAULT_MAX_SPLITS,
            condense: true,
            optimize: OptimizeOptions::default(),
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
    /// Symbolic analysis and preconditioner set-up.
    pub setup: f64,
    pub solve: f64,
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
    /// What the repair did (`CurveOptions::repair`; all zero when off).
    pub repair: RepairSummary,
    /// For each cell of the curved mesh, an input cell: itself, or for a cell
    /// made by the repair, the input cell that contains its centroid.
    pub input_cell: Vec<usize>,
    pub projected_nodes: usize,
    /// Largest distance between a straight node and its projection.
    pub max_projection_distance: f64,
    pub quality: MeshQuality,
    pub timings: Timings,
    /// NONLINEAR: ‖R‖/‖R₀‖ after each Newton iteration, per increment.
    pub newton_history: Vec<Vec<f64>>,
    /// The linear solver that ran ("direct", ...).
    pub linear_solver: &'static str,
    /// Krylov iterations of each linear solve (zeros for a direct solver;
    /// with those of an attempt that fell back).
    pub solver_iterations: Vec<usize>,
    /// The solver that produced each solve's solution.
    pub solver_per_solve: Vec<SolvedBy>,
    /// Per solve, why the first choice of solver did not produce it.
    pub fallback_per_solve: Vec<Option<FallbackReason>>,
    /// Solves that fell back (restarted PCG, direct after PCG, LU after Cholesky).
    pub fallbacks: usize,
    /// Where the elastic stage stopped short of the full load, if it did:
    /// adaptive stepping could not keep a cell valid, so the remaining load
    /// was applied in one linear solve on the straight mesh and the
    /// optimisation stage took over.
    pub elastic_stop: Option<ElasticStop>,
    /// What the optimisation stage did.
    pub optimization: OptimizeReport,
}

/// The point where adaptive load stepping gave up.
#[derive(Debug, Clone, PartialEq)]
pub struct ElasticStop {
    /// Load fraction reached (the start of the increment that failed).
    pub load: f64,
    pub reason: StepBackReason,
    /// The cell that could not be kept valid, when known.
    pub cell: Option<usize>,
    /// What went wrong, in words.
    pub detail: String,
    /// The optimisation from the stopped geometry (plus the rest of the load
    /// in one linear solve) left cells invalid, and the mesh returned is the
    /// optimisation of the whole load in one linear solve on the straight
    /// mesh instead, which left fewer.
    pub restarted: bool,
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
}

impl Finished {
    /// Measure `mesh` (with the certified verdicts when known) and optimise it.
    #[allow(clippy::too_many_arguments)]
    fn new(
        mut mesh: HighOrderMesh,
        mut straight: Vec<f64>,
        certified: Option<Vec<quality::CertifiedJacobian>>,
        basis: &LagrangeBasis,
        cache: &ElementCache,
        opts: &OptimizeOptions,
        projector: &dyn Projector,
        ti: Option<&[[f64; 3]]>,
    ) -> Result<Finished> {
        if let Some(i) = mesh.coords.iter().position(|x| !x.is_finite()) {
            return Err(Error::Solver(format!("the solution is not finite at node {}", i / mesh.dim())));
        }
        // Q1, Q2 against the straight mesh's elements (the curving may move vertices).
        let mut cell_quality = quality::cell_qualities(cache, &mesh.coords, Some(&straight), &mesh.cells, ti);
        let mut certified = certified.unwrap_or_else(|| quality::certify_cells(basis, &mesh.coords, &mesh.cells));
        let (optimization, parent) = optimize::optimize(
            &mut mesh,
            &mut straight,
            basis,
            cache,
            opts,
            Some(projector),
            &mut cell_quality,
            &mut certified,
        );
        Ok(Finished { mesh, straight, cell_quality, certified, optimization, parent })
    }

    fn invalid(&self) -> usize {
        self.certified.iter().filter(|c| c.verdict != quality::Verdict::Valid).count()
    }
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
    let material = validate_options(opts)?;
    let mut tick = |stage: Stage, step: usize, total: usize| -> Result<()> {
        if progress(&Progress { stage, step, total }) {
            Ok(())
        } else {
            Err(Error::Cancelled)
        }
    };
    let mut timings = Timings::default();

    // 1-2. Validate and elevate.
    tick(Stage::Elevate, 0, 1)?;
    let (linear, reoriented) = validate_and_orient(linear)?;
    let n_input_cells = linear.n_cells();
    let (linear, input_cell) =
        if opts.remove_caps { remove_boundary_caps(&linear) } else { (linear, (0..n_input_cells).collect()) };
    let removed_caps = n_input_cells - input_cell.len();
    let (linear, input_cell, repair_summary) = if opts.repair {
        let r = repair_with(&linear, opts.remove_caps, |m| crate::geometry::facet_bulges(m, projector))?;
        (r.mesh, r.input_cell.iter().map(|&c| input_cell[c]).collect(), r.summary)
    } else {
        (linear, input_cell, RepairSummary::default())
    };
    let topo = Topology::new(&linear)?;
    let nodes = NodeSet::new(topo.simplex, opts.order, opts.spacing);
    let mut mesh = HighOrderMesh::elevate(&linear, &topo, &nodes, opts.spacing)?;
    let straight = mesh.coords.clone();
    timings.elevate = t0.elapsed().as_secs_f64();

    // 3. Project the boundary nodes.
    let t = Instant::now();
    tick(Stage::Project, 0, 1)?;
    let target = project_boundary(&mesh, &linear, projector)?;
    let dim = mesh.dim();
    let mut ubar = vec![0.0; mesh.coords.len()];
    let mut projected_nodes = 0;
    let mut max_dist: f64 = 0.0;
    for (n, x) in &target {
        let mut d2 = 0.0;
        for k in 0..dim {
            let u = x[k] - mesh.coords[n * dim + k];
            ubar[n * dim + k] = u;
            d2 += u * u;
        }
        max_dist = max_dist.max(d2.sqrt());
        projected_nodes += 1;
    }
    timings.project = t.elapsed().as_secs_f64();

    // 4. Solve in increments.
    let increments = if opts.formulation == Formulation::Linear { 1 } else { opts.increments };
    let basis = LagrangeBasis::new(&nodes);
    let rule = simplex_rule(topo.simplex, 2 * opts.order);
    let cache = ElementCache::new(&basis, &rule);
    let model = make_material(opts.material, opts.young, opts.poisson)?;
    let fibres = match &opts.fibres {
        Some(f) => {
            let f = checked_fibres(f, n_input_cells)?;
            input_cell.iter().map(|&c| f[c]).collect()
        }
        None => default_fibres(&linear, &topo),
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
    };
    let mode = match opts.formulation {
        Formulation::Cil | Formulation::Nonlinear => TangentMode::Consistent,
        _ => TangentMode::Initial,
    };
    let linear_iso = matches!(opts.formulation, Formulation::Linear | Formulation::Ile)
        && !opts.material.is_transversely_isotropic();
    // Every isotropic model is calibrated so that c(F = I) = c_lin: the fast
    // kernel, with a rule of degree 2p − 2, exact on straight-sided cells
    // (∇N_a·∇N_b has degree 2p − 2 there): the symmetric rule has 24
    // points at p = 4 in 3D, against 46 for degree 2p and 64 for a
    // collapsed rule of degree 2p − 2. Curved cells are integrated
    // approximately by any rule.
    let linear_kernel = LinearElasticKernel {
        cache: ElementCache::new(&basis, &simplex_rule(topo.simplex, (2 * opts.order).saturating_sub(2).max(1))),
        material,
    };
    let finish_stepping = Stepping { increments: 1, adaptive: false, finish: false, ..stepping.clone() };
    let mut solved = if linear_iso {
        solve_increments(&mut mesh, &linear_kernel, &ubar, stepping, &mut timings, &mut tick)?
    } else {
        let kernel = MaterialKernel::new(&mesh, &straight, &cache, model.as_ref(), mode, &fibres);
        solve_increments(&mut mesh, &kernel, &ubar, stepping, &mut timings, &mut tick)?
    };
    // The straight mesh, kept for a second start of the optimisation.
    let straight_mesh = solved.stopped.is_some().then(|| HighOrderMesh { coords: straight.clone(), ..mesh.clone() });
    let append_solves = |solved: &mut IncrementsReport, more: IncrementsReport| {
        solved.solver_iterations.extend(more.solver_iterations);
        solved.solver_per_solve.extend(more.solver_per_solve);
        solved.fallback_per_solve.extend(more.fallback_per_solve);
        solved.fallbacks += more.fallbacks;
    };
    if let (Some(stop), Some(reference)) = (solved.stopped.clone(), &straight_mesh) {
        // The remaining load in one linear elastic solve on the straight
        // mesh, which is always valid: the boundary reaches its target and
        // the optimisation stage untangles what this leaves inverted.
        let rest: Vec<f64> = ubar.iter().map(|u| u * (1.0 - stop.load)).collect();
        let mut reference = reference.clone();
        let finish =
            solve_increments(&mut reference, &linear_kernel, &rest, finish_stepping.clone(), &mut timings, &mut tick)?;
        append_solves(&mut solved, finish);
        for ((x, r), s) in mesh.coords.iter_mut().zip(&reference.coords).zip(&straight) {
            *x += r - s;
        }
    }

    // 5. Quality, and the optimisation of the cells that need it.
    let t = Instant::now();
    tick(Stage::Quality, 0, 1)?;
    let ti = opts.material.is_transversely_isotropic().then_some(&fibres[..]);
    let cache = quality::sampling_cache(&basis);
    let certified = solved.certified.take().filter(|_| solved.stopped.is_none());
    timings.quality = t.elapsed().as_secs_f64();
    let t = Instant::now();
    tick(Stage::Optimize, 0, 1)?;
    let finish = |mesh: HighOrderMesh, certified: Option<Vec<quality::CertifiedJacobian>>| {
        Finished::new(mesh, straight.clone(), certified, &basis, &cache, &opts.optimize, projector, ti)
    };
    let mut done = finish(mesh, certified)?;
    let mut restarted = false;
    if let (Some(mut second), true) = (straight_mesh, done.invalid() > 0) {
        // A second start: the whole load in one linear solve on the straight
        // mesh, then the optimisation; kept if it leaves fewer invalid cells.
        let full = solve_increments(&mut second, &linear_kernel, &ubar, finish_stepping, &mut timings, &mut tick)?;
        append_solves(&mut solved, full);
        let other = finish(second, None)?;
        if other.invalid() < done.invalid() {
            (done, restarted) = (other, true);
        }
    }
    let Finished { mesh, straight, mut cell_quality, certified, optimization, parent } = done;
    // Cells split by the optimisation come from the cell at `parent`.
    let input_cell: Vec<usize> = parent.iter().map(|&c| input_cell[c]).collect();
    let fibres: Vec<_> = parent.iter().map(|&c| fibres[c]).collect();
    let ti = ti.map(|_| &fibres[..]);
    if optimization.ran && ti.is_some() {
        // Q4, Q5 of the moved cells need their fibres.
        cell_quality = quality::cell_qualities(&cache, &mesh.coords, Some(&straight), &mesh.cells, ti);
    }
    timings.optimize = t.elapsed().as_secs_f64();
    let mut q = quality::summarize(&cell_quality);
    quality::add_certified(&mut q, &certified);
    if let Some(stop) = &mut solved.stopped {
        stop.restarted = restarted;
        if q.n_certified_invalid > 0 {
            let c = certified.iter().position(|c| c.verdict == quality::Verdict::Invalid).unwrap_or(0);
            return Err(Error::InvalidElement(format!(
                "cell {c} is inverted (certified: det J <= 0 somewhere in it) after optimisation, with {} cells \
                 invalid in all; the elastic stage had stopped at load {:.4}: {}",
                q.n_certified_invalid, stop.load, stop.detail
            )));
        }
    }
    timings.total = t0.elapsed().as_secs_f64();
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
        reoriented_cells: reoriented,
        removed_caps,
        repair: repair_summary,
        input_cell,
        projected_nodes,
        max_projection_distance: max_dist,
        quality: q,
        timings,
        newton_history: solved.newton_history,
        linear_solver: solved.linear_solver,
        solver_iterations: solved.solver_iterations,
        solver_per_solve: solved.solver_per_solve,
        fallback_per_solve: solved.fallback_per_solve,
        fallbacks: solved.fallbacks,
        elastic_stop: solved.stopped,
        optimization,
    };
    Ok(CurvedMesh { mesh, straight, cell_quality, report })
}

/// How the load increments are driven (paper Table 1).
#[derive(Debug, Clone, PartialEq)]
pub struct Stepping {
    /// Number of load increments n ≥ 1.
    pub increments: usize,
    /// Put the internal force −R(x_n) on the right-hand side (IIL, CIL, Newton).
    pub residual: bool,
    /// Newton–Raphson to ‖R_f‖/‖R_0‖ < tolerance in at most max_iterations (NONLINEAR).
    pub newton: Option<(f64, usize)>,
    pub solver: SolverChoice,
    /// Fill-reducing ordering of the direct solver.
    pub direct_ordering: DirectOrdering,
    /// Adaptive load stepping: step back and halve an increment that makes a
    /// cell invalid (certified check, [`quality::ValidityCheck`]) or whose
    /// assembly or Newton iteration fails.
    pub adaptive: bool,
    /// Adaptive load stepping: at most this many halvings, so the smallest
    /// step is 1/(n·2^max_splits) of the load.
    pub max_splits: usize,
    /// Condense the cell-interior nodes out of the linear systems.
    pub condense: bool,
    /// At the limit of adaptive stepping, stop at the last accepted geometry
    /// and report where ([`IncrementsReport::stopped`]) instead of failing.
    pub finish: bool,
}

impl Stepping {
    /// `increments` equal ILE steps, built-in solver, adaptive stepping on
    /// with [`DEFAULT_MAX_SPLITS`].
    pub fn new(increments: usize) -> Stepping {
        Stepping {
            increments,
            residual: false,
            newton: None,
            solver: SolverChoice::Auto,
            direct_ordering: DirectOrdering::Auto,
            adaptive: true,
            max_splits: DEFAULT_MAX_SPLITS,
            condense: false,
            finish: false,
        }
    }
}

/// Why adaptive load stepping rejected an increment.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepBackReason {
    /// An assembly on the new geometry, or the sampled check after an
    /// increment, met det J ≤ 0 at a quadrature point.
    SampledInvalid,
    /// The certified check found a cell with det J ≤ 0 somewhere after the increment.
    CertifiedInvalid,
    /// Newton–Raphson did not converge, or its residual was not finite.
    NewtonFailed,
    /// An earlier increment, checked only at sample points, had inverted a
    /// cell between them (found by the certified check, or by the assembly
    /// at the start of the next increment): the run went back to load 0 and
    /// certified every increment from there.
    Restarted,
}

impl StepBackReason {
    pub fn name(self) -> &'static str {
        match self {
            StepBackReason::SampledInvalid => "sampled-invalid",
            StepBackReason::CertifiedInvalid => "certified-invalid",
            StepBackReason::NewtonFailed => "newton-failed",
            StepBackReason::Restarted => "restarted",
        }
    }
}

/// One increment that adaptive load stepping rejected and split.
#[derive(Debug, Clone, PartialEq)]
pub struct StepBack {
    /// Load fraction at the start of the rejected increment.
    pub load: f64,
    /// Its size, as a fraction of the whole load.
    pub step: f64,
    pub reason: StepBackReason,
    /// The offending cell, when known.
    pub cell: Option<usize>,
}

/// What [`solve_increments`] reports.
#[derive(Debug, Clone, Default)]
pub struct IncrementsReport {
    /// Unknowns: the free degrees of freedom.
    pub n_free: usize,
    /// Unknowns of the linear systems: `n_free` less the condensed ones.
    pub n_system: usize,
    /// NONLINEAR: relative residual history of each attempted increment.
    pub newton_history: Vec<Vec<f64>>,
    pub linear_solver: &'static str,
    /// Krylov iterations of each linear solve (rejected increments included).
    pub solver_iterations: Vec<usize>,
    /// The solver that produced each solve's solution.
    pub solver_per_solve: Vec<SolvedBy>,
    /// Per solve, why the first choice of solver did not produce it.
    pub fallback_per_solve: Vec<Option<FallbackReason>>,
    /// Solves that fell back.
    pub fallbacks: usize,
    /// Load fraction reached by each accepted increment (the last is 1); its
    /// length is the number of increments taken.
    pub load_fractions: Vec<f64>,
    /// The increments rejected by adaptive load stepping, in order.
    pub step_backs: Vec<StepBack>,
    /// Certified bounds of every cell on the geometry the run ended with,
    /// when its last check was the certified one.
    pub certified: Option<Vec<quality::CertifiedJacobian>>,
    /// With [`Stepping::finish`]: where adaptive stepping gave up; the mesh
    /// is left at the last accepted geometry.
    pub stopped: Option<ElasticStop>,
}

impl IncrementsReport {
    /// Record what one linear solve reports.
    fn record_solve(&mut self, stats: &SolveStats) {
        self.solver_iterations.push(stats.iterations);
        self.solver_per_solve.push(stats.solved_by);
        self.fallback_per_solve.push(stats.fallback);
        self.fallbacks += usize::from(stats.fallback.is_some());
    }

    /// Size of each accepted increment, as a fraction of the whole load.
    pub fn steps(&self) -> Vec<f64> {
        let mut prev = 0.0;
        self.load_fractions
            .iter()
            .map(|&l| {
                let h = l - prev;
                prev = l;
                h
            })
            .collect()
    }
}

/// The solver `choice` asks for, set up for this mesh and pattern. `Auto`:
/// direct in 2D and up to [`AUTO_DIRECT_MAX_DOFS`] unknowns in 3D, iterative
/// above. The direct solver orders with `ordering`.
fn make_solver(
    choice: SolverChoice,
    ordering: DirectOrdering,
    mesh: &HighOrderMesh,
    dofs: &DofMap,
    pattern: &SymmetricCsc,
) -> Result<Box<dyn LinearSolver>> {
    let iterative = match choice {
        SolverChoice::External(host) => return Ok(Box::new(ExternalAdapter::new(host, pattern))),
        SolverChoice::Direct => false,
        SolverChoice::Iterative => true,
        SolverChoice::Auto => mesh.dim() == 3 && pattern.n > AUTO_DIRECT_MAX_DOFS,
    };
    if !iterative {
        return Ok(Box::new(DirectSolver::try_new_with(pattern, ordering)?));
    }
    // The free dofs of a node are consecutive: nodal blocks for the smoother.
    let levels = multigrid_levels(mesh, dofs);
    Ok(Box::new(IterativeSolver::try_new(pattern, mesh.dim(), levels, IterativeParams::default())?))
}

/// Move `mesh` by the prescribed boundary displacement `ubar` (one value per
/// dof; only the boundary entries are used) in `stepping.increments` steps:
/// each step assembles the kernel's matrix on the current geometry Ω_n and
/// solves K_ff u_f = −K_fd ū h − R_f(x_n) (the residual only with
/// `residual`) for a step h of the load (1/n unless split), then updates
/// x_{n+1} = x_n + u; with `newton`, it then iterates K Δx = −R until
/// convergence. Each solve starts from the secant extrapolation of the two
/// previous increments' solutions ([`Predictor`]).
///
/// With `stepping.adaptive`, an increment is rejected when its Newton
/// iteration fails (or meets det J ≤ 0), or when it leaves a cell invalid
/// that was valid at its start ([`quality::ValidityCheck`]); the geometry is
/// then restored and the step halved, at most `max_splits` times per nominal
/// increment (the full step comes back at the next nominal increment). The
/// check after an increment is det J at the quadrature points of degree 2p
/// (cheap: about 1–2 % of an increment at p = 4 in 3D), and the certified one
/// (Bernstein bounds, det J > 0 everywhere) after the last increment and
/// after every increment once the run has stepped back. If the certified
/// check finds a cell that was already inverted before the increment, or an
/// assembly fails on the geometry an increment starts from, an earlier
/// increment inverted it between the sample points: the run starts again
/// from load 0, certifying every increment ([`StepBackReason::Restarted`]).
/// At the limit, or on a failure without `adaptive`, the run fails with
/// [`Error::InvalidElement`] or [`Error::Solver`], and `mesh` is left as it
/// was on entry.
pub fn solve_increments<K: ElementKernel>(
    mesh: &mut HighOrderMesh,
    kernel: &K,
    ubar: &[f64],
    stepping: Stepping,
    timings: &mut Timings,
    tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
) -> Result<IncrementsReport> {
    let increments = stepping.increments;
    if increments == 0 {
        return Err(Error::InvalidInput("the number of increments must be at least 1".into()));
    }
    if stepping.adaptive && stepping.max_splits > MAX_SPLITS {
        return Err(Error::InvalidInput(format!(
            "max_splits must be at most {MAX_SPLITS}, got {}",
            stepping.max_splits
        )));
    }
    let dofs = if stepping.condense { DofMap::condensed(mesh) } else { DofMap::new(mesh) };
    let mut out = IncrementsReport { n_free: dofs.n_free, n_system: dofs.n_system, ..Default::default() };
    if dofs.n_free == 0 || ubar.iter().all(|&u| u == 0.0) {
        for (x, u) in mesh.coords.iter_mut().zip(ubar) {
            *x += u;
        }
        out.load_fractions.push(1.0);
        return Ok(out);
    }
    let start = mesh.coords.clone();
    let result = step_through(mesh, kernel, ubar, &stepping, &dofs, timings, tick, &mut out);
    if result.is_err() {
        mesh.coords.copy_from_slice(&start);
    }
    result.map(|()| out)
}

/// Largest `max_splits` accepted: the smallest step is then 2⁻³⁰ of a nominal one.
pub const MAX_SPLITS: usize = 30;

/// Default `max_splits` of adaptive load stepping: the smallest step is 1/64 of a nominal one.
pub const DEFAULT_MAX_SPLITS: usize = 6;

/// A rejected increment: why, where, and the message of the error it becomes
/// when it cannot be split any more.
enum Failure {
    Retry {
        reason: StepBackReason,
        cell: Option<usize>,
        detail: String,
    },
    /// The assembly failed on the geometry at the start of the increment.
    AtStart(String),
    Fatal(Error),
}

impl From<Error> for Failure {
    fn from(e: Error) -> Failure {
        match e {
            Error::InvalidElement(detail) => {
                Failure::Retry { reason: StepBackReason::SampledInvalid, cell: None, detail }
            }
            e => Failure::Fatal(e),
        }
    }
}

/// The increment loop of [`solve_increments`]. The load is counted in ticks
/// of 1/(n·2^splits), so split steps add up exactly to the nominal ones.
#[allow(clippy::too_many_arguments)]
fn step_through<K: ElementKernel>(
    mesh: &mut HighOrderMesh,
    kernel: &K,
    ubar: &[f64],
    stepping: &Stepping,
    dofs: &DofMap,
    timings: &mut Timings,
    tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
    out: &mut IncrementsReport,
) -> Result<()> {
    let increments = stepping.increments;
    let t = Instant::now();
    let pattern = dofs.pattern(mesh);
    let plan = AssemblyPlan::new(mesh, dofs, &pattern);
    let mut solver = make_solver(stepping.solver.clone(), stepping.direct_ordering, mesh, dofs, &pattern)?;
    out.linear_solver = solver.name();
    let check = stepping.adaptive.then(|| {
        quality::ValidityCheck::new(LagrangeBasis::new(&NodeSet::new(mesh.simplex, mesh.order, mesh.spacing)))
    });
    timings.setup += t.elapsed().as_secs_f64();
    let mut ctx = IncrementContext {
        system: Assembled::default(),
        dofs,
        pattern: &pattern,
        plan: &plan,
        kernel,
        residual: stepping.residual || stepping.newton.is_some(),
        newton: stepping.newton,
        check: check.as_ref(),
    };
    let splits = if stepping.adaptive { stepping.max_splits } else { 0 };
    let nominal = 1u64 << splits;
    let total = increments as u64 * nominal;
    let mut predictor = Predictor::new(dofs.n_free);
    let mut u = vec![0.0; dofs.n_free];
    let mut du = vec![0.0; dofs.n_free];
    let mut step = vec![0.0; ubar.len()];
    let start = mesh.coords.clone();
    let mut saved = mesh.coords.clone();
    let (mut at, mut depth) = (0u64, 0usize);
    // The sampled check after each increment, the certified one after the
    // last, after any step back, and after every increment once an inversion
    // has slipped between the sample points.
    let mut certify_all = false;
    while at < total {
        let k = (at / nominal) as usize;
        tick(Stage::Increment, k, increments)?;
        let len = nominal >> depth;
        let (from, h) = (at as f64 / total as f64, len as f64 / total as f64);
        for (s, b) in step.iter_mut().zip(ubar) {
            *s = b * h;
        }
        saved.copy_from_slice(&mesh.coords);
        predictor.predict_into(h, &mut u);
        let certified = certify_all || at + len == total || !out.step_backs.is_empty();
        match ctx.attempt(mesh, solver.as_mut(), &step, &mut u, &mut du, &saved, certified, timings, out) {
            Ok(Some(c)) if certified && !certify_all => {
                // An earlier increment, checked only at the sample points,
                // inverted cell c between them: start again from the
                // straight mesh with the certified check after every step.
                out.step_backs.push(StepBack { load: from, step: h, reason: StepBackReason::Restarted, cell: Some(c) });
                mesh.coords.copy_from_slice(&start);
                out.load_fractions.clear();
                (at, depth, certify_all) = (0, 0, true);
                predictor = Predictor::new(dofs.n_free);
            }
            Ok(_) => {
                predictor.accept(&u, h);
                at += len;
                out.load_fractions.push(at as f64 / total as f64);
                if at % nominal == 0 {
                    depth = 0;
                }
            }
            Err(Failure::Fatal(e)) => return Err(e),
            Err(Failure::AtStart(detail)) if stepping.finish && certify_all => {
                out.stopped = Some(ElasticStop {
                    load: from,
                    reason: StepBackReason::SampledInvalid,
                    cell: None,
                    detail,
                    restarted: false,
                });
                out.certified = None;
                return Ok(());
            }
            Err(Failure::AtStart(detail)) if !stepping.adaptive || certify_all => {
                return Err(Error::InvalidElement(format!(
                    "{detail} in increment {} of {increments}; try more increments or another Poisson ratio",
                    k + 1
                )))
            }
            Err(Failure::AtStart(_)) => {
                // An earlier increment left det J ≤ 0 at a quadrature point of
                // the assembly between the points of the sampled check.
                out.step_backs.push(StepBack { load: from, step: h, reason: StepBackReason::Restarted, cell: None });
                mesh.coords.copy_from_slice(&start);
                out.load_fractions.clear();
                (at, depth, certify_all) = (0, 0, true);
                predictor = Predictor::new(dofs.n_free);
            }
            Err(Failure::Retry { reason, cell, detail }) => {
                mesh.coords.copy_from_slice(&saved);
                if depth >= splits && stepping.finish && reason != StepBackReason::NewtonFailed {
                    out.stopped = Some(ElasticStop { load: from, reason, cell, detail, restarted: false });
                    out.certified = None;
                    return Ok(());
                }
                if depth >= splits {
                    let mut place = format!("in increment {} of {increments}", k + 1);
                    if stepping.adaptive {
                        place += &format!(
                            " (load {from:.4} to {:.4}, after halving the step {splits} times: the limit of adaptive \
                             stepping)",
                            from + h
                        );
                    }
                    return Err(match reason {
                        StepBackReason::NewtonFailed => Error::Solver(format!(
                            "{detail} {place}; try more increments, or the CIL or ILE formulation"
                        )),
                        _ if stepping.adaptive => Error::InvalidElement(format!(
                            "{detail} {place}; try more increments or another Poisson ratio, or turn adaptive \
                             stepping off to get the mesh with its invalid cells reported (a cell no step keeps \
                             valid, e.g. a kept boundary cap)"
                        )),
                        _ => Error::InvalidElement(format!(
                            "{detail} {place}; try more increments or another Poisson ratio"
                        )),
                    });
                }
                out.step_backs.push(StepBack { load: from, step: h, reason, cell });
                depth += 1;
                predictor.step_back();
            }
        }
    }
    Ok(())
}

/// What one increment needs besides the geometry.
struct IncrementContext<'a, K> {
    /// The last assembled system; its buffers are reused.
    system: Assembled,
    dofs: &'a DofMap,
    pattern: &'a SymmetricCsc,
    plan: &'a AssemblyPlan,
    kernel: &'a K,
    residual: bool,
    newton: Option<(f64, usize)>,
    check: Option<&'a quality::ValidityCheck>,
}

impl<K: ElementKernel> IncrementContext<'_, K> {
    /// One increment from the geometry `saved` (= `mesh.coords` on entry)
    /// with prescribed values `step`, starting the solve from `u`, then the
    /// validity check (certified or sampled). Ok(Some(c)): accepted, but cell
    /// c was already invalid at the start.
    #[allow(clippy::too_many_arguments)]
    fn attempt(
        &mut self,
        mesh: &mut HighOrderMesh,
        solver: &mut dyn LinearSolver,
        step: &[f64],
        u: &mut [f64],
        du: &mut [f64],
        saved: &[f64],
        certified: bool,
        timings: &mut Timings,
        out: &mut IncrementsReport,
    ) -> std::result::Result<Option<usize>, Failure> {
        let dofs = self.dofs;
        let t = Instant::now();
        // det J ≤ 0 here is at the start geometry: no split of this increment helps.
        let system = &mut self.system;
        assemble_into(mesh, &mesh.coords, dofs, self.pattern, self.plan, self.kernel, step, self.residual, system)
            .map_err(|e| match e {
                Error::InvalidElement(detail) => Failure::AtStart(detail),
                e => Failure::Fatal(e),
            })?;
        timings.assembly += t.elapsed().as_secs_f64();
        let r0 = system.rhs_norm.max(f64::MIN_POSITIVE);
        let t = Instant::now();
        let n = dofs.n_system;
        let stats = solver.solve(self.pattern, &system.values, &system.rhs, &mut u[..n]).map_err(Failure::Fatal)?;
        out.record_solve(&stats);
        system.recover_interior(mesh, dofs, step, u);
        timings.solve += t.elapsed().as_secs_f64();
        for (dof, x) in mesh.coords.iter_mut().enumerate() {
            let f = dofs.free[dof];
            *x += if f == usize::MAX { step[dof] } else { u[f] };
        }
        if let Some((tolerance, max_iterations)) = self.newton {
            let zero = vec![0.0; step.len()];
            let mut hist = vec![1.0];
            let mut converged = false;
            for _ in 0..max_iterations {
                let t = Instant::now();
                let assembled =
                    assemble_into(mesh, &mesh.coords, dofs, self.pattern, self.plan, self.kernel, &zero, true, system);
                timings.assembly += t.elapsed().as_secs_f64();
                if let Err(e) = assembled {
                    out.newton_history.push(hist);
                    return Err(e.into());
                }
                let ratio = system.rhs_norm / r0;
                hist.push(ratio);
                if !ratio.is_finite() {
                    out.newton_history.push(hist);
                    return Err(Failure::Retry {
                        reason: StepBackReason::NewtonFailed,
                        cell: None,
                        detail: "Newton residual is not finite".into(),
                    });
                }
                if ratio < tolerance {
                    converged = true;
                    break;
                }
                let t = Instant::now();
                du.fill(0.0);
                let n = dofs.n_system;
                let stats =
                    solver.solve(self.pattern, &system.values, &system.rhs, &mut du[..n]).map_err(Failure::Fatal)?;
                out.record_solve(&stats);
                system.recover_interior(mesh, dofs, &zero, du);
                timings.solve += t.elapsed().as_secs_f64();
                for (dof, x) in mesh.coords.iter_mut().enumerate() {
                    let f = dofs.free[dof];
                    if f != usize::MAX {
                        *x += du[f];
                    }
                }
            }
            let last = *hist.last().expect("history starts with 1");
            out.newton_history.push(hist);
            if !converged {
                return Err(Failure::Retry {
                    reason: StepBackReason::NewtonFailed,
                    cell: None,
                    detail: format!(
                        "Newton-Raphson did not converge in {max_iterations} iterations (relative residual {last:.2e})"
                    ),
                });
            }
        }
        let Some(check) = self.check else { return Ok(None) };
        let t = Instant::now();
        // Only a cell that this increment made invalid rejects it; one that
        // was already invalid at its start is returned to the caller.
        let (mut new, mut old) = (None, None);
        // Certified: the bounds of every cell are kept for the quality stage,
        // which would otherwise compute them again on the final mesh.
        out.certified = certified.then(|| check.certify_cells(&mesh.coords, &mesh.cells));
        let invalid: Vec<usize> = match &out.certified {
            Some(cells) => (0..cells.len()).filter(|&c| cells[c].verdict == quality::Verdict::Invalid).collect(),
            None => check.invalid_cells(&mesh.coords, &mesh.cells, certified),
        };
        for c in invalid {
            if check.cell_is_invalid(saved, mesh.cell(c), certified) {
                old = old.or(Some(c));
            } else {
                new = Some(c);
                break;
            }
        }
        timings.check += t.elapsed().as_secs_f64();
        match new {
            Some(c) if certified => Err(Failure::Retry {
                reason: StepBackReason::CertifiedInvalid,
                cell: Some(c),
                detail: format!("cell {c} is inverted (certified: det J <= 0 somewhere in it)"),
            }),
            Some(c) => Err(Failure::Retry {
                reason: StepBackReason::SampledInvalid,
                cell: Some(c),
                detail: format!("cell {c} has det J <= 0 at a quadrature point"),
            }),
            None => Ok(old),
        }
    }
}

/// Secant predictor of the increment solutions u_k (free dofs) for steps of
/// any size h_k. With the rates v_k = u_k / h_k (mean dx/dλ over increment
/// k, i.e. the rate at its midpoint to second order), extrapolate the rate
/// linearly through the midpoints of the two previous increments:
///
/// u_k ≈ h_k [v_(k-1) + (v_(k-1) − v_(k-2)) (h_(k-1) + h_k) / (h_(k-2) + h_(k-1))],
///
/// exact when x(λ) is quadratic in the load λ, and 2 u_(k-1) − u_(k-2) for
/// equal steps. After one previous increment, u_k ≈ h_k v_(k-1); after a step
/// back the curvature term is dropped until two increments are known again
/// (the path was just found to bend).
#[derive(Debug, Clone)]
pub struct Predictor {
    v1: Vec<f64>,
    v2: Vec<f64>,
    h1: f64,
    h2: f64,
    known: usize,
}

impl Predictor {
    pub fn new(n: usize) -> Predictor {
        Predictor { v1: vec![0.0; n], v2: vec![0.0; n], h1: 0.0, h2: 0.0, known: 0 }
    }

    /// The guess for an increment of size `h`, written into `u`.
    pub fn predict_into(&self, h: f64, u: &mut [f64]) {
        match self.known {
            0 => u.fill(0.0),
            1 => {
                for (x, v) in u.iter_mut().zip(&self.v1) {
                    *x = h * v;
                }
            }
            _ => {
                let r = (self.h1 + h) / (self.h2 + self.h1);
                for ((x, v1), v2) in u.iter_mut().zip(&self.v1).zip(&self.v2) {
                    *x = h * (v1 + r * (v1 - v2));
                }
            }
        }
    }

    /// Record the solution `u` of an accepted increment of size `h`.
    pub fn accept(&mut self, u: &[f64], h: f64) {
        std::mem::swap(&mut self.v1, &mut self.v2);
        for (v, x) in self.v1.iter_mut().zip(u) {
            *v = x / h;
        }
        (self.h2, self.h1) = (self.h1, h);
        self.known = (self.known + 1).min(2);
    }

    /// Forget the curvature term after a rejected increment.
    pub fn step_back(&mut self) {
        self.known = self.known.min(1);
    }
}

/// Batch size of projector calls.
const PROJECT_BATCH: usize = 65_536;

/// Project every node classified on an entity; returns node → projected point.
///
/// Rejects a projector error, a non-finite point, or a point farther from the
/// straight node than the longest edge of the cells around it (a projection
/// onto the wrong entity).
fn project_boundary(
    mesh: &HighOrderMesh,
    linear: &LinearMesh,
    projector: &dyn Projector,
) -> Result<Vec<(usize, [f64; 3])>> {
    let mut groups: BTreeMap<(usize, i32), Vec<usize>> = BTreeMap::new();
    for (n, c) in mesh.constraint.iter().enumerate() {
        if let NodeConstraint::OnEntity { dim, tag } = *c {
            groups.entry((dim, tag)).or_default().push(n);
        }
    }
    if groups.is_empty() {
        return Ok(Vec::new());
    }
    // Local size: longest vertex-to-vertex edge of the cells around each node.
    let mut size = vec![0.0f64; mesh.n_nodes()];
    let npc_lin = linear.dim + 1;
    for (c, lv) in linear.cells.chunks_exact(npc_lin).enumerate() {
        let mut h: f64 = 0.0;
        for i in 0..npc_lin {
            for j in i + 1..npc_lin {
                let (a, b) = (linear.vertex(lv[i]), linear.vertex(lv[j]));
                h = h.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt());
            }
        }
        for &n in mesh.cell(c) {
            size[n] = size[n].max(h);
        }
    }
    let mut out = Vec::new();
    for ((edim, tag), ids) in groups {
        for chunk in ids.chunks(PROJECT_BATCH) {
            let pts: Vec<[f64; 3]> = chunk.iter().map(|&n| mesh.node(n)).collect();
            let mut proj = vec![[f64::NAN; 3]; pts.len()];
            projector
                .project(edim, tag, &pts, &mut proj)
                .map_err(|m| Error::Projection(format!("projector failed on entity (dim {edim}, tag {tag}): {m}")))?;
            for ((&n, x), y) in chunk.iter().zip(&pts).zip(&proj) {
                let mut y = *y;
                if mesh.dim() == 2 {
                    y[2] = 0.0;
                }
                if !y.iter().all(|v| v.is_finite()) {
                    return Err(Error::Projection(format!(
                        "projector returned a non-finite point for node {n} on entity (dim {edim}, tag {tag})"
                    )));
                }
                let d = ((y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2) + (y[2] - x[2]).powi(2)).sqrt();
                if d > size[n] {
                    return Err(Error::Projection(format!(
                        "projector moved node {n} on entity (dim {edim}, tag {tag}) by {d:.3e}, more than the size \
                         of its elements ({:.3e}): is the tag mapped to the right entity?",
                        size[n]
                    )));
                }
                out.push((n, y));
            }
        }
    }
    Ok(out)
}

/// Normalise user fibres: one finite non-zero vector per cell.
fn checked_fibres(f: &[[f64; 3]], n_cells: usize) -> Result<Vec<[f64; 3]>> {
    if f.len() != n_cells {
        return Err(Error::InvalidInput(format!("{} fibre directions given for {n_cells} cells", f.len())));
    }
    f.iter()
        .enumerate()
        .map(|(c, v)| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if n.is_finite() && n > 0.0 {
                Ok([v[0] / n, v[1] / n, v[2] / n])
            } else {
                Err(Error::InvalidInput(format!("fibre direction of cell {c} is zero or not finite")))
            }
        })
        .collect()
}

/// The paper's fibres: −x inside; on cells with a boundary facet, tangent to
/// that facet (in 3D, −x projected onto the facet's plane, or an edge of the
/// facet when −x is normal to it).
pub fn default_fibres(linear: &LinearMesh, topo: &Topology) -> Vec<[f64; 3]> {
    let dim = linear.dim;
    let mut fibres = vec![[-1.0, 0.0, 0.0]; linear.n_cells()];
    let unit = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        (n > 1e-12).then(|| [v[0] / n, v[1] / n, v[2] / n])
    };
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let mut boundary = vec![false; if dim == 2 { topo.edges.len() } else { topo.faces.len() }];
    for &f in &topo.boundary_facets {
        boundary[f] = true;
    }
    for (c, fibre) in fibres.iter_mut().enumerate() {
        if dim == 2 {
            let ne = topo.simplex.edges().len();
            if let Some(&e) = topo.cell_edges[c * ne..(c + 1) * ne].iter().find(|&&e| boundary[e]) {
                let [a, b] = topo.edges[e];
                if let Some(t) = unit(sub(linear.vertex(b), linear.vertex(a))) {
                    *fibre = t;
                }
            }
        } else if let Some(&f) = topo.cell_faces[c * 4..(c + 1) * 4].iter().find(|&&f| boundary[f]) {
            let [a, b, d] = topo.faces[f].map(|v| linear.vertex(v));
            let (u, v) = (sub(b, a), sub(d, a));
            let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            if let Some(n) = unit(n) {
                let m = [-1.0, 0.0, 0.0];
                let dot = m[0] * n[0];
                let proj = [m[0] - dot * n[0], -dot * n[1], -dot * n[2]];
                *fibre = unit(proj).or_else(|| unit(u)).unwrap_or(*fibre);
            }
        }
    }
    fibres
}

#[cfg(test)]
mod tests {
    use super::*;

    /// x(λ) = a λ + b λ² per dof: the increment over [λ0, λ0 + h].
    fn increment(l0: f64, h: f64) -> Vec<f64> {
        let (a, b) = ([1.0, -2.0, 0.5], [3.0, 0.25, -4.0]);
        (0..3).map(|i| a[i] * h + b[i] * ((l0 + h).powi(2) - l0 * l0)).collect()
    }

    #[test]
    fn secant_predictor_is_exact_on_quadratic_paths_with_unequal_steps() {
        let steps = [0.25, 0.125, 0.0625, 0.0625, 0.25, 0.03125];
        let mut p = Predictor::new(3);
        let mut l = 0.0;
        let mut u = vec![0.0; 3];
        for (k, &h) in steps.iter().enumerate() {
            p.predict_into(h, &mut u);
            let exact = increment(l, h);
            if k >= 2 {
                for (g, e) in u.iter().zip(&exact) {
                    assert!((g - e).abs() < 1e-13, "step {k}: {u:?} vs {exact:?}");
                }
            }
            p.accept(&exact, h);
            l += h;
        }
    }

    #[test]
    fn secant_predictor_with_equal_steps_is_two_u1_minus_u2_and_resets_after_a_step_back() {
        let mut p = Predictor::new(2);
        let mut u = vec![9.0; 2];
        p.predict_into(0.1, &mut u);
        assert_eq!(u, [0.0, 0.0]);
        p.accept(&[1.0, 2.0], 0.1);
        p.predict_into(0.1, &mut u);
        assert!((u[0] - 1.0).abs() < 1e-15 && (u[1] - 2.0).abs() < 1e-15);
        p.accept(&[1.5, 2.0], 0.1);
        p.predict_into(0.1, &mut u);
        assert!((u[0] - 2.0).abs() < 1e-14 && (u[1] - 2.0).abs() < 1e-14, "{u:?}");
        // After a step back: first order, scaled by the step ratio.
        p.step_back();
        p.predict_into(0.05, &mut u);
        assert!((u[0] - 0.75).abs() < 1e-14 && (u[1] - 1.0).abs() < 1e-14, "{u:?}");
    }

    #[test]
    fn steps_are_the_differences_of_the_load_fractions() {
        let r = IncrementsReport { load_fractions: vec![0.5, 0.75, 1.0], ..Default::default() };
        assert_eq!(r.steps(), [0.5, 0.25, 0.25]);
    }
}
