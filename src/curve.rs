//! The one orchestrator: elevate, project, solve in load increments, measure.
//!
//! [`curve`] takes a linear mesh and a projector and returns a new curved
//! mesh; the input is never modified, so a failed run leaves nothing
//! half-curved.

use std::collections::BTreeMap;
use std::time::Instant;

use crate::assembly::{
    assemble, multigrid_levels, AssemblyPlan, DofMap, ElementKernel, LinearElasticKernel, MaterialKernel, TangentMode,
};
use crate::geometry::Projector;
use crate::mapping::ElementCache;
use crate::material::{make_material, LinearElastic, MaterialModel};
use crate::mesh::{remove_boundary_caps, validate_and_orient, HighOrderMesh, LinearMesh, NodeConstraint, Topology};
use crate::quadrature::simplex_rule;
use crate::quality::{self, ElementQuality, MeshQuality};
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing};
use crate::solver::{
    DirectSolver, ExternalAdapter, IterativeParams, IterativeSolver, LinearSolver, SolverChoice, SymmetricCsc,
    AUTO_DIRECT_MAX_DOFS,
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
    /// Remove the boundary caps of a 3D mesh before curving (default on): tets
    /// with two faces on one smooth surface, which no curving keeps valid
    /// (see [`crate::mesh::caps`]). The curved mesh then has fewer cells.
    pub remove_caps: bool,
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
            remove_caps: true,
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
}

/// What a run reports.
#[derive(Debug, Clone)]
pub struct CurveReport {
    pub order: usize,
    pub formulation: Formulation,
    pub material: MaterialModel,
    pub young: f64,
    pub poisson: f64,
    pub increments: usize,
    pub nodes: usize,
    /// Unknowns of the linear system (free degrees of freedom).
    pub dofs: usize,
    pub cells: usize,
    /// Cells whose input orientation was negative and was flipped.
    pub reoriented_cells: usize,
    /// Boundary caps removed before curving (`CurveOptions::remove_caps`).
    pub removed_caps: usize,
    /// For each cell of the curved mesh, its index among the input cells.
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
    /// Krylov iterations of each linear solve (zeros for a direct solver).
    pub solver_iterations: Vec<usize>,
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
    LinearElastic::try_from_young_poisson(opts.young, opts.poisson)
}

/// Curve `linear` onto the geometry of `projector` (SPEC section 1).
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
    };
    let mode = match opts.formulation {
        Formulation::Cil | Formulation::Nonlinear => TangentMode::Consistent,
        _ => TangentMode::Initial,
    };
    let linear_iso = matches!(opts.formulation, Formulation::Linear | Formulation::Ile)
        && !opts.material.is_transversely_isotropic();
    let solved = if linear_iso {
        // Every isotropic model is calibrated so that c(F = I) = c_lin: the fast
        // kernel, with a rule of degree 2p − 2, exact on straight-sided cells
        // (∇N_a·∇N_b has degree 2p − 2 there), for half the points of 2p at
        // p = 4 in 3D (64 against 125). Curved cells are integrated
        // approximately by either rule.
        let rule = simplex_rule(topo.simplex, (2 * opts.order).saturating_sub(2).max(1));
        let kernel = LinearElasticKernel { cache: ElementCache::new(&basis, &rule), material };
        solve_increments(&mut mesh, &kernel, &ubar, stepping, &mut timings, &mut tick)?
    } else {
        let kernel = MaterialKernel::new(&mesh, &straight, &cache, model.as_ref(), mode, &fibres);
        solve_increments(&mut mesh, &kernel, &ubar, stepping, &mut timings, &mut tick)?
    };
    if let Some(i) = mesh.coords.iter().position(|x| !x.is_finite()) {
        return Err(Error::Solver(format!("the solution is not finite at node {}", i / dim)));
    }

    // 5. Quality.
    let t = Instant::now();
    tick(Stage::Quality, 0, 1)?;
    let ti = opts.material.is_transversely_isotropic().then_some(&fibres[..]);
    let cell_quality = quality::cell_qualities(&quality::sampling_cache(&basis), &mesh.coords, &mesh.cells, ti);
    let mut q = quality::summarize(&cell_quality);
    if let Some(certified) = quality::certify_cells(&basis, &mesh.coords, &mesh.cells) {
        quality::add_certified(&mut q, &certified);
    }
    timings.quality = t.elapsed().as_secs_f64();
    timings.total = t0.elapsed().as_secs_f64();
    let report = CurveReport {
        order: opts.order,
        formulation: opts.formulation,
        material: opts.material,
        young: opts.young,
        poisson: opts.poisson,
        increments,
        nodes: mesh.n_nodes(),
        dofs: solved.n_free,
        cells: mesh.n_cells(),
        reoriented_cells: reoriented,
        removed_caps: n_input_cells - input_cell.len(),
        input_cell,
        projected_nodes,
        max_projection_distance: max_dist,
        quality: q,
        timings,
        newton_history: solved.newton_history,
        linear_solver: solved.linear_solver,
        solver_iterations: solved.solver_iterations,
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
}

/// What [`solve_increments`] reports.
#[derive(Debug, Clone, Default)]
pub struct IncrementsReport {
    /// Unknowns of the linear system.
    pub n_free: usize,
    /// NONLINEAR: relative residual history of each increment.
    pub newton_history: Vec<Vec<f64>>,
    pub linear_solver: &'static str,
    /// Krylov iterations of each linear solve.
    pub solver_iterations: Vec<usize>,
}

