//! The C ABI: a thin layer over [`Session`].
//!
//! Every function checks its pointers, lengths and enum values, converts,
//! makes one call into the Rust API and maps the error to a status code. No
//! panic crosses the boundary: each body runs under `catch_unwind` and a panic
//! becomes `HOC_ERROR_PANIC`. The handle keeps the last error message. The
//! library never prints.
//!
//! Enumerations are plain `int` typedefs with `#define`d values so that an
//! unknown value from C is reported (`HOC_ERROR_INVALID_ARGUMENT`) instead of
//! being undefined behaviour.

#![allow(clippy::missing_safety_doc)]

use std::borrow::Cow;
use std::cell::{Cell, RefCell, UnsafeCell};
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::curve::{Formulation, Progress, Stage, StepBackReason};
use crate::geometry::Projector;
use crate::material::MaterialModel;
use crate::mesh::LinearMesh;
use crate::reference::NodeSpacing;
use crate::session::{NodeOrdering, Session};
use crate::solver::{CsrView, ExternalSolver, FallbackReason, SolvedBy, SystemSolver};
use crate::Error;

/// The library's version (hoc_version gives it as a string); the header
/// and the library linked must agree on it.
pub const HOCURVE_VERSION_MAJOR: c_int = 0;
pub const HOCURVE_VERSION_MINOR: c_int = 4;
pub const HOCURVE_VERSION_PATCH: c_int = 0;

/// The defaults that every interface (C, C++, Fortran, the command line and
/// Rust's `CurveOptions::default()`) shares: load increments of a run ...
pub const HOC_DEFAULT_INCREMENTS: c_int = 10;
/// ... halvings of an increment by adaptive load stepping ...
pub const HOC_DEFAULT_MAX_SPLITS: c_int = 6;
/// ... and Young's modulus and Poisson's ratio of the material.
pub const HOC_DEFAULT_YOUNG: f64 = 1e5;
pub const HOC_DEFAULT_POISSON: f64 = 0.45;

/// Stage of a run reported to the progress callback (HocProgressFn):
/// elevating the mesh to the order ...
pub const HOC_STAGE_ELEVATE: c_int = 0;
/// ... projecting the boundary nodes ...
pub const HOC_STAGE_PROJECT: c_int = 1;
/// ... one load increment (`step` of `total`) ...
pub const HOC_STAGE_INCREMENT: c_int = 2;
/// ... measuring the quality ...
pub const HOC_STAGE_QUALITY: c_int = 3;
/// ... and the optimisation stage.
pub const HOC_STAGE_OPTIMIZE: c_int = 4;

/// Status code returned by every function (0 = success).
pub type HocStatus = c_int;
/// Success.
pub const HOC_OK: HocStatus = 0;
/// A required pointer argument was NULL.
pub const HOC_ERROR_NULL_POINTER: HocStatus = 1;
/// An argument is out of range (order, material constants, enum value, ...).
pub const HOC_ERROR_INVALID_ARGUMENT: HocStatus = 2;
/// The mesh or its boundary description is malformed.
pub const HOC_ERROR_INVALID_MESH: HocStatus = 3;
/// The projector failed, returned a non-finite point or one too far away.
pub const HOC_ERROR_PROJECTION: HocStatus = 4;
/// A linear solve failed.
pub const HOC_ERROR_SOLVER: HocStatus = 5;
/// An element became inverted during the run.
pub const HOC_ERROR_INVALID_ELEMENT: HocStatus = 6;
/// A file could not be written.
pub const HOC_ERROR_IO: HocStatus = 7;
/// The progress callback asked to stop.
pub const HOC_ERROR_CANCELLED: HocStatus = 8;
/// An output buffer has the wrong length.
pub const HOC_ERROR_BUFFER_SIZE: HocStatus = 9;
/// An internal error (a bug in hocurve); the handle is still usable.
pub const HOC_ERROR_PANIC: HocStatus = 10;
/// Another call on the same handle is running: from another thread, or the
/// call was made from inside one of the handle's callbacks. Nothing changed.
pub const HOC_ERROR_BUSY: HocStatus = 11;

/// Placement of the high-order nodes in the reference element.
pub type HocNodeSpacing = c_int;
/// Warburton's warp & blend nodes (Gauss–Lobatto on edges). The default.
pub const HOC_SPACING_OPTIMAL: HocNodeSpacing = 0;
/// Equispaced nodes (the convention of gmsh and VTK files).
pub const HOC_SPACING_EQUISPACED: HocNodeSpacing = 1;

/// Constitutive model of the mesh-as-a-solid.
pub type HocMaterial = c_int;
/// Isotropic linear elasticity.
pub const HOC_MATERIAL_LINEAR_ELASTIC: HocMaterial = 0;
/// Compressible neo-Hookean.
pub const HOC_MATERIAL_NEO_HOOKEAN: HocMaterial = 1;
/// Compressible Mooney–Rivlin.
pub const HOC_MATERIAL_MOONEY_RIVLIN: HocMaterial = 2;
/// Nearly incompressible Mooney–Rivlin.
pub const HOC_MATERIAL_NI_MOONEY_RIVLIN: HocMaterial = 3;
/// Transversely isotropic hyperelastic (fibres: see hoc_mesh_set_fibres).
pub const HOC_MATERIAL_TRANSVERSELY_ISOTROPIC: HocMaterial = 4;
/// Transversely isotropic linear elastic (for ILE).
pub const HOC_MATERIAL_TRANSVERSELY_ISOTROPIC_LINEAR: HocMaterial = 5;

/// Solid-mechanics formulation (paper Table 1).
pub type HocFormulation = c_int;
/// Classical linear elasticity, one solve.
pub const HOC_FORMULATION_LINEAR: HocFormulation = 0;
/// Incremental linear elasticity on the updated geometry. The default.
pub const HOC_FORMULATION_ILE: HocFormulation = 1;
/// Inconsistent incrementally linearised (needs a hyperelastic material).
pub const HOC_FORMULATION_IIL: HocFormulation = 2;
/// Consistent incrementally linearised (needs a hyperelastic material).
pub const HOC_FORMULATION_CIL: HocFormulation = 3;
/// Newton–Raphson on the hyperelastic problem (needs a hyperelastic material).
pub const HOC_FORMULATION_NONLINEAR: HocFormulation = 4;

/// Local node order of the returned connectivity.
pub type HocNodeOrdering = c_int;
/// hocurve's own: vertices, edge nodes, face nodes, interior nodes; node
/// positions at the mesh's own node set (warp & blend unless set otherwise).
pub const HOC_ORDERING_NATIVE: HocNodeOrdering = 0;
/// gmsh's element node order; node positions at the equispaced node set.
pub const HOC_ORDERING_GMSH: HocNodeOrdering = 1;
/// VTK Lagrange cell node order; node positions at the equispaced node set.
pub const HOC_ORDERING_VTK: HocNodeOrdering = 2;

/// Why adaptive load stepping rejected an increment (hoc_mesh_get_step_backs).
pub type HocStepBackReason = c_int;
/// Assembly on the new geometry met det J ≤ 0 at a quadrature point.
pub const HOC_STEP_BACK_SAMPLED_INVALID: HocStepBackReason = 0;
/// The certified check found a cell with det J ≤ 0 somewhere after the increment.
pub const HOC_STEP_BACK_CERTIFIED_INVALID: HocStepBackReason = 1;
/// Newton–Raphson did not converge (HOC_FORMULATION_NONLINEAR).
pub const HOC_STEP_BACK_NEWTON_FAILED: HocStepBackReason = 2;
/// An inversion between the sample points of an earlier increment was found:
/// the run restarted from load 0 with the certified check after every increment.
pub const HOC_STEP_BACK_RESTARTED: HocStepBackReason = 3;

/// Which solver produced the solution of a linear solve (hoc_mesh_get_solves).
pub type HocSolvedBy = c_int;
/// Preconditioned conjugate gradients (the built-in iterative solver).
pub const HOC_SOLVED_BY_PCG: HocSolvedBy = 0;
/// PCG restarted after a breakdown, with the preconditioner rebuilt in its
/// safe mode (double precision, Gershgorin bound of the eigenvalues).
pub const HOC_SOLVED_BY_PCG_RESTARTED: HocSolvedBy = 1;
/// Sparse Cholesky.
pub const HOC_SOLVED_BY_DIRECT: HocSolvedBy = 2;
/// Sparse LU (the matrix was not positive definite).
pub const HOC_SOLVED_BY_DIRECT_LU: HocSolvedBy = 3;
/// The host's solver (hoc_mesh_set_linear_solver).
pub const HOC_SOLVED_BY_EXTERNAL: HocSolvedBy = 4;

/// Why a linear solve fell back from its first choice of solver
/// (hoc_mesh_get_solves).
pub type HocFallbackReason = c_int;
/// No fallback.
pub const HOC_FALLBACK_NONE: HocFallbackReason = 0;
/// PCG found rᵀz ≤ 0: the preconditioner was not positive definite.
pub const HOC_FALLBACK_PRECONDITIONER_NOT_POSITIVE: HocFallbackReason = 1;
/// PCG's residual stagnated.
pub const HOC_FALLBACK_STAGNATION: HocFallbackReason = 2;
/// PCG was slow and a fresh eigenvalue estimate exceeded the smoother's.
pub const HOC_FALLBACK_EIGENVALUE_UNDERESTIMATED: HocFallbackReason = 3;
/// PCG reached its iteration limit.
pub const HOC_FALLBACK_NOT_CONVERGED: HocFallbackReason = 4;
/// PCG's residual became infinite or NaN.
pub const HOC_FALLBACK_NON_FINITE: HocFallbackReason = 5;
/// The matrix is not positive definite (PCG found pᵀAp ≤ 0 or a diagonal
/// block that is not).
pub const HOC_FALLBACK_MATRIX_NOT_POSITIVE: HocFallbackReason = 6;
/// The preconditioner could not be built.
pub const HOC_FALLBACK_PRECONDITIONER_SETUP: HocFallbackReason = 7;
/// Sparse Cholesky failed (not positive definite): sparse LU solved it.
pub const HOC_FALLBACK_CHOLESKY_FAILED: HocFallbackReason = 8;

