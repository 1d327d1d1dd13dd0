!> @file hocurve.f90
!> @brief Fortran 2003 bindings to the hocurve C ABI (hocurve.h).
!>
!> Compile this file with your program (module files are compiler specific);
!> with CMake, `find_package(hocurve)` sets hocurve_FORTRAN_MODULE_SOURCE to it.
!>
!> The interfaces are the C functions themselves, so:
!> - a mesh handle is a type(c_ptr); hoc_mesh_create(..., mesh) fills it and
!>   hoc_mesh_destroy(mesh) frees it and sets it to c_null_ptr;
!> - vertex, node and cell ids are 0-based integer(c_int64_t), as in C;
!> - coordinates are interleaved: coords(dim, n) in Fortran order is the C layout;
!> - counts are integer(c_size_t), passed by value;
!> - strings come back as type(c_ptr): use hoc_string(ptr) to get a Fortran string;
!> - a projector is a bind(C) function with the interface hoc_project_fn,
!>   passed as c_funloc(f); a progress callback has the interface hoc_progress_fn,
!>   a linear solver (hoc_mesh_set_linear_solver) the interface hoc_linear_solver_fn.
module hocurve
  use, intrinsic :: iso_c_binding
  implicit none
  private

  public :: c_ptr, c_funptr, c_null_ptr, c_null_funptr, c_funloc, c_loc, &
            c_int, c_int32_t, c_int64_t, c_size_t, c_double, c_char, c_null_char, c_associated, &
            c_f_pointer

  ! Version of the library these bindings are for (hoc_version gives the library's)
  integer(c_int), parameter, public :: HOCURVE_VERSION_MAJOR = 0
  integer(c_int), parameter, public :: HOCURVE_VERSION_MINOR = 4
  integer(c_int), parameter, public :: HOCURVE_VERSION_PATCH = 0
  ! Defaults shared by every interface
  integer(c_int), parameter, public :: HOC_DEFAULT_INCREMENTS = 10
  integer(c_int), parameter, public :: HOC_DEFAULT_MAX_SPLITS = 6
  real(c_double), parameter, public :: HOC_DEFAULT_YOUNG = 1.0e5_c_double
  real(c_double), parameter, public :: HOC_DEFAULT_POISSON = 0.45_c_double
  ! HocStatus
  integer(c_int), parameter, public :: HOC_OK = 0
  integer(c_int), parameter, public :: HOC_ERROR_NULL_POINTER = 1
  integer(c_int), parameter, public :: HOC_ERROR_INVALID_ARGUMENT = 2
  integer(c_int), parameter, public :: HOC_ERROR_INVALID_MESH = 3
  integer(c_int), parameter, public :: HOC_ERROR_PROJECTION = 4
  integer(c_int), parameter, public :: HOC_ERROR_SOLVER = 5
  integer(c_int), parameter, public :: HOC_ERROR_INVALID_ELEMENT = 6
  integer(c_int), parameter, public :: HOC_ERROR_IO = 7
  integer(c_int), parameter, public :: HOC_ERROR_CANCELLED = 8
  integer(c_int), parameter, public :: HOC_ERROR_BUFFER_SIZE = 9
  integer(c_int), parameter, public :: HOC_ERROR_PANIC = 10
  integer(c_int), parameter, public :: HOC_ERROR_BUSY = 11
  ! HocNodeSpacing
  integer(c_int), parameter, public :: HOC_SPACING_OPTIMAL = 0
  integer(c_int), parameter, public :: HOC_SPACING_EQUISPACED = 1
  ! HocMaterial
  integer(c_int), parameter, public :: HOC_MATERIAL_LINEAR_ELASTIC = 0
  integer(c_int), parameter, public :: HOC_MATERIAL_NEO_HOOKEAN = 1
  integer(c_int), parameter, public :: HOC_MATERIAL_MOONEY_RIVLIN = 2
  integer(c_int), parameter, public :: HOC_MATERIAL_NI_MOONEY_RIVLIN = 3
  integer(c_int), parameter, public :: HOC_MATERIAL_TRANSVERSELY_ISOTROPIC = 4
  integer(c_int), parameter, public :: HOC_MATERIAL_TRANSVERSELY_ISOTROPIC_LINEAR = 5
  ! HocFormulation
  integer(c_int), parameter, public :: HOC_FORMULATION_LINEAR = 0
  integer(c_int), parameter, public :: HOC_FORMULATION_ILE = 1
  integer(c_int), parameter, public :: HOC_FORMULATION_IIL = 2
  integer(c_int), parameter, public :: HOC_FORMULATION_CIL = 3
  integer(c_int), parameter, public :: HOC_FORMULATION_NONLINEAR = 4
  ! HocStepBackReason
  integer(c_int), parameter, public :: HOC_STEP_BACK_SAMPLED_INVALID = 0
  integer(c_int), parameter, public :: HOC_STEP_BACK_CERTIFIED_INVALID = 1
  integer(c_int), parameter, public :: HOC_STEP_BACK_NEWTON_FAILED = 2
  integer(c_int), parameter, public :: HOC_STEP_BACK_RESTARTED = 3
  ! HocSolvedBy
  integer(c_int), parameter, public :: HOC_SOLVED_BY_PCG = 0
  integer(c_int), parameter, public :: HOC_SOLVED_BY_PCG_RESTARTED = 1
  integer(c_int), parameter, public :: HOC_SOLVED_BY_DIRECT = 2
  integer(c_int), parameter, public :: HOC_SOLVED_BY_DIRECT_LU = 3
  integer(c_int), parameter, public :: HOC_SOLVED_BY_EXTERNAL = 4
  ! HocFallbackReason
  integer(c_int), parameter, public :: HOC_FALLBACK_NONE = 0
  integer(c_int), parameter, public :: HOC_FALLBACK_PRECONDITIONER_NOT_POSITIVE = 1
  integer(c_int), parameter, public :: HOC_FALLBACK_STAGNATION = 2
  integer(c_int), parameter, public :: HOC_FALLBACK_EIGENVALUE_UNDERESTIMATED = 3
  integer(c_int), parameter, public :: HOC_FALLBACK_NOT_CONVERGED = 4
  integer(c_int), parameter, public :: HOC_FALLBACK_NON_FINITE = 5
  integer(c_int), parameter, public :: HOC_FALLBACK_MATRIX_NOT_POSITIVE = 6
  integer(c_int), parameter, public :: HOC_FALLBACK_PRECONDITIONER_SETUP = 7
  integer(c_int), parameter, public :: HOC_FALLBACK_CHOLESKY_FAILED = 8
  ! HocNodeOrdering
  integer(c_int), parameter, public :: HOC_ORDERING_NATIVE = 0
  integer(c_int), parameter, public :: HOC_ORDERING_GMSH = 1
  integer(c_int), parameter, public :: HOC_ORDERING_VTK = 2
  ! Progress stages
  integer(c_int), parameter, public :: HOC_STAGE_ELEVATE = 0
  integer(c_int), parameter, public :: HOC_STAGE_PROJECT = 1
  integer(c_int), parameter, public :: HOC_STAGE_INCREMENT = 2
  integer(c_int), parameter, public :: HOC_STAGE_QUALITY = 3
  integer(c_int), parameter, public :: HOC_STAGE_OPTIMIZE = 4

  !> HocQuality: minima of Q1..Q5 over the cells, mean Q3, invalid and total cell counts,
  !> certified lower bound of Q3, certified-invalid and undecided cell counts, and the
  !> largest distance of a straight boundary node to its projection in the last run.
  type, bind(C), public :: hoc_quality
    real(c_double) :: min_q1, min_q2, min_q3, min_q4, min_q5, mean_q3
    integer(c_size_t) :: n_invalid
    integer(c_size_t) :: n_cells
    real(c_double) :: certified_min_q3
    integer(c_size_t) :: n_certified_invalid, n_uncertain
    real(c_double) :: max_projection_distance
  end type hoc_quality

  !> HocOptimization: what the optimisation stage of the last run did (see hocurve.h).
  type, bind(C), public :: hoc_optimization
    integer(c_int) :: ran, elastic_stopped
    real(c_double) :: elastic_load
    integer(c_int) :: elastic_restarted
    integer(c_size_t) :: target_cells, cells_touched, nodes_moved, patches, cells_split
    integer(c_size_t) :: invalid_before, invalid_after
    real(c_double) :: min_q3_before, min_q3_after, seconds
  end type hoc_optimization

  !> HocTimings: where the last run's time went, seconds per stage (see hocurve.h).
  type, bind(C), public :: hoc_timings
    real(c_double) :: total, repair_and_elevate, place_boundary, assembly, solver_setup
    real(c_double) :: solve, check, optimize, quality
  end type hoc_timings

  !> HocRepair: boundary caps removed; bad cells found by the last run (all, on one
  !> surface, bulging), flips by kind (2-3, 3-2, edge removal, 2D edge flip), surface
  !> caps removed, cells removed and added, bad cells left, interior edges split,
  !> surface edges flipped.
  type, bind(C), public :: hoc_repair
    integer(c_size_t) :: removed_caps
    integer(c_size_t) :: bad_cells, surface_cells, bulge_cells
    integer(c_size_t) :: flips_23, flips_32, edge_removals, flips_22, surface_caps
    integer(c_size_t) :: cells_removed, cells_added, bad_cells_left
    integer(c_size_t) :: edge_splits, surface_flips
  end type hoc_repair

  abstract interface
    !> HocProjectFn: project n_points points (n_points*dim coordinates) onto
    !> entity (entity_dim, entity_tag); return 0 on success.
    function hoc_project_fn(user_data, entity_dim, entity_tag, n_points, points, projected) &
        bind(C) result(status)
      import :: c_ptr, c_int, c_size_t, c_double
      type(c_ptr), value :: user_data
      integer(c_int), value :: entity_dim, entity_tag
      integer(c_size_t), value :: n_points
      real(c_double), intent(in) :: points(*)
      real(c_double), intent(out) :: projected(*)
      integer(c_int) :: status
    end function hoc_project_fn

    !> HocProgressFn: return 0 to continue, nonzero to cancel.
    function hoc_progress_fn(user_data, stage, step, total) bind(C) result(status)
      import :: c_ptr, c_int
      type(c_ptr), value :: user_data
      integer(c_int), value :: stage, step, total
      integer(c_int) :: status
    end function hoc_progress_fn

    !> HocLinearSolverFn: solve A x = b, A the n x n reduced symmetric matrix in full CSR form
    !> (both triangles, 0-based row_ptr(n+1) and col_idx(row_ptr(n+1)), sorted columns,
    !> values alongside); x holds the initial guess on entry and the solution on return.
    !> The arrays are valid only during the call. Return 0 on success.
    function hoc_linear_solver_fn(user_data, n, row_ptr, col_idx, values, rhs, x) &
        bind(C) result(status)
      import :: c_ptr, c_int, c_int64_t, c_double
      type(c_ptr), value :: user_data
      integer(c_int64_t), value :: n
      integer(c_int64_t), intent(in) :: row_ptr(*), col_idx(*)
      real(c_double), intent(in) :: values(*), rhs(*)
      real(c_double), intent(inout) :: x(*)
      integer(c_int) :: status
    end function hoc_linear_solver_fn
  end interface
  public :: hoc_project_fn, hoc_progress_fn, hoc_linear_solver_fn

  interface
    function hoc_mesh_create(dim, n_vertices, coords, n_cells, cells, mesh) &
        bind(C, name="hoc_mesh_create") result(status)
      import :: c_int, c_size_t, c_double, c_int64_t, c_ptr
      integer(c_int), value :: dim
      integer(c_size_t), value :: n_vertices
      real(c_double), intent(in) :: coords(*)
      integer(c_size_t), value :: n_cells
      integer(c_int64_t), intent(in) :: cells(*)
      type(c_ptr), intent(out) :: mesh
      integer(c_int) :: status
    end function hoc_mesh_create

    ! This process's share of a mesh spread over the MPI communicator comm
    ! (the integer handle of `use mpi`; comm%MPI_VAL with mpi_f08). Collective;
    ! needs a library built with MPI and MPI_Init_thread at MPI_THREAD_SERIALIZED or above.
    function hoc_mesh_create_distributed(comm, dim, n_vertices, coords, global_ids, n_cells, cells, mesh) &
        bind(C, name="hoc_mesh_create_distributed") result(status)
      import :: c_int, c_size_t, c_double, c_int64_t, c_ptr
      integer(c_int), value :: comm, dim
      integer(c_size_t), value :: n_vertices
      real(c_double), intent(in) :: coords(*)
      integer(c_int64_t), intent(in) :: global_ids(*)
      integer(c_size_t), value :: n_cells
      integer(c_int64_t), intent(in) :: cells(*)
      type(c_ptr), intent(out) :: mesh
      integer(c_int) :: status
    end function hoc_mesh_create_distributed

    function hoc_mesh_destroy(mesh) bind(C, name="hoc_mesh_destroy") result(status)
      import :: c_int, c_ptr
      type(c_ptr), intent(inout) :: mesh
      integer(c_int) :: status
    end function hoc_mesh_destroy

    function hoc_mesh_set_boundary(mesh, n_facets, facets, entity_tags) &
        bind(C, name="hoc_mesh_set_boundary") result(status)
      import :: c_int, c_size_t, c_int64_t, c_int32_t, c_ptr
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_facets
      integer(c_int64_t), intent(in) :: facets(*)
      integer(c_int32_t), intent(in) :: entity_tags(*)
      integer(c_int) :: status
    end function hoc_mesh_set_boundary

    function hoc_mesh_set_feature_edges(mesh, n_edges, edges, curve_tags) &
        bind(C, name="hoc_mesh_set_feature_edges") result(status)
      import :: c_int, c_size_t, c_int64_t, c_int32_t, c_ptr
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_edges
      integer(c_int64_t), intent(in) :: edges(*)
      integer(c_int32_t), intent(in) :: curve_tags(*)
      integer(c_int) :: status
    end function hoc_mesh_set_feature_edges

    !> Hold the facets (entity_dim = dim - 1) or 3D feature edges (entity_dim = 1) with
    !> these tags straight; replaces the earlier list for entity_dim (n_tags = 0: none).
    function hoc_mesh_set_straight_tags(mesh, entity_dim, n_tags, tags) &
        bind(C, name="hoc_mesh_set_straight_tags") result(status)
      import :: c_int, c_size_t, c_int32_t, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: entity_dim
      integer(c_size_t), value :: n_tags
      integer(c_int32_t), intent(in) :: tags(*)
      integer(c_int) :: status
    end function hoc_mesh_set_straight_tags

    !> fn: c_funloc of a bind(C) function with interface hoc_project_fn (or c_null_funptr).
    function hoc_mesh_set_projector(mesh, fn, user_data) &
        bind(C, name="hoc_mesh_set_projector") result(status)
      import :: c_int, c_ptr, c_funptr
      type(c_ptr), value :: mesh
      type(c_funptr), value :: fn
      type(c_ptr), value :: user_data
      integer(c_int) :: status
    end function hoc_mesh_set_projector

    !> fn: c_funloc of a bind(C) function with interface hoc_progress_fn (or c_null_funptr).
    function hoc_mesh_set_progress(mesh, fn, user_data) &
        bind(C, name="hoc_mesh_set_progress") result(status)
      import :: c_int, c_ptr, c_funptr
      type(c_ptr), value :: mesh
      type(c_funptr), value :: fn
      type(c_ptr), value :: user_data
      integer(c_int) :: status
    end function hoc_mesh_set_progress

    !> fn: c_funloc of a bind(C) function with interface hoc_linear_solver_fn, or
    !> c_null_funptr to restore the built-in solvers.
    function hoc_mesh_set_linear_solver(mesh, fn, user_data) &
        bind(C, name="hoc_mesh_set_linear_solver") result(status)
      import :: c_int, c_ptr, c_funptr
      type(c_ptr), value :: mesh
      type(c_funptr), value :: fn
      type(c_ptr), value :: user_data
      integer(c_int) :: status
    end function hoc_mesh_set_linear_solver

    function hoc_mesh_set_threads(mesh, n_threads) bind(C, name="hoc_mesh_set_threads") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: n_threads
      integer(c_int) :: status
    end function hoc_mesh_set_threads

    function hoc_mesh_set_remove_caps(mesh, remove) bind(C, name="hoc_mesh_set_remove_caps") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: remove
      integer(c_int) :: status
    end function hoc_mesh_set_remove_caps

    function hoc_mesh_set_retry(mesh, enabled) bind(C, name="hoc_mesh_set_retry") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: enabled
      integer(c_int) :: status
    end function hoc_mesh_set_retry

    !> caps_kept: 1 if the last run was made again with the caps kept;
    !> message_len: the first run's error message's length; message (len
    !> bytes) gets that message, NUL-terminated. caps_kept 0 with a message:
    !> the caps-kept run ended invalid too, and the mesh is the first run's
    !> made again with every optimisation round; the message is its error.
    function hoc_mesh_retry(mesh, caps_kept, message_len, len, message) bind(C, name="hoc_mesh_retry") &
        result(status)
      import :: c_int, c_ptr, c_size_t, c_char
      type(c_ptr), value :: mesh
      integer(c_int), intent(out) :: caps_kept
      integer(c_size_t), intent(out) :: message_len
      integer(c_size_t), value :: len
      character(kind=c_char), intent(out) :: message(*)
      integer(c_int) :: status
    end function hoc_mesh_retry

    function hoc_mesh_set_repair(mesh, enabled) bind(C, name="hoc_mesh_set_repair") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: enabled
      integer(c_int) :: status
    end function hoc_mesh_set_repair

    function hoc_mesh_get_input_cells(mesh, n_cells, input_cells) &
        bind(C, name="hoc_mesh_get_input_cells") result(status)
      import :: c_int, c_ptr, c_size_t, c_int64_t
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_cells
      integer(c_int64_t) :: input_cells(*)
      integer(c_int) :: status
    end function hoc_mesh_get_input_cells

    function hoc_mesh_get_global_nodes(mesh, n_nodes, global_ids, owners) &
        bind(C, name="hoc_mesh_get_global_nodes") result(status)
      import :: c_int, c_ptr, c_size_t, c_int64_t
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_nodes
      integer(c_int64_t) :: global_ids(*)
      integer(c_int) :: owners(*)
      integer(c_int) :: status
    end function hoc_mesh_get_global_nodes

    function hoc_mesh_set_order(mesh, order, spacing) bind(C, name="hoc_mesh_set_order") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: order, spacing
      integer(c_int) :: status
    end function hoc_mesh_set_order

    function hoc_mesh_set_material(mesh, model, young, poisson) &
        bind(C, name="hoc_mesh_set_material") result(status)
      import :: c_int, c_ptr, c_double
      type(c_ptr), value :: mesh
      integer(c_int), value :: model
      real(c_double), value :: young, poisson
      integer(c_int) :: status
    end function hoc_mesh_set_material

    function hoc_mesh_set_formulation(mesh, formulation) &
        bind(C, name="hoc_mesh_set_formulation") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: formulation
      integer(c_int) :: status
    end function hoc_mesh_set_formulation

    function hoc_mesh_set_newton(mesh, tolerance, max_iterations) &
        bind(C, name="hoc_mesh_set_newton") result(status)
      import :: c_int, c_ptr, c_double
      type(c_ptr), value :: mesh
      real(c_double), value :: tolerance
      integer(c_int), value :: max_iterations
      integer(c_int) :: status
    end function hoc_mesh_set_newton

    !> fibres: 3 * n_cells doubles, or c_null_ptr for the default
    function hoc_mesh_set_fibres(mesh, n_cells, fibres) &
        bind(C, name="hoc_mesh_set_fibres") result(status)
      import :: c_int, c_ptr, c_size_t
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_cells
      type(c_ptr), value :: fibres
      integer(c_int) :: status
    end function hoc_mesh_set_fibres

    !> enabled: 1 on, 0 off, -1 the default (on unless HOC_FORMULATION_LINEAR); max_splits 0..30
    function hoc_mesh_set_adaptive_stepping(mesh, enabled, max_splits) &
        bind(C, name="hoc_mesh_set_adaptive_stepping") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: enabled, max_splits
      integer(c_int) :: status
    end function hoc_mesh_set_adaptive_stepping

    function hoc_mesh_set_static_condensation(mesh, enabled) &
        bind(C, name="hoc_mesh_set_static_condensation") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: enabled
      integer(c_int) :: status
    end function hoc_mesh_set_static_condensation

    !> enabled: 1 on (default), 0 off
    function hoc_mesh_set_optimize(mesh, enabled) bind(C, name="hoc_mesh_set_optimize") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: enabled
      integer(c_int) :: status
    end function hoc_mesh_set_optimize

    !> enabled: 1 on, 0 off (default); for a slow projector
    function hoc_mesh_set_tangent_first(mesh, enabled) bind(C, name="hoc_mesh_set_tangent_first") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: enabled
      integer(c_int) :: status
    end function hoc_mesh_set_tangent_first

    function hoc_mesh_optimization(mesh, out) bind(C, name="hoc_mesh_optimization") result(status)
      import :: c_int, c_ptr, hoc_optimization
      type(c_ptr), value :: mesh
      type(hoc_optimization), intent(out) :: out
      integer(c_int) :: status
    end function hoc_mesh_optimization

    function hoc_mesh_timings(mesh, out) bind(C, name="hoc_mesh_timings") result(status)
      import :: c_int, c_ptr, hoc_timings
      type(c_ptr), value :: mesh
      type(hoc_timings), intent(out) :: out
      integer(c_int) :: status
    end function hoc_mesh_timings

    function hoc_mesh_increment_count(mesh, n_taken, n_step_backs) &
        bind(C, name="hoc_mesh_increment_count") result(status)
      import :: c_int, c_ptr, c_size_t
      type(c_ptr), value :: mesh
      integer(c_size_t), intent(out) :: n_taken, n_step_backs
      integer(c_int) :: status
    end function hoc_mesh_increment_count

    function hoc_mesh_get_load_fractions(mesh, n_taken, fractions) &
        bind(C, name="hoc_mesh_get_load_fractions") result(status)
      import :: c_int, c_ptr, c_size_t, c_double
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_taken
      real(c_double), intent(out) :: fractions(*)
      integer(c_int) :: status
    end function hoc_mesh_get_load_fractions

    !> loads, steps, reasons (HOC_STEP_BACK_*), cells: n_step_backs each, or c_null_ptr
    function hoc_mesh_get_step_backs(mesh, n_step_backs, loads, steps, reasons, cells) &
        bind(C, name="hoc_mesh_get_step_backs") result(status)
      import :: c_int, c_ptr, c_size_t
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_step_backs
      type(c_ptr), value :: loads, steps, reasons, cells
      integer(c_int) :: status
    end function hoc_mesh_get_step_backs

    function hoc_mesh_solve_count(mesh, n_solves, n_fallbacks) &
        bind(C, name="hoc_mesh_solve_count") result(status)
      import :: c_int, c_ptr, c_size_t
      type(c_ptr), value :: mesh
      integer(c_size_t), intent(out) :: n_solves, n_fallbacks
      integer(c_int) :: status
    end function hoc_mesh_solve_count

    !> solved_by (HOC_SOLVED_BY_*), fallbacks (HOC_FALLBACK_*), iterations (size_t):
    !> n_solves each, or c_null_ptr
    function hoc_mesh_get_solves(mesh, n_solves, solved_by, fallbacks, iterations) &
        bind(C, name="hoc_mesh_get_solves") result(status)
      import :: c_int, c_ptr, c_size_t
      type(c_ptr), value :: mesh
      integer(c_size_t), value :: n_solves
      type(c_ptr), value :: solved_by, fallbacks, iterations
      integer(c_int) :: status
    end function hoc_mesh_get_solves

    function hoc_mesh_run_increments(mesh, increments) &
        bind(C, name="hoc_mesh_run_increments") result(status)
      import :: c_int, c_ptr
      type(c_ptr), value :: mesh
      integer(c_int), value :: increments
      integer(c_int) :: status
    end function hoc_mesh_run_increments

    function hoc_mesh_quality(mesh, quality) bind(C, name="hoc_mesh_quality") result(status)
      import :: c_int, c_ptr, hoc_quality
      type(c_ptr), value :: mesh
      type(hoc_quality), intent(out) :: quality
      integer(c_int) :: status
    end function hoc_mesh_quality

    function hoc_mesh_repair_summary(mesh, repair) bind(C, name="hoc_mesh_repair_summary") result(status)
      import :: c_int, c_ptr, hoc_repair
      type(c_ptr), value :: mesh
      type(hoc_repair), intent(out) :: repair
      integer(c_int) :: status
    end function hoc_mesh_repair_summary

    function hoc_mesh_cell_quality(mesh, measure, n, values) &
        bind(C, name="hoc_mesh_cell_quality") result(status)
      import :: c_int, c_ptr, c_size_t, c_double
      type(c_ptr), value :: mesh
      integer(c_int), value :: measure
      integer(c_size_t), value :: n
      real(c_double), intent(out) :: values(*)
      integer(c_int) :: status
    end function hoc_mesh_cell_quality

    function hoc_mesh_node_count(mesh, n_nodes) bind(C, name="hoc_mesh_node_count") result(status)
      import :: c_int, c_ptr, c_size_t
      type(c_ptr), value :: mesh
      integer(c_size_t), intent(out) :: n_nodes
      integer(c_int) :: status
    end function hoc_mesh_node_count

    function hoc_mesh_cell_count(mesh, n_cells, nodes_per_cell) &
        bind(C, name="hoc_mesh_cell_count") result(status)
      import :: c_int, c_ptr, c_size_t
      type(c_ptr), value :: mesh
      integer(c_size_t), intent(out) :: n_cells, nodes_per_cell
      integer(c_int) :: status
    end function hoc_mesh_cell_count

    !> ordering: that of the connectivity used with the nodes (HOC_ORDERING_GMSH and _VTK
    !> mean equispaced node positions, HOC_ORDERING_NATIVE the mesh's own).
    function hoc_mesh_get_nodes(mesh, ordering, n_nodes, coords) bind(C, name="hoc_mesh_get_nodes") &
        result(status)
      import :: c_int, c_ptr, c_size_t, c_double
      type(c_ptr), value :: mesh
      integer(c_int), value :: ordering
      integer(c_size_t), value :: n_nodes
      real(c_double), intent(out) :: coords(*)
      integer(c_int) :: status
    end function hoc_mesh_get_nodes

    function hoc_mesh_get_cells(mesh, ordering, len, cells) bind(C, name="hoc_mesh_get_cells") result(status)
      import :: c_int, c_ptr, c_size_t, c_int64_t
      type(c_ptr), value :: mesh
      integer(c_int), value :: ordering
      integer(c_size_t), value :: len
      integer(c_int64_t), intent(out) :: cells(*)
      integer(c_int) :: status
    end function hoc_mesh_get_cells

    !> path: a NUL-terminated string, e.g. "out.msh"//c_null_char.
    function hoc_mesh_write(mesh, path) bind(C, name="hoc_mesh_write") result(status)
      import :: c_int, c_ptr, c_char
      type(c_ptr), value :: mesh
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function hoc_mesh_write

    function hoc_mesh_last_error(mesh) bind(C, name="hoc_mesh_last_error") result(message)
      import :: c_ptr
      type(c_ptr), value :: mesh
      type(c_ptr) :: message
    end function hoc_mesh_last_error

    function hoc_status_string(status) bind(C, name="hoc_status_string") result(message)
      import :: c_ptr, c_int
      integer(c_int), value :: status
      type(c_ptr) :: message
    end function hoc_status_string

    function hoc_solved_by_string(solved_by) bind(C, name="hoc_solved_by_string") result(name)
      import :: c_ptr, c_int
      integer(c_int), value :: solved_by
      type(c_ptr) :: name
    end function hoc_solved_by_string

    function hoc_fallback_reason_string(reason) bind(C, name="hoc_fallback_reason_string") result(name)
      import :: c_ptr, c_int
      integer(c_int), value :: reason
      type(c_ptr) :: name
    end function hoc_fallback_reason_string

    function hoc_version() bind(C, name="hoc_version") result(version)
      import :: c_ptr
      type(c_ptr) :: version
    end function hoc_version

    function hoc_c_strlen(s) bind(C, name="strlen") result(n)
      import :: c_ptr, c_size_t
      type(c_ptr), value :: s
      integer(c_size_t) :: n
    end function hoc_c_strlen
  end interface

  public :: hoc_mesh_create, hoc_mesh_create_distributed, hoc_mesh_destroy, &
            hoc_mesh_set_boundary, hoc_mesh_set_feature_edges, &
            hoc_mesh_set_projector, hoc_mesh_set_progress, hoc_mesh_set_linear_solver, &
            hoc_mesh_set_threads, hoc_mesh_set_remove_caps, hoc_mesh_set_retry, hoc_mesh_retry, &
            hoc_mesh_set_repair, hoc_mesh_get_input_cells, hoc_mesh_get_global_nodes, &
            hoc_mesh_set_order, hoc_mesh_repair_summary, &
            hoc_mesh_set_material, hoc_mesh_set_formulation, hoc_mesh_set_newton, hoc_mesh_set_fibres, &
            hoc_mesh_set_adaptive_stepping, hoc_mesh_set_static_condensation, hoc_mesh_run_increments, &
            hoc_mesh_set_optimize, hoc_mesh_set_tangent_first, hoc_mesh_optimization, hoc_mesh_timings, &
            hoc_mesh_increment_count, &
            hoc_mesh_get_load_fractions, hoc_mesh_get_step_backs, hoc_mesh_solve_count, hoc_mesh_get_solves, &
            hoc_mesh_quality, hoc_mesh_cell_quality, hoc_mesh_node_count, hoc_mesh_cell_count, &
            hoc_mesh_get_nodes, hoc_mesh_get_cells, hoc_mesh_write, hoc_mesh_last_error, &
            hoc_status_string, hoc_solved_by_string, hoc_fallback_reason_string, hoc_version, hoc_string

contains

  !> A C string (NUL-terminated, e.g. from hoc_mesh_last_error) as a Fortran string; "" for NULL.
  function hoc_string(cstr) result(str)
    type(c_ptr), intent(in) :: cstr
    character(len=:), allocatable :: str
    character(kind=c_char), pointer :: chars(:)
    integer(c_size_t) :: n, i
    if (.not. c_associated(cstr)) then
      str = ""
      return
    end if
    n = hoc_c_strlen(cstr)
    call c_f_pointer(cstr, chars, [n])
    allocate (character(len=n) :: str)
    do i = 1, n
      str(i:i) = chars(i)
    end do
  end function hoc_string

end module hocurve
