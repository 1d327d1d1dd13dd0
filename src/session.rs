//! A stateful curving session: the Rust object behind the C ABI handle.
//!
//! It owns the validated linear mesh, the settings, the projector and the
//! current high-order mesh. Every setter validates its input and leaves the
//! session unchanged on error; [`Session::run`] replaces the current mesh only
//! when the whole run succeeds, so a failed run leaves nothing half-curved.
//!
//! Before any run (and after changing the order or the boundary) the current
//! mesh is the straight-sided mesh at the current order. The session keeps
//! the mesh prepared for curving ([`Prepared`]: oriented, without its caps,
//! elevated), rebuilt only when the mesh, the order or the cap removal
//! change, and every run curves it from there.

use std::borrow::Cow;
use std::time::Instant;

use crate::curve::{run_retrying, validate_options, CurveOptions, CurveReport, Formulation, Prepared, Progress};
use crate::geometry::Projector;
pub use crate::material::MaterialModel;
use crate::mesh::{validate_and_orient, HighOrderMesh, LinearMesh};
use crate::quality::{self, ElementQuality, MeshQuality};
use crate::reference::{ordering, NodeSet, NodeSpacing};
use crate::solver::{ExternalSolver, SolverChoice};
use crate::{Error, Result};

/// Progress callback: return `false` to cancel.
pub type ProgressFn = Box<dyn FnMut(&Progress) -> bool + Send>;

/// Node orderings the connectivity can be returned in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeOrdering {
    /// hocurve's own: vertices, edges, faces, interior (see `reference::nodes`).
    Native,
    /// gmsh's MSH element node order.
    Gmsh,
    /// VTK Lagrange cell node order.
    Vtk,
}

/// The most worker threads a session's pool may have. Each is an OS thread
/// with its own stack, and a pool is started in full before any work: a
/// count far above the machine's cores only costs time and memory.
pub const MAX_THREADS: usize = 4096;

/// See the module documentation.
pub struct Session {
    /// The validated mesh as the host gave it, with its tags.
    input: LinearMesh,
    /// Cells of the mesh the host gave whose orientation was flipped.
    reoriented: usize,
    /// (entity dimension, tag) of the facets and feature edges held straight:
    /// `prepared` has them untagged.
    straight_tags: Vec<(usize, i32)>,
    /// `input` without the straight tags, prepared for curving at the order:
    /// without its boundary caps (when `opts.remove_caps`), elevated.
    prepared: Prepared,
    opts: CurveOptions,
    projector: Option<Box<dyn Projector + Send>>,
    progress: Option<ProgressFn>,
    /// The host's linear solver; it overrides `opts.solver` while set.
    external_solver: Option<ExternalSolver>,
    threads: usize,
    pool: Option<rayon::ThreadPool>,
    mesh: HighOrderMesh,
    cell_quality: Vec<ElementQuality>,
    quality: MeshQuality,
    report: Option<CurveReport>,
    /// When this session is one process's share of a mesh spread over the
    /// processes of an MPI run: the communicator and global ids.
    partition: Option<Partition>,
}

/// One process's share of a mesh spread over the processes of an MPI run
/// (the `mpi` feature's [`crate::distributed::partitioned`]): plain data,
/// so the session itself does no communication.
#[derive(Debug, Clone)]
pub struct Partition {
    /// The host's communicator, as its Fortran handle (`MPI_Comm_c2f`).
    pub comm: i32,
    /// The host's global id of each vertex of the session's input mesh.
    pub global_vertex: Vec<u64>,
    /// After a successful run, for each node of the curved share: its index
    /// in the whole curved mesh, and the lowest process holding it (its owner).
    pub nodes: Option<(Vec<u64>, Vec<i32>)>,
}

impl Session {
    /// Validate and orient the linear mesh; the session starts at order 1
    /// with the default options otherwise.
    pub fn try_new(linear: LinearMesh) -> Result<Session> {
        let (input, reoriented) = validate_and_orient(&linear)?;
        let opts = CurveOptions { order: 1, ..Default::default() };
        let prepared = prepare(&input, &opts, &[])?;
        let (mesh, cell_quality, quality) = straight(&prepared);
        Ok(Session {
            input,
            reoriented,
            straight_tags: Vec::new(),
            prepared,
            opts,
            projector: None,
            progress: None,
            external_solver: None,
            threads: 0,
            pool: None,
            mesh,
            cell_quality,
            quality,
            report: None,
            partition: None,
        })
    }