/// Mesh quality (paper section 5): minima over the cells, mean Q3, and the
/// number of cells with a non-positive Jacobian at a sample point.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct HocQuality {
    pub min_q1: f64,
    pub min_q2: f64,
    pub min_q3: f64,
    /// NaN unless the material is transversely isotropic.
    pub min_q4: f64,
    /// NaN unless the material is transversely isotropic.
    pub min_q5: f64,
    pub mean_q3: f64,
    pub n_invalid: usize,
    pub n_cells: usize,
    /// A lower bound of Q3 over the whole of every element (Bernstein bounds
    /// of det J, not only samples): ≤ min_q3, at every order. NaN when not
    /// computed (before a run).
    pub certified_min_q3: f64,
    /// Cells with det J ≤ 0 at some point, found by the certified check.
    pub n_certified_invalid: usize,
    /// Cells whose sign the certified check could not decide (counted as not valid).
    pub n_uncertain: usize,
    /// Largest distance between a boundary node of the straight mesh and its
    /// projection onto the geometry in the last run: how far the straight
    /// boundary was from the CAD. 0 before a run.
    pub max_projection_distance: f64,
}

/// What the optimisation stage of the last run did (hoc_mesh_optimization).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct HocOptimization {
    /// 1 if it ran: some cell was invalid or had Q3 below 0.2, or the
    /// polish of the cells nearest the smallest Q3 ran (every valid mesh,
    /// unless the stage is off); else 0.
    pub ran: c_int,
    /// 1 if the elastic stage stopped short of the full load, because
    /// adaptive stepping could not keep a cell valid: the rest of the load
    /// was applied in one solve and the optimisation made the mesh valid.
    pub elastic_stopped: c_int,
    /// The load fraction the elastic stage reached (1 if it did not stop).
    pub elastic_load: f64,
    /// 1 if, the elastic stage having stopped, the optimisation from there
    /// left cells invalid and the mesh returned is the optimisation of the
    /// whole load in one linear solve on the straight mesh, which left fewer.
    pub elastic_restarted: c_int,
    /// Cells selected: invalid, or with Q3 below the threshold.
    pub target_cells: usize,
    /// Cells of the patches whose new node positions were kept.
    pub cells_touched: usize,
    pub nodes_moved: usize,
    pub patches: usize,
    /// Cells still invalid after the first rounds that were split at their
    /// centroid (each into dim + 1 cells; hoc_mesh_get_input_cells maps
    /// the pieces to the input cell).
    pub cells_split: usize,
    /// Certified-invalid (or undecided) cells before and after the stage.
    pub invalid_before: usize,
    pub invalid_after: usize,
    /// Minimum Q3 before and after the stage.
    pub min_q3_before: f64,
    pub min_q3_after: f64,
    /// Wall-clock seconds of the stage.
    pub seconds: f64,
}

/// Where the last run's time went (hoc_mesh_timings): wall-clock seconds
/// per stage, the fields of the command line's report `seconds`. The
/// stages do not cover everything (the elastic stage's set-up, the handing
/// back of the mesh), so they sum to a little less than `total`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct HocTimings {
    /// The whole run (both runs when the caps were kept in a second one;
    /// the stages are then the second run's).
    pub total: f64,
    /// The repair of the linear mesh and its elevation to order p.
    pub repair_and_elevate: f64,
    /// The placement of the boundary nodes on the geometry.
    pub place_boundary: f64,
    /// Elastic stage: assembly of the stiffness (every increment).
    pub assembly: f64,
    /// Elastic stage: the solver's symbolic analysis and set-up.
    pub solver_setup: f64,
    /// Elastic stage: the linear solves.
    pub solve: f64,
    /// Elastic stage: the validity checks after each increment (certified
    /// after the last).
    pub check: f64,
    /// The quality of every cell, and the optimisation stage
    /// (hoc_mesh_optimization).
    pub optimize: f64,
    /// The set-up of the quality measures.
    pub quality: f64,
}

/// What the repair of the linear mesh did (hoc_mesh_repair_summary): boundary
/// caps removed (hoc_mesh_set_remove_caps) and cells flipped away by the last
/// run (hoc_mesh_set_repair).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct HocRepair {
    /// Boundary caps removed.
    pub removed_caps: usize,
    /// Bad cells found by the last run: all vertices on one surface that
    /// bulges into the domain, or a boundary facet bulging past half the
    /// height of the opposite vertex, itself on the boundary.
    pub bad_cells: usize,
    /// Of them, with all vertices on one surface.
    pub surface_cells: usize,
    /// Of them, with a boundary facet bulging too far.
    pub bulge_cells: usize,
    /// 2-3 flips (3D).
    pub flips_23: usize,
    /// 3-2 flips (3D).
    pub flips_32: usize,
    /// Removals of an edge with four or more tets around it (3D).
    pub edge_removals: usize,
    /// Edge flips (2D).
    pub flips_22: usize,
    /// Bad surface cells no flip improved that were caps with faces more
    /// than 45° apart (kept by the caps step): removed like caps.
    pub surface_caps: usize,
    /// Cells of the straight mesh (after the caps step) replaced by the repair.
    pub cells_removed: usize,
    /// Cells the repair made.
    pub cells_added: usize,
    /// Bad cells that no flip improved.
    pub bad_cells_left: usize,
    /// Interior edges split at their midpoint (each cell around them into
    /// two): edges opposite a vertex where a triangle of the mesh has two
    /// boundary edges and the boundary is smooth, which would squeeze the
    /// cells between that triangle and the boundary flat.
    pub edge_splits: usize,
    /// Boundary edges flipped to the other diagonal of their two facets
    /// (on one smooth surface), because curving would fold one of those
    /// facets on the surface.
    pub surface_flips: usize,
}

/// Projects `n_points` points (`dim` interleaved coordinates each, `dim` the
/// mesh dimension) onto the geometric entity (`entity_dim`, `entity_tag`),
/// writing the closest points into `projected`. Returns 0 on success. It is
/// called from one thread at a time, possibly a worker thread of hocurve.
pub type HocProjectFn = Option<
    unsafe extern "C" fn(
        user_data: *mut c_void,
        entity_dim: c_int,
        entity_tag: c_int,
        n_points: usize,
        points: *const f64,
        projected: *mut f64,
    ) -> c_int,
>;

/// Progress of a run: `stage` one of HOC_STAGE_*; `step` of `total`. Return
/// 0 to continue, nonzero to cancel the run. It must not call hocurve on the
/// same handle (such a call is refused with HOC_ERROR_BUSY).
pub type HocProgressFn =
    Option<unsafe extern "C" fn(user_data: *mut c_void, stage: c_int, step: c_int, total: c_int) -> c_int>;

/// Solves one reduced linear system A x = b of a run with the host's solver
/// (PETSc, MUMPS, hypre, ...).
///
/// A is the stiffness matrix restricted to the free degrees of freedom (the
/// unknowns of the interior and of untagged boundary nodes; the projected
/// nodes are eliminated; with static condensation, the default, the nodes
/// inside each cell are eliminated too and A is the Schur complement on the
/// others, see hoc_mesh_set_static_condensation): `n` × `n`, symmetric, given in full CSR form with
/// both triangles, 0-based, columns sorted within each row. Row `i` holds the
/// columns `col_idx[row_ptr[i] .. row_ptr[i+1]-1]` with the values at the
/// same positions of `values`; `row_ptr` has `n + 1` entries and `row_ptr[n]`
/// is the number of entries. The pattern is the same for every call of a run
/// (only the values change), so a solver may reuse its symbolic set-up while
/// `n` and `row_ptr[n]` stay the same. A is positive definite for the
/// LINEAR and ILE formulations; with CIL or NONLINEAR it may be indefinite.
///
/// On entry `x` (`n` doubles) holds an initial guess: extrapolated from the
/// previous increments' solutions (zeros for the first one, and for each
/// Newton correction); on
/// return it must hold the solution. Return 0 on success. A nonzero return, or
/// a non-finite value left in `x`, stops the run with HOC_ERROR_SOLVER and a
/// message naming the external linear solver and the status; the mesh is then
/// unchanged.
///
/// All pointers are valid only during the call; `row_ptr`, `col_idx`,
/// `values` and `rhs` must not be modified. It is called once per linear
/// system (once per load increment; for HOC_FORMULATION_NONLINEAR, once more
/// per Newton iteration), one call at a time, from the thread that runs the
/// curving: a worker thread of the handle's pool, while hoc_mesh_run_increments
/// blocks the calling thread. Two handles running at once may call it at once.
/// It must not call back into hocurve on the same handle, and must not unwind
/// (throw, longjmp) through the library.
pub type HocLinearSolverFn = Option<
    unsafe extern "C" fn(
        user_data: *mut c_void,
        n: i64,
        row_ptr: *const i64,
        col_idx: *const i64,
        values: *const f64,
        rhs: *const f64,
        x: *mut f64,
    ) -> c_int,
>;

/// Opaque handle: one mesh being curved.
///
/// One call at a time: a call made while another runs on the same handle
/// (from another thread, or from inside one of the handle's callbacks) is
/// refused with `HOC_ERROR_BUSY` and changes nothing.
pub struct HocMesh {
    /// Set while a call runs on the handle: the only way to reach `state`.
    busy: AtomicBool,
    state: UnsafeCell<HandleState>,
}

struct HandleState {
    session: Session,
    last_error: CString,
}

// SAFETY: `state` is only reached by the call that set `busy` (see `Claim`).
unsafe impl Sync for HocMesh {}

/// Exclusive use of a handle for one call; dropping it releases the handle.
struct Claim<'a>(&'a HocMesh);

impl HocMesh {
    fn claim(&self) -> Option<Claim<'_>> {
        self.busy.compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed).ok().map(|_| Claim(self))
    }
}

impl Claim<'_> {
    fn state(&mut self) -> &mut HandleState {
        // SAFETY: `busy` was set by this claim, so no other reference to `state` exists.
        unsafe { &mut *self.0.state.get() }
    }
}

impl Drop for Claim<'_> {
    fn drop(&mut self) {
        self.0.busy.store(false, Ordering::Release);
    }
}

type FfiResult = std::result::Result<(), (HocStatus, String)>;

fn status_of(e: &Error, mesh_context: bool) -> HocStatus {
    match e {
        Error::InvalidInput(_) if mesh_context => HOC_ERROR_INVALID_MESH,
        Error::InvalidInput(_) => HOC_ERROR_INVALID_ARGUMENT,
        Error::Projection(_) => HOC_ERROR_PROJECTION,
        Error::Solver { .. } => HOC_ERROR_SOLVER,
        Error::InvalidElement { .. } => HOC_ERROR_INVALID_ELEMENT,
        Error::Io(_) => HOC_ERROR_IO,
        Error::Cancelled => HOC_ERROR_CANCELLED,
    }
}

fn err(e: Error) -> (HocStatus, String) {
    (status_of(&e, false), e.to_string())
}

fn mesh_err(e: Error) -> (HocStatus, String) {
    (status_of(&e, true), e.to_string())
}

fn arg(msg: impl Into<String>) -> (HocStatus, String) {
    (HOC_ERROR_INVALID_ARGUMENT, msg.into())
}