/// The solver `choice` asks for, set up for this mesh and pattern. `Auto`:
/// direct in 2D and up to [`AUTO_DIRECT_MAX_DOFS`] unknowns in 3D, iterative above.
fn make_solver(
    choice: SolverChoice,
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
        return Ok(Box::new(DirectSolver::try_new(pattern)?));
    }
    // The free dofs of a node are consecutive: nodal blocks for the smoother.
    let levels = multigrid_levels(mesh, dofs);
    Ok(Box::new(IterativeSolver::try_new(pattern, mesh.dim(), levels, IterativeParams::default())?))
}

fn euclid(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Move `mesh` by the prescribed boundary displacement `ubar` (one value per
/// dof; only the boundary entries are used) in `stepping.increments` steps:
/// each step assembles the kernel's matrix on the current geometry Ω_n and
/// solves K_ff u_f = −K_fd ū/n (− R_f(x_n) with `residual`), then updates
/// x_{n+1} = x_n + u; with `newton`, it then iterates K Δx = −R until
/// convergence. Each solve starts from the secant extrapolation of the two
/// previous increments' solutions.
pub fn solve_increments<K: ElementKernel>(
    mesh: &mut HighOrderMesh,
    kernel: &K,
    ubar: &[f64],
    stepping: Stepping,
    timings: &mut Timings,
    tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
) -> Result<IncrementsReport> {
    let increments = stepping.increments;
    let dofs = DofMap::new(mesh);
    let step: Vec<f64> = ubar.iter().map(|u| u / increments as f64).collect();
    let zero = vec![0.0; ubar.len()];
    let mut out = IncrementsReport { n_free: dofs.n_free, ..Default::default() };
    if dofs.n_free == 0 || ubar.iter().all(|&u| u == 0.0) {
        for (x, u) in mesh.coords.iter_mut().zip(ubar) {
            *x += u;
        }
        return Ok(out);
    }
    let t = Instant::now();
    let pattern = dofs.pattern(mesh);
    let plan = AssemblyPlan::new(mesh, &dofs, &pattern);
    let mut solver = make_solver(stepping.solver.clone(), mesh, &dofs, &pattern)?;
    out.linear_solver = solver.name();
    timings.setup += t.elapsed().as_secs_f64();
    let residual = stepping.residual || stepping.newton.is_some();
    // The increment solutions u_(k-1) and u_(k-2), for the next initial guess.
    let mut u = vec![0.0; dofs.n_free];
    let mut du = vec![0.0; dofs.n_free];
    let mut u_prev = vec![0.0; dofs.n_free];
    for k in 0..increments {
        tick(Stage::Increment, k, increments)?;
        let context = |e: Error| match e {
            Error::InvalidElement(m) => Error::InvalidElement(format!(
                "{m} in increment {} of {increments}; try more increments or another Poisson ratio",
                k + 1
            )),
            e => e,
        };
        let t = Instant::now();
        let (values, rhs) =
            assemble(mesh, &mesh.coords, &dofs, &pattern, &plan, kernel, &step, residual).map_err(context)?;
        timings.assembly += t.elapsed().as_secs_f64();
        let r0 = euclid(&rhs).max(f64::MIN_POSITIVE);
        let t = Instant::now();
        // Secant predictor: the increments are equal and the solution path
        // smooth, so u_k ≈ 2 u_(k-1) − u_(k-2) (error O(1/n²) against O(1/n)
        // for u_(k-1) alone): at p = 4, 10 increments, 1–2 PCG iterations
        // after the third increment instead of 6.
        if k >= 2 {
            for (x, p) in u.iter_mut().zip(&mut u_prev) {
                (*x, *p) = (2.0 * *x - *p, *x);
            }
        } else {
            u_prev.copy_from_slice(&u);
        }
        out.solver_iterations.push(solver.solve(&pattern, &values, &rhs, &mut u)?.iterations);
        timings.solve += t.elapsed().as_secs_f64();
        for (dof, x) in mesh.coords.iter_mut().enumerate() {
            let f = dofs.free[dof];
            *x += if f == usize::MAX { step[dof] } else { u[f] };
        }
        let Some((tolerance, max_iterations)) = stepping.newton else { continue };
        let mut hist = vec![1.0];
        let mut converged = false;
        for _ in 0..max_iterations {
            let t = Instant::now();
            let (values, rhs) =
                assemble(mesh, &mesh.coords, &dofs, &pattern, &plan, kernel, &zero, true).map_err(context)?;
            timings.assembly += t.elapsed().as_secs_f64();
            let ratio = euclid(&rhs) / r0;
            hist.push(ratio);
            if !ratio.is_finite() {
                return Err(Error::Solver(format!("Newton residual is not finite in increment {}", k + 1)));
            }
            if ratio < tolerance {
                converged = true;
                break;
            }
            let t = Instant::now();
            du.fill(0.0);
            out.solver_iterations.push(solver.solve(&pattern, &values, &rhs, &mut du)?.iterations);
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
            return Err(Error::Solver(format!(
                "Newton-Raphson did not converge in {max_iterations} iterations in increment {} of {increments} \
                 (relative residual {last:.2e}); try more increments, or the CIL or ILE formulation",
                k + 1
            )));
        }
    }
    Ok(out)
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