    /// A session on one process's share of a distributed mesh
    /// ([`Partition`]); `global_vertex` has one id per vertex of `linear`.
    pub fn try_new_partition(linear: LinearMesh, comm: i32, global_vertex: Vec<u64>) -> Result<Session> {
        if global_vertex.len() != linear.n_vertices() {
            return Err(Error::InvalidInput(format!(
                "{} global ids for {} vertices",
                global_vertex.len(),
                linear.n_vertices()
            )));
        }
        let mut seen = global_vertex.clone();
        seen.sort_unstable();
        if let Some(w) = seen.windows(2).find(|w| w[0] == w[1]) {
            return Err(Error::InvalidInput(format!("global id {} is given to two vertices", w[0])));
        }
        let mut session = Session::try_new(linear)?;
        session.partition = Some(Partition { comm, global_vertex, nodes: None });
        Ok(session)
    }

    /// The share of a distributed mesh this session holds, if it is one.
    pub fn partition(&self) -> Option<&Partition> {
        self.partition.as_ref()
    }

    /// The validated, oriented mesh the host gave, with its tags.
    pub fn input(&self) -> &LinearMesh {
        &self.input
    }

    /// Facets and feature edges held straight: (entity dimension, tag).
    pub fn straight_tags(&self) -> &[(usize, i32)] {
        &self.straight_tags
    }

    /// Whether a projector is set.
    pub fn has_projector(&self) -> bool {
        self.projector.is_some()
    }

    /// Whether the host's linear solver is set.
    pub fn has_external_solver(&self) -> bool {
        self.external_solver.is_some()
    }