/// A C boolean argument: 0 or 1, else an invalid-argument error naming it.
fn flag(name: &str, value: c_int) -> Result<bool, (HocStatus, String)> {
    match value {
        0 => Ok(false),
        1 => Ok(true),
        v => Err(arg(format!("{name} must be 0 or 1, got {v}"))),
    }
}

fn null(what: &str) -> (HocStatus, String) {
    (HOC_ERROR_NULL_POINTER, format!("{what} is NULL"))
}

thread_local! {
    /// The message of the last failed call on this thread that had no handle,
    /// or that was refused because its handle was busy.
    static THREAD_LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
    /// The handle of this thread's last refused (`HOC_ERROR_BUSY`) call, until
    /// the thread's next call on that handle runs: hoc_mesh_last_error then
    /// gives the refusal, not the message of the call that held the handle.
    static REFUSED: Cell<*const HocMesh> = const { Cell::new(std::ptr::null()) };
}

fn set_thread_error(msg: CString) {
    THREAD_LAST_ERROR.with(|e| *e.borrow_mut() = msg);
}

fn busy_message() -> CString {
    CString::new(
        "the handle is busy: another call on it is running (from another thread, or this call was made \
         from inside one of its callbacks)",
    )
    .expect("no NUL")
}

/// Run `f` with panics caught, holding the handle (if any) for the call;
/// record the message on the handle, or on the thread without one. A handle
/// already held gives `HOC_ERROR_BUSY` without running `f`.
fn guard(handle: *const HocMesh, f: impl FnOnce() -> FfiResult) -> HocStatus {
    // SAFETY: a non-null handle comes from hoc_mesh_create.
    let mut claim = match unsafe { handle.as_ref() } {
        None => None,
        Some(h) => match h.claim() {
            Some(c) => {
                REFUSED.with(|r| {
                    if r.get() == handle {
                        r.set(std::ptr::null());
                    }
                });
                Some(c)
            }
            None => {
                set_thread_error(busy_message());
                REFUSED.with(|r| r.set(handle));
                return HOC_ERROR_BUSY;
            }
        },
    };
    let result = catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|p| {
        let msg = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        Err((HOC_ERROR_PANIC, format!("internal error (please report): {msg}")))
    });
    let (status, msg) = match result {
        Ok(()) => (HOC_OK, String::new()),
        Err(e) => e,
    };
    let msg = CString::new(msg.replace('\0', " ")).unwrap_or_default();
    match claim.as_mut() {
        Some(c) => c.state().last_error = msg,
        // No handle (hoc_mesh_create, or a NULL handle): keep it per thread.
        None => set_thread_error(msg),
    }
    status
}

/// Borrow a slice from C, checking the pointer (NULL is fine when len = 0).
unsafe fn slice<'a, T>(ptr: *const T, len: usize, what: &str) -> std::result::Result<&'a [T], (HocStatus, String)> {
    if len == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(null(what));
    }
    if len > isize::MAX as usize / std::mem::size_of::<T>().max(1) {
        return Err(arg(format!("{what}: length {len} is too large")));
    }
    Ok(std::slice::from_raw_parts(ptr, len))
}

fn indices(v: &[i64], what: &str) -> std::result::Result<Vec<usize>, (HocStatus, String)> {
    v.iter()
        .enumerate()
        .map(|(k, &i)| {
            usize::try_from(i).map_err(|_| (HOC_ERROR_INVALID_MESH, format!("{what}[{k}] = {i} is negative")))
        })
        .collect()
}

/// The largest count of vertices, cells, facets or edges a call takes
/// (2^32 − 1). A count is checked against it before the array it describes
/// is read or copied, so an absurd count (2^40 nodes) fails with
/// `HOC_ERROR_INVALID_ARGUMENT` instead of reading past the caller's buffer or
/// aborting in the allocator.
const MAX_COUNT: usize = u32::MAX as usize;

fn checked_count(n: usize, what: &str) -> std::result::Result<usize, (HocStatus, String)> {
    if n > MAX_COUNT {
        return Err(arg(format!("{what} = {n} is too large (hocurve takes at most {MAX_COUNT})")));
    }
    Ok(n)
}

fn checked_mul(a: usize, b: usize, what: &str) -> std::result::Result<usize, (HocStatus, String)> {
    a.checked_mul(b).ok_or_else(|| arg(format!("{what}: size overflows")))
}

/// The state of the handle that the enclosing [`guard`] holds. Only for use
/// inside a `guard` closure, once per call.
unsafe fn handle_mut<'a>(mesh: *mut HocMesh) -> std::result::Result<&'a mut HandleState, (HocStatus, String)> {
    // SAFETY: `guard` claimed the handle for this call.
    mesh.as_ref().map(|h| &mut *h.state.get()).ok_or_else(|| null("mesh"))
}

/// Shared access to the handle that the enclosing [`guard`] holds.
unsafe fn handle<'a>(mesh: *const HocMesh) -> std::result::Result<&'a HandleState, (HocStatus, String)> {
    // SAFETY: `guard` claimed the handle for this call.
    mesh.as_ref().map(|h| &*h.state.get()).ok_or_else(|| null("mesh"))
}

/// Create a mesh handle from a linear triangle (`dim` = 2) or tetrahedral
/// (`dim` = 3) mesh. Cells with negative orientation are reoriented.
///
/// @param[in] dim 2 or 3
/// @param[in] n_vertices number of vertices (at most 2^32 − 1)
/// @param[in] coords `n_vertices * dim` interleaved coordinates
/// @param[in] n_cells number of cells (at least 1, at most 2^32 − 1)
/// @param[in] cells `n_cells * (dim + 1)` 0-based vertex indices
/// @param[out] out the new handle (set to NULL on failure)
/// @return HOC_OK, HOC_ERROR_NULL_POINTER, HOC_ERROR_INVALID_ARGUMENT or HOC_ERROR_INVALID_MESH
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_create(
    dim: c_int,
    n_vertices: usize,
    coords: *const f64,
    n_cells: usize,
    cells: *const i64,
    out: *mut *mut HocMesh,
) -> HocStatus {
    create_handle(out, |out_is_null| {
        if out_is_null {
            return Err(null("out"));
        }
        let linear = linear_mesh(dim, n_vertices, coords, n_cells, cells)?;
        Session::try_new(linear).map_err(mesh_err)
    })
}

/// Set `*out` to a handle on the session `make` makes, or to NULL with the
/// error kept per thread. `make` is told whether `out` is NULL, and runs
/// either way (a collective call must reach every process's agreement).
unsafe fn create_handle(
    out: *mut *mut HocMesh,
    make: impl FnOnce(bool) -> std::result::Result<Session, (HocStatus, String)>,
) -> HocStatus {
    if !out.is_null() {
        *out = std::ptr::null_mut();
    }
    let mut created = None;
    let status = guard(std::ptr::null(), || {
        created = Some(make(out.is_null())?);
        Ok(())
    });
    if let (Some(session), false) = (created, out.is_null()) {
        *out = new_handle(session);
    }
    status
}

/// The linear mesh of hoc_mesh_create's arguments, checked.
unsafe fn linear_mesh(
    dim: c_int,
    n_vertices: usize,
    coords: *const f64,
    n_cells: usize,
    cells: *const i64,
) -> std::result::Result<LinearMesh, (HocStatus, String)> {
    if dim != 2 && dim != 3 {
        return Err(arg(format!("dim must be 2 or 3, got {dim}")));
    }
    let d = dim as usize;
    if n_cells == 0 {
        return Err((HOC_ERROR_INVALID_MESH, "the mesh has no cells".into()));
    }
    let n_vertices = checked_count(n_vertices, "n_vertices")?;
    let n_cells = checked_count(n_cells, "n_cells")?;
    let coords = slice(coords, checked_mul(n_vertices, d, "coords")?, "coords")?.to_vec();
    let cells = indices(slice(cells, checked_mul(n_cells, d + 1, "cells")?, "cells")?, "cells")?;
    Ok(LinearMesh { dim: d, coords, cells, ..Default::default() })
}

fn new_handle(session: Session) -> *mut HocMesh {
    let state = HandleState { session, last_error: CString::default() };
    Box::into_raw(Box::new(HocMesh { busy: AtomicBool::new(false), state: UnsafeCell::new(state) }))
}

/// Create a handle for this process's share of a mesh spread over the
/// processes of an MPI communicator. Collective: every process of `comm`
/// calls it with its own cells; all succeed, or all fail with the first
/// failing process's status and message (a NULL `out` included). Needs a library built with MPI
/// (the `mpi` feature; otherwise HOC_ERROR_INVALID_ARGUMENT) and MPI
/// initialised with MPI_Init_thread at MPI_THREAD_SERIALIZED or above.
///
/// A process gives the cells it holds, and every vertex they use (its own
/// and its ghosts), each with its global id: a vertex several processes
/// give has one id and the same coordinates everywhere. Then, as for
/// hoc_mesh_create, each process tags the boundary facets and feature edges
/// of its own cells and sets its own projector, which is asked only about
/// entities its facets or edges carry. Settings must be the same on every
/// process (a run checks). hoc_mesh_run_increments is then collective, and
/// the queries give this process's share of the curved mesh: its cells
/// (with the cells the repair made from them), their nodes numbered
/// locally with its vertices first in its order (hoc_mesh_get_global_nodes
/// gives each node's global index and owner), and the whole mesh's figures
/// (hoc_mesh_quality, except n_cells, the share's).
///
/// @param[in] comm the communicator as a Fortran handle: MPI_Comm_c2f(comm) in C, the integer in Fortran
/// @param[in] dim 2 or 3
/// @param[in] n_vertices number of this process's vertices (at most 2^32 − 1)
/// @param[in] coords `n_vertices * dim` interleaved coordinates
/// @param[in] global_ids `n_vertices` distinct ids (≥ 0) of the vertices in the whole mesh
/// @param[in] n_cells number of this process's cells (at least 1)
/// @param[in] cells `n_cells * (dim + 1)` 0-based indices of this process's vertices
/// @param[out] out the new handle (set to NULL on failure)
/// @return HOC_OK, HOC_ERROR_NULL_POINTER, HOC_ERROR_INVALID_ARGUMENT or HOC_ERROR_INVALID_MESH
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn hoc_mesh_create_distributed(
    comm: c_int,
    dim: c_int,
    n_vertices: usize,
    coords: *const f64,
    global_ids: *const i64,
    n_cells: usize,
    cells: *const i64,
    out: *mut *mut HocMesh,
) -> HocStatus {
    create_handle(out, |out_is_null| {
        let local = (|| {
            if out_is_null {
                return Err(null("out"));
            }
            let linear = linear_mesh(dim, n_vertices, coords, n_cells, cells)?;
            let ids = slice(global_ids, checked_count(n_vertices, "n_vertices")?, "global_ids")?;
            let ids = indices(ids, "global_ids")?.into_iter().map(|g| g as u64).collect();
            Session::try_new_partition(linear, comm, ids).map_err(mesh_err)
        })();
        create_distributed(comm, local)
    })
}