    /// The worker threads asked for (0 = one per core).
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Take the projector and the progress callback out (to lend them to
    /// another session); [`Session::restore_callbacks`] puts them back.
    pub fn take_callbacks(&mut self) -> (Option<Box<dyn Projector + Send>>, Option<ProgressFn>) {
        (self.projector.take(), self.progress.take())
    }

    pub fn restore_callbacks(&mut self, callbacks: (Option<Box<dyn Projector + Send>>, Option<ProgressFn>)) {
        (self.projector, self.progress) = callbacks;
    }

    /// Run `f` on this session's worker threads.
    pub fn install<R: Send>(&mut self, f: impl FnOnce(Option<&(dyn Projector + Send)>) -> R + Send) -> Result<R> {
        self.pool()?;
        let (pool, projector) = (self.pool.as_ref().expect("pool was just built"), self.projector.as_deref());
        Ok(pool.install(|| f(projector)))
    }

    fn pool(&mut self) -> Result<&rayon::ThreadPool> {
        if self.pool.is_none() {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(self.threads)
                .thread_name(|i| format!("hocurve-{i}"))
                .build()
                .map_err(|e| Error::InvalidInput(format!("cannot start {} threads: {e}", self.threads)))?;
            self.pool = Some(pool);
        }
        Ok(self.pool.as_ref().expect("pool was just built"))
    }

    /// Make `mesh` the current mesh, as the result of a run made elsewhere
    /// (a distributed run: this process's share of the curved mesh), with
    /// its cells' quality, the whole run's figures and report, and the
    /// share's global node ids and owners.
    pub fn adopt(
        &mut self,
        mesh: HighOrderMesh,
        cell_quality: Vec<ElementQuality>,
        report: CurveReport,
        nodes: (Vec<u64>, Vec<i32>),
    ) {
        self.mesh = mesh;
        self.cell_quality = cell_quality;
        self.quality = report.quality.clone();
        self.report = Some(report);
        if let Some(p) = &mut self.partition {
            p.nodes = Some(nodes);
        }
    }

    pub fn dim(&self) -> usize {
        self.input.dim
    }
    pub fn options(&self) -> &CurveOptions {
        &self.opts
    }
    /// The current mesh: straight before a run, curved after a successful one.
    pub fn mesh(&self) -> &HighOrderMesh {
        &self.mesh
    }
    pub fn quality(&self) -> &MeshQuality {
        &self.quality
    }
    pub fn cell_quality(&self) -> &[ElementQuality] {
        &self.cell_quality
    }
    /// The report of the last successful run, if the mesh is curved.
    pub fn report(&self) -> Option<&CurveReport> {
        self.report.as_ref()
    }

    /// Number of cells the host gave (before boundary caps were removed).
    pub fn n_input_cells(&self) -> usize {
        self.input.n_cells()
    }

    /// Number of cells of the straight mesh that is curved: the input cells
    /// less the boundary caps removed.
    pub fn n_straight_cells(&self) -> usize {
        self.prepared.linear().n_cells()
    }

    /// For each cell of the current mesh, an index among the cells the host
    /// gave: the straight mesh lacks only the boundary caps removed; a curved
    /// one may also have cells made by the repair, which map to the input cell
    /// holding their centroid ([`crate::mesh::Repaired::input_cell`]).
    pub fn input_cells(&self) -> &[usize] {
        self.report.as_ref().map_or(self.prepared.input_cell(), |r| &r.input_cell)
    }

    /// Rebuild the straight mesh for a new input mesh or settings; on error
    /// nothing changes.
    fn reset(&mut self, input: LinearMesh, opts: CurveOptions) -> Result<()> {
        let prepared = prepare_after(&input, &opts, &self.straight_tags, Some(&self.prepared))?;
        self.reset_to(input, opts, prepared);
        Ok(())
    }

    /// [`Session::reset`] with the mesh already prepared for `input` and `opts`.
    fn reset_to(&mut self, input: LinearMesh, opts: CurveOptions, prepared: Prepared) {
        let (mesh, cq, q) = straight(&prepared);
        self.input = input;
        self.prepared = prepared;
        self.opts = opts;
        self.mesh = mesh;
        self.cell_quality = cq;
        self.quality = q;
        self.report = None;
        if let Some(p) = &mut self.partition {
            p.nodes = None;
        }
    }

    /// Tag boundary facets (`dim` vertices each). Replaces earlier tags.
    pub fn set_boundary(&mut self, facets: Vec<usize>, tags: Vec<i32>) -> Result<()> {
        let mut linear = self.input.clone();
        linear.facets = facets;
        linear.facet_tags = tags;
        let (linear, _) = validate_and_orient(&linear)?;
        self.reset(linear, self.opts.clone())
    }

    /// Tag 3D feature edges with CAD curve tags. Replaces earlier ones.
    pub fn set_feature_edges(&mut self, edges: Vec<usize>, tags: Vec<i32>) -> Result<()> {
        let mut linear = self.input.clone();
        linear.feature_edges = edges;
        linear.feature_edge_tags = tags;
        let (linear, _) = validate_and_orient(&linear)?;
        self.reset(linear, self.opts.clone())
    }

    /// Hold the facets (`entity_dim` = dim − 1) or 3D feature edges
    /// (`entity_dim` = 1) with these tags straight: they are curved by
    /// nothing, their nodes stay where elevation put them and the projector
    /// is never asked about them. Replaces the earlier list for
    /// `entity_dim`; an empty list curves them all again. A tag that no
    /// facet or edge carries is an error.
    pub fn set_straight_tags(&mut self, entity_dim: usize, tags: &[i32]) -> Result<()> {
        let dim = self.dim();
        let tagged: &[i32] = if entity_dim + 1 == dim {
            &self.input.facet_tags
        } else if dim == 3 && entity_dim == 1 {
            &self.input.feature_edge_tags
        } else {
            return Err(Error::InvalidInput(format!(
                "entity_dim must be {} (facets){}, got {entity_dim}",
                dim - 1,
                if dim == 3 { " or 1 (feature edges)" } else { "" }
            )));
        };
        if let Some(t) = tags.iter().find(|t| !tagged.contains(t)) {
            return Err(Error::InvalidInput(format!("no entity of dimension {entity_dim} has tag {t}")));
        }
        let previous = std::mem::take(&mut self.straight_tags);
        self.straight_tags = previous
            .iter()
            .copied()
            .filter(|&(d, _)| d != entity_dim)
            .chain(tags.iter().map(|&t| (entity_dim, t)))
            .collect();
        let result = self.reset(self.input.clone(), self.opts.clone());
        if result.is_err() {
            self.straight_tags = previous;
        }
        result
    }

    pub fn set_order(&mut self, order: usize, spacing: NodeSpacing) -> Result<()> {
        let opts = CurveOptions { order, spacing, ..self.opts.clone() };
        validate_options(&opts)?;
        // Same mesh, tags and caps: only the elevation changes.
        let prepared = self.prepared.at_order(&opts)?;
        self.reset_to(self.input.clone(), opts, prepared);
        Ok(())
    }

    /// Whether boundary caps are removed before curving (default true; see
    /// [`crate::mesh::caps`]). The current mesh is rebuilt straight.
    pub fn set_remove_caps(&mut self, remove: bool) -> Result<()> {
        let opts = CurveOptions { remove_caps: remove, ..self.opts.clone() };
        self.reset(self.input.clone(), opts)
    }

    /// Whether a run that removed caps and ends with an invalid cell is made
    /// again with the caps kept (default true; see
    /// [`CurveOptions::retry_keep_caps`]). Takes effect at the next run.
    pub fn set_retry_keep_caps(&mut self, retry: bool) {
        self.opts.retry_keep_caps = retry;
    }

    /// Whether the linear mesh is repaired at each run (default true; see
    /// [`CurveOptions::repair`]). Takes effect at the next run.
    pub fn set_repair(&mut self, repair: bool) {
        self.opts.repair = repair;
    }

    /// Static condensation of the cell-interior nodes (default on; see
    /// [`CurveOptions::condense`]). Keeps a curved result: it changes how the
    /// systems are solved, not the mesh.
    pub fn set_condense(&mut self, condense: bool) {
        self.opts.condense = condense;
    }

    /// The optimisation stage after the elastic solve (default on; see
    /// [`crate::optimize`]). Keeps a curved result; applies to the next run.
    pub fn set_optimize(&mut self, enabled: bool) {
        self.opts.optimize.enabled = enabled;
    }

    /// [`crate::curve::OptimizeOptions::tangent_first`]: for a slow
    /// projector, the optimisation's sliding nodes move in their tangent
    /// planes and are projected after each pass first (default off).
    pub fn set_tangent_first(&mut self, enabled: bool) {
        self.opts.optimize.tangent_first = enabled;
    }

    /// Material model and constants (E > 0, 0 ≤ ν < 0.5). Whether the model
    /// suits the formulation is checked at the next run, so the two may be
    /// set in any order.
    pub fn set_material(&mut self, model: MaterialModel, young: f64, poisson: f64) -> Result<()> {
        crate::material::make_material(model, young, poisson)?;
        self.opts = CurveOptions { material: model, young, poisson, ..self.opts.clone() };
        Ok(())
    }

    /// The formulation; IIL, CIL and NONLINEAR need a hyperelastic material
    /// (checked at the next run, so the two may be set in any order).
    pub fn set_formulation(&mut self, formulation: Formulation) {
        self.opts.formulation = formulation;
    }

    /// Newton–Raphson tolerance on ‖R‖/‖R₀‖ and iteration limit per increment.
    pub fn set_newton(&mut self, tolerance: f64, max_iterations: usize) -> Result<()> {
        if !(tolerance.is_finite() && tolerance > 0.0) || max_iterations == 0 {
            return Err(Error::InvalidInput(format!(
                "Newton tolerance must be positive and iterations at least 1 (got {tolerance}, {max_iterations})"
            )));
        }
        self.opts.tolerance = tolerance;
        self.opts.max_iterations = max_iterations;
        Ok(())
    }

    /// Adaptive load stepping ([`crate::curve::solve_increments`]): `enabled`
    /// None restores the default (on for the incremental formulations, off
    /// for LINEAR); `max_splits` halvings per increment, at most
    /// [`crate::curve::MAX_SPLITS`].
    pub fn set_adaptive(&mut self, enabled: Option<bool>, max_splits: usize) -> Result<()> {
        if max_splits > crate::curve::MAX_SPLITS {
            return Err(Error::InvalidInput(format!(
                "max_splits must be between 0 and {}, got {max_splits}",
                crate::curve::MAX_SPLITS
            )));
        }
        self.opts.adaptive = enabled;
        self.opts.max_splits = max_splits;
        Ok(())
    }

    /// Fibre direction per cell for the transversely isotropic models (None:
    /// the paper's default). Checked at the next run.
    pub fn set_fibres(&mut self, fibres: Option<Vec<[f64; 3]>>) -> Result<()> {
        if let Some(f) = &fibres {
            if f.len() != self.input.n_cells() {
                return Err(Error::InvalidInput(format!(
                    "{} fibre directions for {} cells",
                    f.len(),
                    self.input.n_cells()
                )));
            }
            // Checked here, not only at the run, so the call that set them fails.
            if let Some(c) = f.iter().position(|v| {
                let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                !(n.is_finite() && n > 0.0)
            }) {
                return Err(Error::InvalidInput(format!("fibre direction of cell {c} is zero or not finite")));
            }
        }
        self.opts.fibres = fibres;
        Ok(())
    }

    pub fn set_projector(&mut self, projector: Option<Box<dyn Projector + Send>>) {
        self.projector = projector;
    }

    pub fn set_progress(&mut self, progress: Option<ProgressFn>) {
        self.progress = progress;
    }

    /// The host's linear solver for every system of the next runs; None
    /// restores the built-in one (`options().solver`).
    pub fn set_linear_solver(&mut self, solver: Option<ExternalSolver>) {
        self.external_solver = solver;
    }

    /// Worker threads of this session's own pool (0 = one per core, at most
    /// [`MAX_THREADS`]). The host's global rayon pool is never used.
    pub fn set_threads(&mut self, threads: usize) -> Result<()> {
        if threads > MAX_THREADS {
            return Err(Error::InvalidInput(format!("threads must be at most {MAX_THREADS}, got {threads}")));
        }
        if threads != self.threads {
            self.threads = threads;
            self.pool = None;
        }
        Ok(())
    }

    /// Curve the mesh in `increments` load increments. On error the session
    /// is exactly as before the call.
    pub fn run(&mut self, increments: usize) -> Result<()> {
        let mut opts = CurveOptions { increments, ..self.opts.clone() };
        if let Some(e) = &self.external_solver {
            opts.solver = SolverChoice::External(e.clone());
        }
        validate_options(&opts)?;
        let linear = self.prepared.linear();
        let has_tags = !linear.facets.is_empty() || !linear.feature_edges.is_empty();
        if has_tags && self.projector.is_none() {
            return Err(Error::InvalidInput("boundary facets are tagged but no projector is set".into()));
        }
        self.pool()?;
        let none = NoProjector;
        let projector: &dyn Projector = match &self.projector {
            Some(p) => p.as_ref(),
            None => &none,
        };
        let mut always = |_: &Progress| true;
        let progress: &mut (dyn FnMut(&Progress) -> bool + Send) = match &mut self.progress {
            Some(p) => p.as_mut(),
            None => &mut always,
        };
        let (prepared, pool) = (&self.prepared, self.pool.as_ref().expect("pool was just built"));
        let (input, straight_tags) = (&self.input, &self.straight_tags[..]);
        let reprepare = |o: &CurveOptions| prepare(input, o, straight_tags);
        let curved = pool.install(|| {
            run_retrying(prepared, &reprepare, projector, &opts, &mut |p: &Progress| progress(p), Instant::now())
        })?;
        self.mesh = curved.mesh;
        self.quality = curved.report.quality.clone();
        self.cell_quality = curved.cell_quality;
        // The prepared mesh was oriented when the session was made.
        let report = CurveReport { reoriented_cells: self.reoriented, ..curved.report };
        self.report = Some(report);
        Ok(())
    }

    /// Curve with the settings `opts` (all of them, the order included) in
    /// `increments` load increments. On success the session keeps `opts`
    /// and the curved mesh; on error it is exactly as before, settings
    /// included, which the setters one by one cannot promise (a new order
    /// makes the current mesh the straight one at that order).
    pub fn run_with(&mut self, opts: CurveOptions, increments: usize) -> Result<()> {
        validate_options(&CurveOptions { increments, ..opts.clone() })?;
        let same_mesh = opts.order == self.opts.order
            && opts.spacing == self.opts.spacing
            && opts.remove_caps == self.opts.remove_caps;
        let fresh = if same_mesh {
            None
        } else if opts.remove_caps == self.opts.remove_caps {
            Some(self.prepared.at_order(&opts)?)
        } else {
            Some(prepare(&self.input, &opts, &self.straight_tags)?)
        };
        let saved_opts = std::mem::replace(&mut self.opts, opts);
        let saved_prepared = fresh.map(|p| std::mem::replace(&mut self.prepared, p));
        let result = self.run(increments);
        if result.is_err() {
            self.opts = saved_opts;
            if let Some(p) = saved_prepared {
                self.prepared = p;
            }
        }
        result
    }

    /// Node coordinates of the current mesh for connectivity in `ordering`:
    /// at this mesh's own node set for [`NodeOrdering::Native`], at the
    /// equispaced one for gmsh's and VTK's (their cells interpolate there).
    /// Same nodes, same numbering; the same curved geometry either way.
    pub fn nodes(&self, ordering: NodeOrdering) -> Cow<'_, [f64]> {
        match ordering {
            NodeOrdering::Native => Cow::Borrowed(&self.mesh.coords),
            NodeOrdering::Gmsh | NodeOrdering::Vtk => self.mesh.equispaced_coords(),
        }
    }