/// Every process's outcome of making its share, agreed: all fail with the
/// lowest failing process's status and message, if any fails.
#[cfg(feature = "mpi")]
fn create_distributed(
    comm: c_int,
    local: std::result::Result<Session, (HocStatus, String)>,
) -> std::result::Result<Session, (HocStatus, String)> {
    let failure = local.as_ref().err().map(|(status, message)| format!("{status} {message}"));
    match crate::distributed::partitioned::first_failure(comm, failure).map_err(err)? {
        None => local,
        Some(f) => Err(f
            .split_once(' ')
            .and_then(|(s, m)| Some((s.parse().ok()?, m.to_string())))
            .unwrap_or((HOC_ERROR_INVALID_MESH, f))),
    }
}

#[cfg(not(feature = "mpi"))]
fn create_distributed(
    _: c_int,
    _: std::result::Result<Session, (HocStatus, String)>,
) -> std::result::Result<Session, (HocStatus, String)> {
    Err(arg("this libhocurve was built without MPI: build it with the `mpi` cargo feature"))
}

/// Destroy a handle and set `*mesh` to NULL. NULL and `*mesh == NULL` are fine.
///
/// @param[in,out] mesh address of the handle
/// @return HOC_OK
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_destroy(mesh: *mut *mut HocMesh) -> HocStatus {
    if mesh.is_null() || (*mesh).is_null() {
        return HOC_OK;
    }
    match (**mesh).claim() {
        // Keep it held: nothing may start on the handle while it is freed.
        Some(claim) => std::mem::forget(claim),
        None => {
            set_thread_error(busy_message());
            return HOC_ERROR_BUSY;
        }
    }
    let h = std::mem::replace(&mut *mesh, std::ptr::null_mut());
    // Dropping cannot panic in our types, but never let it unwind into C.
    let _ = catch_unwind(AssertUnwindSafe(|| drop(Box::from_raw(h))));
    HOC_OK
}

/// Tag boundary facets (edges in 2D, triangles in 3D) with geometric entity
/// tags; replaces earlier tags. Untagged boundary stays straight.
///
/// @param[in,out] mesh the handle
/// @param[in] n_facets number of facets (at most 2^32 − 1)
/// @param[in] facets `n_facets * dim` vertex indices
/// @param[in] entity_tags `n_facets` tags
/// @return HOC_OK, or HOC_ERROR_INVALID_MESH if a facet is not on the boundary or is tagged twice
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_boundary(
    mesh: *mut HocMesh,
    n_facets: usize,
    facets: *const i64,
    entity_tags: *const i32,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let d = h.session.dim();
        let n_facets = checked_count(n_facets, "n_facets")?;
        let f = indices(slice(facets, checked_mul(n_facets, d, "facets")?, "facets")?, "facets")?;
        let t = slice(entity_tags, n_facets, "entity_tags")?.to_vec();
        h.session.set_boundary(f, t).map_err(mesh_err)
    })
}

/// Tag 3D feature edges (where two CAD surfaces meet) with curve tags;
/// their high-order nodes are projected onto the curve.
///
/// @param[in,out] mesh the handle
/// @param[in] n_edges number of edges (at most 2^32 − 1)
/// @param[in] edges `2 * n_edges` vertex indices
/// @param[in] curve_tags `n_edges` tags
/// @return HOC_OK, or HOC_ERROR_INVALID_MESH if an edge is not on the boundary
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_feature_edges(
    mesh: *mut HocMesh,
    n_edges: usize,
    edges: *const i64,
    curve_tags: *const i32,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let n_edges = checked_count(n_edges, "n_edges")?;
        let e = indices(slice(edges, checked_mul(n_edges, 2, "edges")?, "edges")?, "edges")?;
        let t = slice(curve_tags, n_edges, "curve_tags")?.to_vec();
        h.session.set_feature_edges(e, t).map_err(mesh_err)
    })
}

/// Adapts a C projection callback to [`Projector`].
struct CProjector {
    f: unsafe extern "C" fn(*mut c_void, c_int, c_int, usize, *const f64, *mut f64) -> c_int,
    user_data: *mut c_void,
    dim: usize,
}

// SAFETY: hocurve calls the projector from one thread at a time (documented
// in the header); the host owns what `user_data` points to.
unsafe impl Send for CProjector {}
unsafe impl Sync for CProjector {}

impl Projector for CProjector {
    fn project(
        &self,
        entity_dim: usize,
        tag: i32,
        points: &[[f64; 3]],
        out: &mut [[f64; 3]],
    ) -> std::result::Result<(), String> {
        let d = self.dim;
        let flat: Vec<f64> = points.iter().flat_map(|p| p[..d].to_vec()).collect();
        let mut proj = vec![f64::NAN; flat.len()];
        // SAFETY: both buffers hold points.len() * dim doubles.
        let rc = unsafe {
            (self.f)(self.user_data, entity_dim as c_int, tag, points.len(), flat.as_ptr(), proj.as_mut_ptr())
        };
        if rc != 0 {
            return Err(format!("the projection callback returned {rc}"));
        }
        for (o, p) in out.iter_mut().zip(proj.chunks_exact(d)) {
            *o = [0.0; 3];
            o[..d].copy_from_slice(p);
        }
        Ok(())
    }
}

/// Hold the boundary facets (`entity_dim` = dim − 1) or the 3D feature
/// edges (`entity_dim` = 1) with these tags straight: their nodes stay where
/// the straight elevation put them, and the projector is never called for
/// them (like facets left untagged, but the tags stay set). Replaces the
/// earlier list for `entity_dim`; `n_tags` = 0 curves them all again.
///
/// @param[in,out] mesh the handle
/// @param[in] entity_dim dim − 1 for facets, 1 for 3D feature edges
/// @param[in] n_tags number of tags
/// @param[in] tags `n_tags` tags given by hoc_mesh_set_boundary or hoc_mesh_set_feature_edges
/// @return HOC_OK, HOC_ERROR_NULL_POINTER or HOC_ERROR_INVALID_ARGUMENT (a bad entity_dim, or a tag no facet or edge carries)
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_straight_tags(
    mesh: *mut HocMesh,
    entity_dim: c_int,
    n_tags: usize,
    tags: *const i32,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let entity_dim = usize::try_from(entity_dim).map_err(|_| arg(format!("entity_dim = {entity_dim}")))?;
        let tags = slice(tags, checked_count(n_tags, "n_tags")?, "tags")?;
        h.session.set_straight_tags(entity_dim, tags).map_err(err)
    })
}

/// Set the projection callback (NULL removes it).
///
/// @param[in,out] mesh the handle
/// @param[in] callback the callback
/// @param[in] user_data passed back to every call
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_projector(
    mesh: *mut HocMesh,
    callback: HocProjectFn,
    user_data: *mut c_void,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let dim = h.session.dim();
        h.session
            .set_projector(callback.map(|f| Box::new(CProjector { f, user_data, dim }) as Box<dyn Projector + Send>));
        Ok(())
    })
}

struct SendPtr(*mut c_void);
// SAFETY: the progress callback is called from one thread at a time.
unsafe impl Send for SendPtr {}

/// Set a progress callback, called at each stage and load increment; it may
/// cancel the run (NULL removes it).
///
/// @param[in,out] mesh the handle
/// @param[in] callback the callback; returns 0 to continue
/// @param[in] user_data passed back to every call
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_progress(
    mesh: *mut HocMesh,
    callback: HocProgressFn,
    user_data: *mut c_void,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let ud = SendPtr(user_data);
        h.session.set_progress(callback.map(|f| {
            Box::new(move |p: &Progress| {
                let stage = match p.stage {
                    Stage::Elevate => HOC_STAGE_ELEVATE,
                    Stage::Project => HOC_STAGE_PROJECT,
                    Stage::Increment => HOC_STAGE_INCREMENT,
                    Stage::Quality => HOC_STAGE_QUALITY,
                    Stage::Optimize => HOC_STAGE_OPTIMIZE,
                };
                let ud = &ud;
                // SAFETY: host-provided callback with its own user data.
                unsafe { f(ud.0, stage, p.step as c_int, p.total as c_int) == 0 }
            }) as crate::session::ProgressFn
        }));
        Ok(())
    })
}

/// Adapts a C linear-solver callback to [`SystemSolver`].
struct CLinearSolver {
    f: unsafe extern "C" fn(*mut c_void, i64, *const i64, *const i64, *const f64, *const f64, *mut f64) -> c_int,
    user_data: *mut c_void,
}

// SAFETY: a run calls the solver from one thread at a time (documented in the
// header, with the case of two handles sharing it); the host owns `user_data`.
unsafe impl Send for CLinearSolver {}
unsafe impl Sync for CLinearSolver {}

/// Indices as `int64_t`: borrowed where `usize` has the same layout.
fn as_i64(v: &[usize]) -> Cow<'_, [i64]> {
    if std::mem::size_of::<usize>() == std::mem::size_of::<i64>() {
        // SAFETY: same size and alignment; entries are offsets into Rust
        // allocations, so at most isize::MAX and unchanged as i64.
        Cow::Borrowed(unsafe { std::slice::from_raw_parts(v.as_ptr() as *const i64, v.len()) })
    } else {
        Cow::Owned(v.iter().map(|&k| k as i64).collect())
    }
}

impl SystemSolver for CLinearSolver {
    fn solve(&self, a: CsrView<'_>, rhs: &[f64], x: &mut [f64]) -> std::result::Result<(), String> {
        let (row_ptr, col_idx) = (as_i64(a.row_ptr), as_i64(a.col_idx));
        // SAFETY: row_ptr has n + 1 entries, col_idx and values row_ptr[n],
        // rhs and x n each (the adapter's pattern); the callback is the host's.
        let rc = unsafe {
            (self.f)(
                self.user_data,
                a.n as i64,
                row_ptr.as_ptr(),
                col_idx.as_ptr(),
                a.values.as_ptr(),
                rhs.as_ptr(),
                x.as_mut_ptr(),
            )
        };
        if rc != 0 {
            return Err(format!("the callback returned status {rc}"));
        }
        Ok(())
    }
}

/// Solve every linear system of the next runs with the host's solver (see
/// HocLinearSolverFn for what it receives and must return); NULL restores the
/// built-in solvers.
///
/// @param[in,out] mesh the handle
/// @param[in] solve the callback, or NULL
/// @param[in] user_data passed back to every call
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_linear_solver(
    mesh: *mut HocMesh,
    solve: HocLinearSolverFn,
    user_data: *mut c_void,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        h.session.set_linear_solver(solve.map(|f| ExternalSolver::new(CLinearSolver { f, user_data })));
        Ok(())
    })
}

/// Number of worker threads of this handle's own pool (0 = one per core).
/// The pool is started in full by the next run, so counts above 4096 are
/// refused.
///
/// @param[in,out] mesh the handle
/// @param[in] n_threads 0 to 4096
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_threads(mesh: *mut HocMesh, n_threads: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let n = usize::try_from(n_threads).map_err(|_| arg(format!("n_threads must be >= 0, got {n_threads}")))?;
        h.session.set_threads(n).map_err(err)
    })
}

/// Whether boundary caps are removed before curving (default 1). A cap is a
/// tet with two faces on the same smooth surface (same tag, normals within
/// 45°) sharing an edge, its other faces and chord interior: curving makes its
/// Jacobian vanish along that edge, so it comes out inverted whatever the
/// interior does. Removing it flips that surface edge to the chord; the curved
/// mesh covers the same domain with fewer cells (see hoc_mesh_cell_count and
/// hoc_mesh_get_input_cells). 2D meshes are never changed. Discards a curved
/// result.
///
/// @param[in,out] mesh the handle
/// @param[in] remove 1 to remove caps, 0 to keep them (and every cell as given
///   if the repair is off too, see hoc_mesh_set_repair)
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_remove_caps(mesh: *mut HocMesh, remove: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let remove = flag("remove", remove)?;
        h.session.set_remove_caps(remove).map_err(err)
    })
}

/// Whether a run that removed caps (hoc_mesh_set_remove_caps, or the
/// repair's) and still ends with a certified-invalid cell is made once more
/// with the caps kept (default 1). Removing a cap turns its interior chord
/// into a boundary edge, which on a coarse mesh under strong curvature can
/// bulge through the cells below it. hoc_mesh_retry says when it happened.
/// The second run goes through every stage again from HOC_STAGE_ELEVATE, and
/// asks the projector to place the boundary again (a host whose projector
/// or progress callback keeps state per run sees it there). Takes effect
/// at the next run.
///
/// @param[in,out] mesh the handle
/// @param[in] enabled 1 on, 0 off
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_retry(mesh: *mut HocMesh, enabled: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let enabled = flag("enabled", enabled)?;
        h.session.set_retry_keep_caps(enabled);
        Ok(())
    })
}

/// Whether the last successful run was made a second time with the caps
/// kept (hoc_mesh_set_retry), and the error that ended its first run.
/// Before any run, and after a run made once, caps_kept is 0 and the message "".
/// caps_kept 0 with a message: a run with the caps kept was made and ended
/// invalid too, and the mesh is that of the first run made again with every
/// optimisation round (the first had stopped after its first rounds); the
/// message is the caps-kept run's error.
///
/// @param[in] mesh the handle
/// @param[out] caps_kept 1 if the run was made again with the caps kept, else 0
/// @param[out] message_len NULL, or the length of the whole message in bytes
///   (without its NUL): call with message NULL first to size the buffer
/// @param[in] len bytes available at message (with message NULL: ignored)
/// @param[out] message NULL, or the first run's (or the caps-kept run's) error message, NUL-terminated
///   and cut to len - 1 bytes (len 0: nothing written)
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_retry(
    mesh: *const HocMesh,
    caps_kept: *mut c_int,
    message_len: *mut usize,
    len: usize,
    message: *mut c_char,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let caps_kept = caps_kept.as_mut().ok_or_else(|| null("caps_kept"))?;
        let report = h.session.report();
        let first = report.and_then(|r| r.caps_kept_after.as_deref());
        *caps_kept = first.is_some() as c_int;
        let bytes = first.or_else(|| report.and_then(|r| r.caps_kept_failed.as_deref())).unwrap_or("").as_bytes();
        if let Some(l) = message_len.as_mut() {
            *l = bytes.len();
        }
        if !message.is_null() && len > 0 {
            let n = bytes.len().min(len - 1);
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), message.cast::<u8>(), n);
            *message.add(n) = 0;
        }
        Ok(())
    })
}

/// Whether each run repairs the linear mesh first (default 1). A cell whose
/// vertices all lie on one surface that bulges into the domain (e.g. a tet
/// inside the shell between a sphere cavity and its straight facets), or
/// whose boundary facet bulges, once curved, past half the height of the
/// opposite vertex (itself on the boundary), cannot stay valid with its
/// vertices fixed. The run
/// projects a few points of every tagged facet to measure the bulges, then
/// removes such cells by local flips (2-3, 3-2, edge removal; edge flips in
/// 2D) that keep the boundary facets and vertices; unless caps are kept
/// (hoc_mesh_set_remove_caps), such a cell that no flip helps and that is a
/// cap whose faces meet at more than 45° is removed like a cap. Last, an
/// interior edge opposite a vertex where a triangle has two boundary edges
/// on a smooth boundary (which would squeeze the cells between that
/// triangle and the boundary flat there) is split at its midpoint, a new
/// interior vertex. The curved
/// mesh may then have other cells and nodes than the straight one (see hoc_mesh_cell_count,
/// hoc_mesh_get_input_cells and hoc_mesh_repair_summary). Takes effect at
/// the next run.
///
/// @param[in,out] mesh the handle
/// @param[in] enabled 1 on, 0 off
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_repair(mesh: *mut HocMesh, enabled: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let enabled = flag("enabled", enabled)?;
        h.session.set_repair(enabled);
        Ok(())
    })
}

/// Static condensation of the cell-interior nodes (default 1). The nodes
/// inside a cell (from p = 4 for tets, p = 3 for triangles) couple only with
/// that cell's nodes; they are eliminated cell by cell before each linear
/// solve and recovered after it, so the systems (also those an external
/// solver receives, see HocLinearSolveFn) hold only the vertex, edge and face
/// nodes. The curved mesh is the same to round-off; the runs are faster
/// (1.04x at p = 4 to 1.5x at p = 6) and use less memory.
///
/// @param[in,out] mesh the handle
/// @param[in] enabled 1 on, 0 off
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_static_condensation(mesh: *mut HocMesh, enabled: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let enabled = flag("enabled", enabled)?;
        h.session.set_condense(enabled);
        Ok(())
    })
}

/// The optimisation stage after the elastic solve (default 1): the nodes
/// around every cell that the elastic curving leaves invalid, or with Q3
/// below 0.2, are moved to untangle and improve it (boundary nodes stay on
/// their entity). With it on, an increment that adaptive stepping cannot
/// keep valid does not fail the run: the rest of the load is applied in one
/// solve and the optimisation must make the mesh valid, or the run fails
/// with HOC_ERROR_INVALID_ELEMENT and the mesh is left as it was. With it
/// off, such a run fails as soon as adaptive stepping gives up.
///
/// @param[in,out] mesh the handle
/// @param[in] enabled 1 on, 0 off
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_optimize(mesh: *mut HocMesh, enabled: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let enabled = flag("enabled", enabled)?;
        h.session.set_optimize(enabled);
        Ok(())
    })
}

/// For a slow projector (default 0): where moving the interior nodes leaves
/// a cell invalid or below 0.2, the optimisation's boundary nodes first
/// move in their entity's tangent planes and are projected after each pass,
/// and at every step only if that is not enough. On parts that need sliding
/// this makes a fifth to a third of the projector calls; the mesh is as
/// valid, its smallest quality sometimes lower. The polish always slides
/// this way.
///
/// @param[in,out] mesh the handle
/// @param[in] enabled 1 on, 0 off
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_tangent_first(mesh: *mut HocMesh, enabled: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let enabled = flag("enabled", enabled)?;
        h.session.set_tangent_first(enabled);
        Ok(())
    })
}

/// What the optimisation stage of the last successful run did; all zero
/// (elastic_load 1, qualities NaN) before any run.
///
/// @param[in] mesh the handle
/// @param[out] out the figures
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_optimization(mesh: *const HocMesh, out: *mut HocOptimization) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let out = out.as_mut().ok_or_else(|| null("out"))?;
        *out = match h.session.report() {
            Some(r) => {
                let o = &r.optimization;
                HocOptimization {
                    ran: o.ran as c_int,
                    elastic_stopped: r.elastic_stop.is_some() as c_int,
                    elastic_load: r.elastic_stop.as_ref().map_or(1.0, |s| s.load),
                    elastic_restarted: r.elastic_stop.as_ref().is_some_and(|s| s.restarted) as c_int,
                    target_cells: o.target_cells,
                    cells_touched: o.cells_touched,
                    nodes_moved: o.nodes_moved,
                    patches: o.patches,
                    cells_split: o.cells_split,
                    invalid_before: o.invalid_before,
                    invalid_after: o.invalid_after,
                    min_q3_before: o.min_q3_before,
                    min_q3_after: o.min_q3_after,
                    seconds: o.seconds,
                }
            }
            None => HocOptimization {
                elastic_load: 1.0,
                min_q3_before: f64::NAN,
                min_q3_after: f64::NAN,
                ..Default::default()
            },
        };
        Ok(())
    })
}

/// Where the last successful run's time went, per stage; all zero before
/// any run.
///
/// @param[in] mesh the handle
/// @param[out] out the seconds
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_timings(mesh: *const HocMesh, out: *mut HocTimings) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let out = out.as_mut().ok_or_else(|| null("out"))?;
        *out = h.session.report().map_or_else(HocTimings::default, |r| {
            let t = &r.timings;
            HocTimings {
                total: t.total,
                repair_and_elevate: t.elevate,
                place_boundary: t.project,
                assembly: t.assembly,
                solver_setup: t.setup,
                solve: t.solve,
                check: t.check,
                optimize: t.optimize,
                quality: t.quality,
            }
        });
        Ok(())
    })
}

/// Polynomial order (1..10) and node spacing. Discards a curved result.
///
/// @param[in,out] mesh the handle
/// @param[in] order 1 to 10
/// @param[in] spacing HOC_SPACING_OPTIMAL or HOC_SPACING_EQUISPACED
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_order(mesh: *mut HocMesh, order: c_int, spacing: HocNodeSpacing) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let spacing = match spacing {
            HOC_SPACING_OPTIMAL => NodeSpacing::Optimal,
            HOC_SPACING_EQUISPACED => NodeSpacing::Equispaced,
            s => return Err(arg(format!("unknown node spacing {s}"))),
        };
        let order = usize::try_from(order).map_err(|_| arg(format!("order must be between 1 and 10, got {order}")))?;
        h.session.set_order(order, spacing).map_err(err)
    })
}