    /// Cell connectivity of the current mesh in the given node ordering.
    pub fn cells(&self, ordering: NodeOrdering) -> Vec<usize> {
        let m = &self.mesh;
        let nodes = NodeSet::new(m.simplex, m.order, m.spacing);
        let target = match ordering {
            NodeOrdering::Native => return m.cells.clone(),
            NodeOrdering::Gmsh => ordering::gmsh_multi_indices(m.simplex, m.order),
            NodeOrdering::Vtk => ordering::vtk_multi_indices(m.simplex, m.order),
        };
        let perm = ordering::permutation(&nodes.multi, &target).expect("orderings are permutations of the node set");
        m.cells.chunks_exact(nodes.len()).flat_map(|c| perm.iter().map(move |&k| c[k])).collect()
    }
}

/// The mesh to curve, prepared: `input` (validated and oriented) with the
/// straight tags dropped ([`Prepared::from_oriented`]).
fn prepare(input: &LinearMesh, opts: &CurveOptions, straight_tags: &[(usize, i32)]) -> Result<Prepared> {
    prepare_after(input, opts, straight_tags, None)
}

/// [`prepare`], reusing what of `previous` does not change ([`Prepared::from_oriented_after`]).
fn prepare_after(
    input: &LinearMesh,
    opts: &CurveOptions,
    straight_tags: &[(usize, i32)],
    previous: Option<&Prepared>,
) -> Result<Prepared> {
    let mut curved = input.clone();
    curved.retain_tags(|d, t| !straight_tags.contains(&(d, t)));
    // `input` was validated and oriented when it was given; dropping tags keeps it so.
    Prepared::from_oriented_after(curved, 0, opts, previous)
}

/// The straight-sided mesh of `prepared`, whose quality is exactly 1 (affine elements).
fn straight(prepared: &Prepared) -> (HighOrderMesh, Vec<ElementQuality>, MeshQuality) {
    let mesh = prepared.straight_mesh().clone();
    let cq = vec![ElementQuality::PERFECT; mesh.n_cells()];
    let q = quality::summarize(&cq);
    (mesh, cq, q)
}

/// Used when nothing is tagged: any projection request is an error.
struct NoProjector;

impl Projector for NoProjector {
    fn project(&self, d: usize, t: i32, _: &[[f64; 3]], _: &mut [[f64; 3]]) -> std::result::Result<(), String> {
        Err(format!("no projector is set (entity dim {d}, tag {t})"))
    }
}