/// Material model and constants: Young's modulus E > 0, Poisson's ratio
/// 0 ≤ ν < 0.5.
///
/// @param[in,out] mesh the handle
/// @param[in] model a HOC_MATERIAL_* value
/// @param[in] young E
/// @param[in] poisson ν
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_material(
    mesh: *mut HocMesh,
    model: HocMaterial,
    young: f64,
    poisson: f64,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let model = match model {
            HOC_MATERIAL_LINEAR_ELASTIC => MaterialModel::LinearElastic,
            HOC_MATERIAL_NEO_HOOKEAN => MaterialModel::NeoHookean,
            HOC_MATERIAL_MOONEY_RIVLIN => MaterialModel::MooneyRivlin,
            HOC_MATERIAL_NI_MOONEY_RIVLIN => MaterialModel::NearlyIncompressibleMooneyRivlin,
            HOC_MATERIAL_TRANSVERSELY_ISOTROPIC => MaterialModel::TransverselyIsotropic,
            HOC_MATERIAL_TRANSVERSELY_ISOTROPIC_LINEAR => MaterialModel::TransverselyIsotropicLinear,
            m => return Err(arg(format!("unknown material {m}"))),
        };
        h.session.set_material(model, young, poisson).map_err(err)
    })
}

/// Solid-mechanics formulation.
///
/// @param[in,out] mesh the handle
/// @param[in] formulation a HOC_FORMULATION_* value
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_formulation(mesh: *mut HocMesh, formulation: HocFormulation) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let f = match formulation {
            HOC_FORMULATION_LINEAR => Formulation::Linear,
            HOC_FORMULATION_ILE => Formulation::Ile,
            HOC_FORMULATION_IIL => Formulation::Iil,
            HOC_FORMULATION_CIL => Formulation::Cil,
            HOC_FORMULATION_NONLINEAR => Formulation::Nonlinear,
            f => return Err(arg(format!("unknown formulation {f}"))),
        };
        h.session.set_formulation(f);
        Ok(())
    })
}

/// Newton–Raphson settings of HOC_FORMULATION_NONLINEAR: converged when
/// ‖R‖/‖R₀‖ < `tolerance` (default 1e-5), at most `max_iterations` (default 30)
/// iterations per increment.
///
/// @param[in,out] mesh the handle
/// @param[in] tolerance > 0
/// @param[in] max_iterations ≥ 1
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_newton(mesh: *mut HocMesh, tolerance: f64, max_iterations: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let n = usize::try_from(max_iterations)
            .map_err(|_| arg(format!("max_iterations must be >= 1, got {max_iterations}")))?;
        h.session.set_newton(tolerance, n).map_err(err)
    })
}

/// Adaptive load stepping: when an increment inverts a cell (certified
/// check: Bernstein bounds of det J) or its Newton iteration fails, the mesh
/// goes back to the start of that increment and the increment is halved, at
/// most `max_splits` times (the smallest step is 1/(increments·2^max_splits)
/// of the load); the run fails with HOC_ERROR_INVALID_ELEMENT or
/// HOC_ERROR_SOLVER only at that limit. Default: on for the incremental
/// formulations (ILE, IIL, CIL, NONLINEAR), off for HOC_FORMULATION_LINEAR;
/// max_splits 6. See hoc_mesh_increment_count for what a run did.
///
/// @param[in,out] mesh the handle
/// @param[in] enabled 1 on, 0 off, -1 the default for the formulation
/// @param[in] max_splits 0 to 30
/// @return HOC_OK or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_adaptive_stepping(
    mesh: *mut HocMesh,
    enabled: c_int,
    max_splits: c_int,
) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        let enabled = match enabled {
            -1 => None,
            0 => Some(false),
            1 => Some(true),
            e => return Err(arg(format!("enabled must be 1, 0 or -1, got {e}"))),
        };
        let n = usize::try_from(max_splits).map_err(|_| arg(format!("max_splits must be >= 0, got {max_splits}")))?;
        h.session.set_adaptive(enabled, n).map_err(err)
    })
}

/// Fibre direction of every cell for the transversely isotropic materials
/// (3 doubles per cell, also in 2D; normalised by hocurve). NULL restores the
/// default: −x inside, tangent to the boundary on boundary cells. One
/// direction per cell given to hoc_mesh_create, in that order, also when
/// boundary caps are removed (the cells that remain keep theirs; see
/// hoc_mesh_get_input_cells).
///
/// @param[in,out] mesh the handle
/// @param[in] n_cells must equal the number of cells given to hoc_mesh_create (ignored when `fibres` is NULL)
/// @param[in] fibres `3 * n_cells` doubles, or NULL
/// @return HOC_OK, HOC_ERROR_BUFFER_SIZE or HOC_ERROR_INVALID_ARGUMENT
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_set_fibres(mesh: *mut HocMesh, n_cells: usize, fibres: *const f64) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        if fibres.is_null() {
            return h.session.set_fibres(None).map_err(err);
        }
        // One fibre per cell given to hoc_mesh_create: the current mesh has
        // fewer when boundary caps were removed.
        let nc = h.session.n_input_cells();
        if n_cells != nc {
            return Err((
                HOC_ERROR_BUFFER_SIZE,
                format!("n_cells = {n_cells}, but the mesh was created with {nc} cells"),
            ));
        }
        let f = slice(fibres, checked_mul(n_cells, 3, "fibres")?, "fibres")?;
        h.session.set_fibres(Some(f.chunks_exact(3).map(|v| [v[0], v[1], v[2]]).collect())).map_err(err)
    })
}

/// Curve the mesh: project the tagged boundary and solve in `increments`
/// load increments (split further by adaptive stepping where needed, see
/// hoc_mesh_set_adaptive_stepping). On failure the mesh is exactly as before
/// the call.
///
/// @param[in,out] mesh the handle
/// @param[in] increments ≥ 1
/// @return HOC_OK or the failure's status; see hoc_mesh_last_error
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_run_increments(mesh: *mut HocMesh, increments: c_int) -> HocStatus {
    guard(mesh, || {
        let h = handle_mut(mesh)?;
        if h.session.partition().is_some() {
            // Checked with every process's, so that none is left waiting.
            return run_distributed(&mut h.session, usize::try_from(increments).unwrap_or(0)).map_err(err);
        }
        let n = usize::try_from(increments)
            .ok()
            .filter(|&n| n >= 1)
            .ok_or_else(|| arg(format!("increments must be >= 1, got {increments}")))?;
        h.session.run(n).map_err(err)
    })
}

#[cfg(feature = "mpi")]
fn run_distributed(session: &mut Session, increments: usize) -> crate::Result<()> {
    crate::distributed::partitioned::run(session, increments)
}

#[cfg(not(feature = "mpi"))]
fn run_distributed(_: &mut Session, _: usize) -> crate::Result<()> {
    unreachable!("a distributed handle needs the mpi feature")
}

/// Quality of the current mesh.
///
/// @param[in] mesh the handle
/// @param[out] out the figures
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_quality(mesh: *const HocMesh, out: *mut HocQuality) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let out = out.as_mut().ok_or_else(|| null("out"))?;
        let q = h.session.quality();
        *out = HocQuality {
            min_q1: q.min_q1,
            min_q2: q.min_q2,
            min_q3: q.min_q3,
            min_q4: q.min_q4,
            min_q5: q.min_q5,
            mean_q3: q.mean_q3,
            n_invalid: q.n_invalid,
            n_cells: h.session.mesh().n_cells(),
            certified_min_q3: q.certified_min_q3,
            n_certified_invalid: q.n_certified_invalid,
            n_uncertain: q.n_uncertain,
            max_projection_distance: h.session.report().map_or(0.0, |r| r.max_projection_distance),
        };
        Ok(())
    })
}

/// What the repair did: the boundary caps removed (by the last successful
/// run, which may have kept them, see hoc_mesh_retry; before a run, those
/// the run will remove), and the flips of the last successful run (zero
/// before a run, or when the run did not repair).
///
/// @param[in] mesh the handle
/// @param[out] out the counts
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_repair_summary(mesh: *const HocMesh, out: *mut HocRepair) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let out = out.as_mut().ok_or_else(|| null("out"))?;
        let s = &h.session;
        let r = s.report().map(|r| r.repair).unwrap_or_default();
        *out = HocRepair {
            removed_caps: s.report().map_or(s.n_input_cells() - s.n_straight_cells(), |r| r.removed_caps),
            bad_cells: r.bad_cells,
            surface_cells: r.surface_cells,
            bulge_cells: r.bulge_cells,
            flips_23: r.flips_23,
            flips_32: r.flips_32,
            edge_removals: r.edge_removals,
            flips_22: r.flips_22,
            surface_caps: r.surface_caps,
            cells_removed: r.cells_removed,
            cells_added: r.cells_added,
            bad_cells_left: r.bad_cells_left,
            edge_splits: r.edge_splits,
            surface_flips: r.surface_flips,
        };
        Ok(())
    })
}

/// Per-cell quality Q`measure` (1, 2 or 3).
///
/// @param[in] mesh the handle
/// @param[in] measure 1, 2 or 3
/// @param[in] n number of cells (the length of `out`)
/// @param[out] out one value per cell
/// @return HOC_OK, HOC_ERROR_INVALID_ARGUMENT or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_cell_quality(
    mesh: *const HocMesh,
    measure: c_int,
    n: usize,
    out: *mut f64,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let cq = h.session.cell_quality();
        if n != cq.len() {
            return Err((HOC_ERROR_BUFFER_SIZE, format!("n = {n}, but the mesh has {} cells", cq.len())));
        }
        if out.is_null() {
            return Err(null("out"));
        }
        let get: fn(&crate::quality::ElementQuality) -> f64 = match measure {
            1 => |q| q.q1,
            2 => |q| q.q2,
            3 => |q| q.q3,
            m => return Err(arg(format!("quality measure must be 1, 2 or 3, got {m}"))),
        };
        let out = std::slice::from_raw_parts_mut(out, n);
        for (o, q) in out.iter_mut().zip(cq) {
            *o = get(q);
        }
        Ok(())
    })
}

/// Load increments of the last successful run: how many were taken (the
/// requested number, more if adaptive stepping split some) and how many were
/// rejected and split. Both 0 before a run.
///
/// @param[in] mesh the handle
/// @param[out] n_taken accepted increments
/// @param[out] n_step_backs rejected increments
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_increment_count(
    mesh: *const HocMesh,
    n_taken: *mut usize,
    n_step_backs: *mut usize,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let (taken, backs) = h.session.report().map_or((0, 0), |r| (r.load_fractions.len(), r.step_backs.len()));
        *n_taken.as_mut().ok_or_else(|| null("n_taken"))? = taken;
        *n_step_backs.as_mut().ok_or_else(|| null("n_step_backs"))? = backs;
        Ok(())
    })
}

/// Load fraction reached by each accepted increment of the last run, in
/// (0, 1], increasing, the last one 1.
///
/// @param[in] mesh the handle
/// @param[in] n_taken must equal the count of hoc_mesh_increment_count
/// @param[out] fractions `n_taken` doubles
/// @return HOC_OK, HOC_ERROR_NULL_POINTER or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_get_load_fractions(
    mesh: *const HocMesh,
    n_taken: usize,
    fractions: *mut f64,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let l = h.session.report().map_or(&[][..], |r| &r.load_fractions[..]);
        if n_taken != l.len() {
            return Err((
                HOC_ERROR_BUFFER_SIZE,
                format!("n_taken = {n_taken}, but the run took {} increments", l.len()),
            ));
        }
        if n_taken > 0 {
            std::slice::from_raw_parts_mut(fractions.as_mut().ok_or_else(|| null("fractions"))?, n_taken)
                .copy_from_slice(l);
        }
        Ok(())
    })
}

/// The increments of the last run that adaptive stepping rejected, in order:
/// the load fraction at the start of each, its size, the reason and the
/// offending cell (-1 when not known). Any output may be NULL.
///
/// @param[in] mesh the handle
/// @param[in] n_step_backs must equal the count of hoc_mesh_increment_count
/// @param[out] loads `n_step_backs` doubles, or NULL
/// @param[out] steps `n_step_backs` doubles, or NULL
/// @param[out] reasons `n_step_backs` HOC_STEP_BACK_* values, or NULL
/// @param[out] cells `n_step_backs` cell indices, or NULL
/// @return HOC_OK or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_get_step_backs(
    mesh: *const HocMesh,
    n_step_backs: usize,
    loads: *mut f64,
    steps: *mut f64,
    reasons: *mut HocStepBackReason,
    cells: *mut i64,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let b = h.session.report().map_or(&[][..], |r| &r.step_backs[..]);
        if n_step_backs != b.len() {
            return Err((
                HOC_ERROR_BUFFER_SIZE,
                format!("n_step_backs = {n_step_backs}, but the run stepped back {} times", b.len()),
            ));
        }
        for (i, s) in b.iter().enumerate() {
            if !loads.is_null() {
                *loads.add(i) = s.load;
            }
            if !steps.is_null() {
                *steps.add(i) = s.step;
            }
            if !reasons.is_null() {
                *reasons.add(i) = match s.reason {
                    StepBackReason::SampledInvalid => HOC_STEP_BACK_SAMPLED_INVALID,
                    StepBackReason::CertifiedInvalid => HOC_STEP_BACK_CERTIFIED_INVALID,
                    StepBackReason::NewtonFailed => HOC_STEP_BACK_NEWTON_FAILED,
                    StepBackReason::Restarted => HOC_STEP_BACK_RESTARTED,
                };
            }
            if !cells.is_null() {
                *cells.add(i) = s.cell.map_or(-1, |c| c as i64);
            }
        }
        Ok(())
    })
}

/// Linear solves of the last successful run (rejected increments and Newton
/// iterations included), and how many of them fell back from the first
/// choice of solver (PCG restarted with a safe preconditioner, the direct
/// solver after PCG, LU after Cholesky). Both 0 before a run.
///
/// @param[in] mesh the handle
/// @param[out] n_solves linear solves
/// @param[out] n_fallbacks solves that fell back
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_solve_count(
    mesh: *const HocMesh,
    n_solves: *mut usize,
    n_fallbacks: *mut usize,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let (solves, fallbacks) = h.session.report().map_or((0, 0), |r| (r.solves.len(), r.solves.fallbacks()));
        *n_solves.as_mut().ok_or_else(|| null("n_solves"))? = solves;
        *n_fallbacks.as_mut().ok_or_else(|| null("n_fallbacks"))? = fallbacks;
        Ok(())
    })
}

/// The linear solves of the last run, in order: the solver that produced
/// each solution, why the first choice did not (HOC_FALLBACK_NONE when it
/// did) and the Krylov iterations run (0 for a direct solve; those of a
/// failed attempt included). Any output may be NULL.
///
/// @param[in] mesh the handle
/// @param[in] n_solves must equal the count of hoc_mesh_solve_count
/// @param[out] solved_by `n_solves` HOC_SOLVED_BY_* values, or NULL
/// @param[out] fallbacks `n_solves` HOC_FALLBACK_* values, or NULL
/// @param[out] iterations `n_solves` counts, or NULL
/// @return HOC_OK or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_get_solves(
    mesh: *const HocMesh,
    n_solves: usize,
    solved_by: *mut HocSolvedBy,
    fallbacks: *mut HocFallbackReason,
    iterations: *mut usize,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let Some(r) = h.session.report().filter(|r| !r.solves.is_empty()) else {
            return match n_solves {
                0 => Ok(()),
                _ => Err((HOC_ERROR_BUFFER_SIZE, format!("n_solves = {n_solves}, but no solve has run"))),
            };
        };
        if n_solves != r.solves.len() {
            return Err((
                HOC_ERROR_BUFFER_SIZE,
                format!("n_solves = {n_solves}, but the run made {} linear solves", r.solves.len()),
            ));
        }
        for i in 0..n_solves {
            if !solved_by.is_null() {
                *solved_by.add(i) = solved_by_code(r.solves.solved_by[i]);
            }
            if !fallbacks.is_null() {
                *fallbacks.add(i) = r.solves.fallback[i].map_or(HOC_FALLBACK_NONE, fallback_code);
            }
            if !iterations.is_null() {
                *iterations.add(i) = r.solves.iterations[i];
            }
        }
        Ok(())
    })
}

fn solved_by_code(s: SolvedBy) -> HocSolvedBy {
    match s {
        SolvedBy::Pcg => HOC_SOLVED_BY_PCG,
        SolvedBy::PcgRestarted => HOC_SOLVED_BY_PCG_RESTARTED,
        SolvedBy::Direct => HOC_SOLVED_BY_DIRECT,
        SolvedBy::DirectLu => HOC_SOLVED_BY_DIRECT_LU,
        SolvedBy::External => HOC_SOLVED_BY_EXTERNAL,
    }
}

fn fallback_code(f: FallbackReason) -> HocFallbackReason {
    match f {
        FallbackReason::PreconditionerNotPositive => HOC_FALLBACK_PRECONDITIONER_NOT_POSITIVE,
        FallbackReason::Stagnation => HOC_FALLBACK_STAGNATION,
        FallbackReason::EigenvalueUnderestimated => HOC_FALLBACK_EIGENVALUE_UNDERESTIMATED,
        FallbackReason::NotConverged => HOC_FALLBACK_NOT_CONVERGED,
        FallbackReason::NonFinite => HOC_FALLBACK_NON_FINITE,
        FallbackReason::MatrixNotPositive => HOC_FALLBACK_MATRIX_NOT_POSITIVE,
        FallbackReason::PreconditionerSetup => HOC_FALLBACK_PRECONDITIONER_SETUP,
        FallbackReason::CholeskyFailed => HOC_FALLBACK_CHOLESKY_FAILED,
    }
}

/// The name of a HocSolvedBy value ("pcg", "pcg-restarted", "direct",
/// "direct-lu", "external"; "unknown" for another value).
///
/// @param[in] solved_by a HOC_SOLVED_BY_* value
/// @return a NUL-terminated static string
#[no_mangle]
pub extern "C" fn hoc_solved_by_string(solved_by: HocSolvedBy) -> *const c_char {
    let s: &'static CStr = match solved_by {
        HOC_SOLVED_BY_PCG => c"pcg",
        HOC_SOLVED_BY_PCG_RESTARTED => c"pcg-restarted",
        HOC_SOLVED_BY_DIRECT => c"direct",
        HOC_SOLVED_BY_DIRECT_LU => c"direct-lu",
        HOC_SOLVED_BY_EXTERNAL => c"external",
        _ => c"unknown",
    };
    s.as_ptr()
}

/// The name of a HocFallbackReason value ("none", "stagnation", ...; the
/// names of the CLI's JSON report; "unknown" for another value).
///
/// @param[in] reason a HOC_FALLBACK_* value
/// @return a NUL-terminated static string
#[no_mangle]
pub extern "C" fn hoc_fallback_reason_string(reason: HocFallbackReason) -> *const c_char {
    let s: &'static CStr = match reason {
        HOC_FALLBACK_NONE => c"none",
        HOC_FALLBACK_PRECONDITIONER_NOT_POSITIVE => c"preconditioner-not-positive-definite",
        HOC_FALLBACK_STAGNATION => c"stagnation",
        HOC_FALLBACK_EIGENVALUE_UNDERESTIMATED => c"eigenvalue-underestimated",
        HOC_FALLBACK_NOT_CONVERGED => c"not-converged",
        HOC_FALLBACK_NON_FINITE => c"non-finite-residual",
        HOC_FALLBACK_MATRIX_NOT_POSITIVE => c"matrix-not-positive-definite",
        HOC_FALLBACK_PRECONDITIONER_SETUP => c"preconditioner-setup-failed",
        HOC_FALLBACK_CHOLESKY_FAILED => c"cholesky-failed",
        _ => c"unknown",
    };
    s.as_ptr()
}

/// Number of nodes of the current (order-p) mesh.
///
/// @param[in] mesh the handle
/// @param[out] n_nodes the count
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_node_count(mesh: *const HocMesh, n_nodes: *mut usize) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        *n_nodes.as_mut().ok_or_else(|| null("n_nodes"))? = h.session.mesh().n_nodes();
        Ok(())
    })
}

/// Number of cells and nodes per cell of the current mesh.
///
/// @param[in] mesh the handle
/// @param[out] n_cells the cell count
/// @param[out] nodes_per_cell (p+1)(p+2)/2 or (p+1)(p+2)(p+3)/6
/// @return HOC_OK or HOC_ERROR_NULL_POINTER
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_cell_count(
    mesh: *const HocMesh,
    n_cells: *mut usize,
    nodes_per_cell: *mut usize,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let m = h.session.mesh();
        *n_cells.as_mut().ok_or_else(|| null("n_cells"))? = m.n_cells();
        *nodes_per_cell.as_mut().ok_or_else(|| null("nodes_per_cell"))? = m.nodes_per_cell();
        Ok(())
    })
}

/// For each cell of the current mesh, the index (0-based) of an input cell.
/// The straight mesh is the input cells in their order, less the boundary
/// caps removed (hoc_mesh_set_remove_caps). After a run that repaired cells
/// (hoc_mesh_set_repair), the cells no flip touched come first, in that
/// order, then the new cells, each mapped to the input cell that contains
/// its centroid.
///
/// @param[in] mesh the handle
/// @param[in] n_cells must equal the count of hoc_mesh_cell_count
/// @param[out] input_cells `n_cells` indices
/// @return HOC_OK, HOC_ERROR_NULL_POINTER or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_get_input_cells(
    mesh: *const HocMesh,
    n_cells: usize,
    input_cells: *mut i64,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let map = h.session.input_cells();
        if n_cells != map.len() {
            return Err((HOC_ERROR_BUFFER_SIZE, format!("n_cells = {n_cells}, but the mesh has {} cells", map.len())));
        }
        if input_cells.is_null() {
            return Err(null("input_cells"));
        }
        let out = std::slice::from_raw_parts_mut(input_cells, n_cells);
        for (o, &c) in out.iter_mut().zip(map) {
            *o = c as i64;
        }
        Ok(())
    })
}

fn node_ordering(ordering: HocNodeOrdering) -> std::result::Result<NodeOrdering, (HocStatus, String)> {
    match ordering {
        HOC_ORDERING_NATIVE => Ok(NodeOrdering::Native),
        HOC_ORDERING_GMSH => Ok(NodeOrdering::Gmsh),
        HOC_ORDERING_VTK => Ok(NodeOrdering::Vtk),
        o => Err(arg(format!("unknown node ordering {o}"))),
    }
}

/// For each node of the current mesh, its index in the whole mesh and its
/// owner, the lowest MPI process whose share holds it. For a handle of
/// hoc_mesh_create: its own index, owner 0. For a share of a distributed
/// mesh (hoc_mesh_create_distributed): after a successful run, the index
/// in the whole curved mesh, the same on every process that holds the
/// node; before, HOC_ERROR_INVALID_ARGUMENT.
///
/// @param[in] mesh the handle
/// @param[in] n_nodes must equal hoc_mesh_node_count
/// @param[out] global_ids NULL, or `n_nodes` indices
/// @param[out] owners NULL, or `n_nodes` ranks
/// @return HOC_OK, HOC_ERROR_NULL_POINTER, HOC_ERROR_INVALID_ARGUMENT or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_get_global_nodes(
    mesh: *const HocMesh,
    n_nodes: usize,
    global_ids: *mut i64,
    owners: *mut c_int,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let n = h.session.mesh().n_nodes();
        if n_nodes != n {
            return Err((HOC_ERROR_BUFFER_SIZE, format!("n_nodes = {n_nodes}, but the mesh has {n}")));
        }
        let (ids, ranks): (Cow<'_, [u64]>, Cow<'_, [i32]>) = match h.session.partition() {
            None => (Cow::Owned((0..n as u64).collect()), Cow::Owned(vec![0; n])),
            Some(p) => match &p.nodes {
                Some((ids, ranks)) => (Cow::Borrowed(ids), Cow::Borrowed(ranks)),
                None => return Err(arg("the global node ids of a distributed mesh are known after a run")),
            },
        };
        if !global_ids.is_null() {
            for (o, &g) in std::slice::from_raw_parts_mut(global_ids, n).iter_mut().zip(ids.iter()) {
                *o = g as i64;
            }
        }
        if !owners.is_null() {
            std::slice::from_raw_parts_mut(owners, n).copy_from_slice(&ranks);
        }
        Ok(())
    })
}

/// Node coordinates of the current mesh (`n_nodes * dim` doubles) for
/// connectivity in `ordering`. Nodes `0..n_vertices-1` are the input
/// vertices, and the numbering is the same for every ordering; the positions
/// are not:
/// - HOC_ORDERING_NATIVE: the mesh's own node set (hoc_mesh_set_order's
///   spacing; warp & blend by default);
/// - HOC_ORDERING_GMSH, HOC_ORDERING_VTK: the equispaced node set that gmsh's
///   and VTK's Lagrange cells interpolate at. The curved element map is
///   evaluated there, so a file written with these nodes and the matching
///   hoc_mesh_get_cells connectivity has exactly the curved geometry.
///
/// @param[in] mesh the handle
/// @param[in] ordering HOC_ORDERING_NATIVE, _GMSH or _VTK: that of the connectivity used with them
/// @param[in] n_nodes must equal hoc_mesh_node_count
/// @param[out] coords `n_nodes * dim` doubles
/// @return HOC_OK, HOC_ERROR_NULL_POINTER, HOC_ERROR_INVALID_ARGUMENT or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_get_nodes(
    mesh: *const HocMesh,
    ordering: HocNodeOrdering,
    n_nodes: usize,
    coords: *mut f64,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let ordering = node_ordering(ordering)?;
        let m = h.session.mesh();
        if n_nodes != m.n_nodes() {
            return Err((HOC_ERROR_BUFFER_SIZE, format!("n_nodes = {n_nodes}, but the mesh has {}", m.n_nodes())));
        }
        if coords.is_null() {
            return Err(null("coords"));
        }
        std::slice::from_raw_parts_mut(coords, m.coords.len()).copy_from_slice(&h.session.nodes(ordering));
        Ok(())
    })
}

/// Cell connectivity of the current mesh in the requested node ordering.
/// HOC_ORDERING_NATIVE: vertices, then edge, face and interior nodes;
/// HOC_ORDERING_GMSH: gmsh's MSH element node order (types
/// 9/21/23/25/42-46 and 11/29/30/31/71-75); HOC_ORDERING_VTK: VTK's Lagrange
/// cells (69, 71). Take the coordinates from hoc_mesh_get_nodes with the
/// same ordering: gmsh and VTK cells mean equispaced nodes.
///
/// @param[in] mesh the handle
/// @param[in] ordering HOC_ORDERING_NATIVE, _GMSH or _VTK
/// @param[in] len must equal n_cells * nodes_per_cell
/// @param[out] cells 0-based node indices
/// @return HOC_OK, HOC_ERROR_INVALID_ARGUMENT or HOC_ERROR_BUFFER_SIZE
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_get_cells(
    mesh: *const HocMesh,
    ordering: HocNodeOrdering,
    len: usize,
    cells: *mut i64,
) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        let ordering = node_ordering(ordering)?;
        let m = h.session.mesh();
        if len != m.cells.len() {
            return Err((HOC_ERROR_BUFFER_SIZE, format!("len = {len}, but the connectivity has {}", m.cells.len())));
        }
        if cells.is_null() {
            return Err(null("cells"));
        }
        let out = std::slice::from_raw_parts_mut(cells, len);
        for (o, c) in out.iter_mut().zip(h.session.cells(ordering)) {
            *o = c as i64;
        }
        Ok(())
    })
}

/// Write the current mesh: `.msh` (gmsh 4.1) or `.vtu` (VTK Lagrange cells),
/// chosen by the extension. The file appears whole or not at all.
///
/// @param[in] mesh the handle
/// @param[in] path a NUL-terminated UTF-8 path
/// @return HOC_OK, HOC_ERROR_INVALID_ARGUMENT or HOC_ERROR_IO
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_write(mesh: *const HocMesh, path: *const c_char) -> HocStatus {
    guard(mesh, || {
        let h = handle(mesh)?;
        if path.is_null() {
            return Err(null("path"));
        }
        let p = CStr::from_ptr(path).to_str().map_err(|_| arg("path is not valid UTF-8"))?;
        crate::io::write_mesh(Path::new(p), h.session.mesh(), Some(h.session.cell_quality())).map_err(err)
    })
}

/// The message of the last failed call on this handle ("" after a success).
/// With NULL: the message of the last call on this thread that had no handle
/// (a failed hoc_mesh_create, or a call given a NULL handle). Valid until the
/// next call on the handle (or, for NULL, the next such call on the thread).
///
/// @param[in] mesh the handle, or NULL
/// @return a NUL-terminated string owned by the handle or the thread
#[no_mangle]
pub unsafe extern "C" fn hoc_mesh_last_error(mesh: *const HocMesh) -> *const c_char {
    let thread = || THREAD_LAST_ERROR.with(|e| e.borrow().as_ptr());
    let Some(h) = mesh.as_ref() else { return thread() };
    if REFUSED.with(|r| r.get()) == mesh {
        return thread();
    }
    match h.claim() {
        Some(mut c) => c.state().last_error.as_ptr(),
        None => {
            set_thread_error(busy_message());
            thread()
        }
    }
}

/// A static description of a status code.
///
/// @param[in] status a HocStatus
/// @return a NUL-terminated static string
#[no_mangle]
pub extern "C" fn hoc_status_string(status: HocStatus) -> *const c_char {
    let s: &'static CStr = match status {
        HOC_OK => c"success",
        HOC_ERROR_NULL_POINTER => c"a required pointer is NULL",
        HOC_ERROR_INVALID_ARGUMENT => c"invalid argument",
        HOC_ERROR_INVALID_MESH => c"invalid mesh",
        HOC_ERROR_PROJECTION => c"projection failed",
        HOC_ERROR_SOLVER => c"linear solver failed",
        HOC_ERROR_INVALID_ELEMENT => c"an element became inverted",
        HOC_ERROR_IO => c"file input/output failed",
        HOC_ERROR_CANCELLED => c"cancelled by the progress callback",
        HOC_ERROR_BUFFER_SIZE => c"buffer has the wrong size",
        HOC_ERROR_PANIC => c"internal error",
        HOC_ERROR_BUSY => c"the handle is busy with another call",
        _ => c"unknown status",
    };
    s.as_ptr()
}

/// The library version, e.g. "0.1.0".
///
/// @return a NUL-terminated static string
#[no_mangle]
pub extern "C" fn hoc_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr() as *const c_char
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curve::{CurveOptions, DEFAULT_MAX_SPLITS};

    #[test]
    fn version_macros_are_the_crate_version() {
        let v = |s: &str| s.parse::<c_int>().unwrap();
        assert_eq!(HOCURVE_VERSION_MAJOR, v(env!("CARGO_PKG_VERSION_MAJOR")));
        assert_eq!(HOCURVE_VERSION_MINOR, v(env!("CARGO_PKG_VERSION_MINOR")));
        assert_eq!(HOCURVE_VERSION_PATCH, v(env!("CARGO_PKG_VERSION_PATCH")));
    }

    #[test]
    fn the_header_defaults_are_the_library_defaults() {
        let o = CurveOptions::default();
        assert_eq!(HOC_DEFAULT_INCREMENTS as usize, o.increments);
        assert_eq!(HOC_DEFAULT_MAX_SPLITS as usize, o.max_splits);
        assert_eq!(HOC_DEFAULT_MAX_SPLITS as usize, DEFAULT_MAX_SPLITS);
        assert_eq!(HOC_DEFAULT_YOUNG, o.young);
        assert_eq!(HOC_DEFAULT_POISSON, o.poisson);
    }
}
