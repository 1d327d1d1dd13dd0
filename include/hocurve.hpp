/**
 * @file hocurve.hpp
 * @brief Header-only C++17 wrapper over the hocurve C ABI (hocurve.h).
 *
 * - hocurve::Mesh owns one HocMesh* (move-only, destroyed in the destructor).
 * - Every method mirrors one hoc_mesh_* function and throws hocurve::Error
 *   (a std::runtime_error carrying the HocStatus and the handle's last-error
 *   message) when the status is not HOC_OK.
 * - The projector, progress and linear-solver callbacks are std::function objects; the mesh
 *   keeps them alive at a stable address and hands that address to the C ABI
 *   as user_data. An exception thrown by a callback never crosses into the
 *   library: it stops the run, and run_increments() rethrows it.
 *
 * @code
 *   hocurve::Mesh mesh(3, coords, cells);          // coords: n*3, cells: m*4
 *   mesh.set_boundary(facets, tags);
 *   mesh.set_projector([](int dim, int tag, std::size_t n, const double *in, double *out) {
 *     ...; return 0;
 *   });
 *   mesh.set_order(4);
 *   mesh.run_increments(1);
 *   HocQuality q = mesh.quality();
 * @endcode
 */
#ifndef HOCURVE_HPP
#define HOCURVE_HPP

#include "hocurve.h"

#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hocurve {

/** A failed hocurve call: the status and the library's message. */
class Error : public std::runtime_error {
 public:
  Error(HocStatus status, const std::string &message)
      : std::runtime_error(compose(status, message)), status_(status), message_(message) {}
  /** The HocStatus the C function returned. */
  HocStatus status() const noexcept { return status_; }
  /** The handle's last-error message at the time of the failure (may be empty). */
  const std::string &message() const noexcept { return message_; }

 private:
  static std::string compose(HocStatus status, const std::string &message) {
    const char *s = hoc_status_string(status);
    std::string what = s ? s : "unknown status";
    if (!message.empty()) what += ": " + message;
    return what;
  }
  HocStatus status_;
  std::string message_;
};

/** Projects n points (n*dim coordinates) onto entity (dim, tag); 0 = success. */
using Projector =
    std::function<int(int entity_dim, int entity_tag, std::size_t n, const double *in, double *out)>;
/** Called during a run; return 0 to continue, nonzero to cancel. */
using Progress = std::function<int(int stage, int step, int total)>;
/** Solves A x = b, A the n x n reduced symmetric matrix in full CSR form (both triangles,
 *  0-based, sorted columns); x holds the initial guess on entry. 0 = success. See
 *  HocLinearSolverFn in hocurve.h. */
using LinearSolver = std::function<int(int64_t n, const int64_t *row_ptr, const int64_t *col_idx,
                                       const double *values, const double *rhs, double *x)>;

/** The library's version string. */
inline std::string version() { return hoc_version(); }

/** Throws Error(status, message) unless status is HOC_OK. */
inline void check(HocStatus status, const HocMesh *mesh) {
  if (status == HOC_OK) return;
  // With no handle, hoc_mesh_last_error(NULL) gives this thread's last handle-less failure.
  const char *msg = hoc_mesh_last_error(mesh);
  throw Error(status, msg ? msg : "");
}

namespace detail {
// Callback state lives behind a unique_ptr so its address survives moves of Mesh.
struct Callbacks {
  Projector projector;
  Progress progress;
  LinearSolver linear_solver;
  std::exception_ptr pending;  // first exception a callback threw during a run

  static int project(void *user, int dim, int tag, std::size_t n, const double *in, double *out) {
    auto *self = static_cast<Callbacks *>(user);
    try {
      return self->projector(dim, tag, n, in, out);
    } catch (...) {
      if (!self->pending) self->pending = std::current_exception();
      return -1;
    }
  }
  static int progress_cb(void *user, int stage, int step, int total) {
    auto *self = static_cast<Callbacks *>(user);
    try {
      return self->progress(stage, step, total);
    } catch (...) {
      if (!self->pending) self->pending = std::current_exception();
      return 1;
    }
  }
  static int solve(void *user, int64_t n, const int64_t *row_ptr, const int64_t *col_idx,
                   const double *values, const double *rhs, double *x) {
    auto *self = static_cast<Callbacks *>(user);
    try {
      return self->linear_solver(n, row_ptr, col_idx, values, rhs, x);
    } catch (...) {
      if (!self->pending) self->pending = std::current_exception();
      return -1;
    }
  }
};
}  // namespace detail

/** A mesh handle: the linear mesh, its settings, and after a run, the curved mesh. */
class Mesh {
 public:
  /** Wraps hoc_mesh_create: n_vertices*dim coordinates, n_cells*(dim+1) vertex ids. */
  Mesh(int dim, std::size_t n_vertices, const double *coords, std::size_t n_cells,
       const int64_t *cells)
      : dim_(dim), callbacks_(new detail::Callbacks) {
    HocMesh *out = nullptr;
    HocStatus st = hoc_mesh_create(dim, n_vertices, coords, n_cells, cells, &out);
    if (st != HOC_OK) {
      // The message of a failed create is kept per thread: hoc_mesh_last_error(NULL).
      const char *msg = hoc_mesh_last_error(out);
      std::string m = msg ? msg : "";
      hoc_mesh_destroy(&out);
      throw Error(st, m);
    }
    mesh_ = out;
  }
  /** Same, from vectors; the counts follow from the sizes, which must be
   *  multiples of dim and dim + 1 (else Error with HOC_ERROR_INVALID_ARGUMENT). */
  Mesh(int dim, const std::vector<double> &coords, const std::vector<int64_t> &cells)
      : Mesh(dim, count(coords.size(), dim, "coords"), coords.data(), count(cells.size(), dim + 1, "cells"),
             cells.data()) {}

  /** Wraps hoc_mesh_create_distributed (collective over the communicator, given as
   *  MPI_Comm_c2f(comm)): this MPI process's share of a mesh, its vertices with their
   *  global ids. Needs a library built with MPI; throws Error like the constructor. */
  static Mesh distributed(int comm, int dim, const std::vector<double> &coords,
                          const std::vector<int64_t> &global_ids, const std::vector<int64_t> &cells) {
    std::size_t n_vertices = count(coords.size(), dim, "coords");
    if (global_ids.size() != n_vertices)
      throw Error(HOC_ERROR_INVALID_ARGUMENT, std::to_string(global_ids.size()) + " global ids for " +
                                                  std::to_string(n_vertices) + " vertices");
    HocMesh *out = nullptr;
    HocStatus st = hoc_mesh_create_distributed(comm, dim, n_vertices, coords.data(), global_ids.data(),
                                               count(cells.size(), dim + 1, "cells"), cells.data(), &out);
    if (st != HOC_OK) {
      const char *msg = hoc_mesh_last_error(out);
      throw Error(st, msg ? msg : "");
    }
    return Mesh(out, dim);
  }

  ~Mesh() { hoc_mesh_destroy(&mesh_); }
  Mesh(const Mesh &) = delete;
  Mesh &operator=(const Mesh &) = delete;
  Mesh(Mesh &&other) noexcept
      : mesh_(std::exchange(other.mesh_, nullptr)),
        dim_(other.dim_),
        callbacks_(std::move(other.callbacks_)) {}
  Mesh &operator=(Mesh &&other) noexcept {
    if (this != &other) {
      hoc_mesh_destroy(&mesh_);
      mesh_ = std::exchange(other.mesh_, nullptr);
      dim_ = other.dim_;
      callbacks_ = std::move(other.callbacks_);
    }
    return *this;
  }

  /** The C handle (still owned by this object). */
  HocMesh *get() const noexcept { return mesh_; }
  /** Spatial dimension (2 or 3). */
  int dim() const noexcept { return dim_; }
  /** The handle's last-error message ("" if none). */
  std::string last_error() const {
    const char *m = hoc_mesh_last_error(mesh_);
    return m ? m : "";
  }

  void set_boundary(std::size_t n_facets, const int64_t *facets, const int32_t *tags) {
    check(hoc_mesh_set_boundary(mesh_, n_facets, facets, tags), mesh_);
  }
  /** facets: n*dim vertex ids, tags: n entity tags. */
  void set_boundary(const std::vector<int64_t> &facets, const std::vector<int32_t> &tags) {
    same_count(facets.size(), tags.size(), dim_, "facets", "tags");
    set_boundary(tags.size(), facets.data(), tags.data());
  }
  void set_feature_edges(std::size_t n_edges, const int64_t *edges, const int32_t *tags) {
    check(hoc_mesh_set_feature_edges(mesh_, n_edges, edges, tags), mesh_);
  }
  /** edges: n*2 vertex ids, tags: n curve tags (3D). */
  void set_feature_edges(const std::vector<int64_t> &edges, const std::vector<int32_t> &tags) {
    same_count(edges.size(), tags.size(), 2, "edges", "tags");
    set_feature_edges(tags.size(), edges.data(), tags.data());
  }
  /** Holds the facets (entity_dim = dim - 1) or 3D feature edges (entity_dim = 1) with these
   *  tags straight; replaces the earlier list for entity_dim (empty: curve them all). */
  void set_straight_tags(int entity_dim, const std::vector<int32_t> &tags) {
    check(hoc_mesh_set_straight_tags(mesh_, entity_dim, tags.size(), tags.data()), mesh_);
  }
  /** Sets (or, with an empty function, clears) the projector. */
  void set_projector(Projector fn) {
    ensure_callbacks();
    callbacks_->projector = std::move(fn);
    if (callbacks_->projector)
      check(hoc_mesh_set_projector(mesh_, &detail::Callbacks::project, callbacks_.get()), mesh_);
    else
      check(hoc_mesh_set_projector(mesh_, nullptr, nullptr), mesh_);
  }
  /** Sets (or, with an empty function, clears) the progress callback. */
  void set_progress(Progress fn) {
    ensure_callbacks();
    callbacks_->progress = std::move(fn);
    if (callbacks_->progress)
      check(hoc_mesh_set_progress(mesh_, &detail::Callbacks::progress_cb, callbacks_.get()), mesh_);
    else
      check(hoc_mesh_set_progress(mesh_, nullptr, nullptr), mesh_);
  }
  /** Sets (or, with an empty function, clears: back to the built-in solvers) the host's
   *  linear solver for every system of a run. */
  void set_linear_solver(LinearSolver fn) {
    ensure_callbacks();
    callbacks_->linear_solver = std::move(fn);
    if (callbacks_->linear_solver)
      check(hoc_mesh_set_linear_solver(mesh_, &detail::Callbacks::solve, callbacks_.get()), mesh_);
    else
      check(hoc_mesh_set_linear_solver(mesh_, nullptr, nullptr), mesh_);
  }
  /** 0 = all cores. */
  void set_threads(int n_threads) { check(hoc_mesh_set_threads(mesh_, n_threads), mesh_); }
  /** Remove boundary caps before curving (default true). */
  void set_remove_caps(bool remove) { check(hoc_mesh_set_remove_caps(mesh_, remove ? 1 : 0), mesh_); }
  /** Run again with the caps kept when a run that removed caps ends with an invalid cell (default on). */
  void set_retry(bool enabled) { check(hoc_mesh_set_retry(mesh_, enabled ? 1 : 0), mesh_); }
  /** Repair the linear mesh at each run: flip away cells that cannot stay valid once curved (default true). */
  void set_repair(bool enabled) { check(hoc_mesh_set_repair(mesh_, enabled ? 1 : 0), mesh_); }
  void set_order(int order, HocNodeSpacing spacing = HOC_SPACING_OPTIMAL) {
    check(hoc_mesh_set_order(mesh_, order, spacing), mesh_);
  }
  void set_material(HocMaterial model, double young, double poisson) {
    check(hoc_mesh_set_material(mesh_, model, young, poisson), mesh_);
  }
  void set_formulation(HocFormulation formulation) {
    check(hoc_mesh_set_formulation(mesh_, formulation), mesh_);
  }
  /** Adaptive load stepping: enabled 1 on, 0 off, -1 the default for the formulation; max_splits 0..30. */
  void set_adaptive_stepping(int enabled, int max_splits = HOC_DEFAULT_MAX_SPLITS) {
    check(hoc_mesh_set_adaptive_stepping(mesh_, enabled, max_splits), mesh_);
  }
  /** Static condensation of the cell-interior nodes: 1 on (default), 0 off. */
  void set_static_condensation(int enabled) { check(hoc_mesh_set_static_condensation(mesh_, enabled), mesh_); }
  /** The optimisation stage after the elastic solve: true on (default), false off. */
  void set_optimize(bool enabled) { check(hoc_mesh_set_optimize(mesh_, enabled ? 1 : 0), mesh_); }
  void set_tangent_first(bool enabled) { check(hoc_mesh_set_tangent_first(mesh_, enabled ? 1 : 0), mesh_); }
  /** Newton–Raphson settings of HOC_FORMULATION_NONLINEAR: tolerance > 0, max_iterations ≥ 1. */
  void set_newton(double tolerance, int max_iterations) {
    check(hoc_mesh_set_newton(mesh_, tolerance, max_iterations), mesh_);
  }
  /** One fibre direction (3 doubles) per cell; n_cells must equal the cell count. */
  void set_fibres(std::size_t n_cells, const double *fibres) {
    check(hoc_mesh_set_fibres(mesh_, n_cells, fibres), mesh_);
  }
  /** From a vector of 3 * n_cells doubles. */
  void set_fibres(const std::vector<double> &fibres) {
    set_fibres(count(fibres.size(), 3, "fibres"), fibres.data());
  }
  /** Back to the default fibres. */
  void reset_fibres() { check(hoc_mesh_set_fibres(mesh_, 0, nullptr), mesh_); }
  /** Curves the mesh. On failure the mesh is as before, and a callback's exception is rethrown. */
  void run_increments(int increments = HOC_DEFAULT_INCREMENTS) {
    if (callbacks_) callbacks_->pending = nullptr;
    HocStatus st = hoc_mesh_run_increments(mesh_, increments);
    if (st != HOC_OK && callbacks_ && callbacks_->pending) {
      std::exception_ptr e = std::exchange(callbacks_->pending, nullptr);
      std::rethrow_exception(e);
    }
    check(st, mesh_);
  }

  HocQuality quality() const {
    HocQuality q{};
    check(hoc_mesh_quality(mesh_, &q), mesh_);
    return q;
  }
  /** What the optimisation stage of the last run did. */
  HocOptimization optimization() const {
    HocOptimization o{};
    check(hoc_mesh_optimization(mesh_, &o), mesh_);
    return o;
  }
  /** Where the last run's time went, seconds per stage. */
  HocTimings timings() const {
    HocTimings t{};
    check(hoc_mesh_timings(mesh_, &t), mesh_);
    return t;
  }
  /** When the last run was made again with the caps kept: the error that ended its first run. */
  std::optional<std::string> caps_kept_after() const {
    int kept = 0;
    std::size_t len = 0;
    check(hoc_mesh_retry(mesh_, &kept, &len, 0, nullptr), mesh_);
    if (!kept) return std::nullopt;
    std::string message(len + 1, '\0');
    check(hoc_mesh_retry(mesh_, &kept, &len, message.size(), message.data()), mesh_);
    message.resize(len);
    return message;
  }
  /** Boundary caps removed and the last run's repair flips. */
  HocRepair repair_summary() const {
    HocRepair r{};
    check(hoc_mesh_repair_summary(mesh_, &r), mesh_);
    return r;
  }
  /** Per-cell quality, measure 1..3. */
  std::vector<double> cell_quality(int measure) const {
    std::vector<double> q(cell_count().first);
    check(hoc_mesh_cell_quality(mesh_, measure, q.size(), q.data()), mesh_);
    return q;
  }
  std::size_t node_count() const {
    std::size_t n = 0;
    check(hoc_mesh_node_count(mesh_, &n), mesh_);
    return n;
  }
  /** (number of cells, nodes per cell). */
  std::pair<std::size_t, std::size_t> cell_count() const {
    std::size_t n = 0, per = 0;
    check(hoc_mesh_cell_count(mesh_, &n, &per), mesh_);
    return {n, per};
  }
  /** Load fraction reached by each accepted increment of the last run (the last is 1). */
  std::vector<double> load_fractions() const {
    std::size_t taken = 0, backs = 0;
    check(hoc_mesh_increment_count(mesh_, &taken, &backs), mesh_);
    std::vector<double> l(taken);
    check(hoc_mesh_get_load_fractions(mesh_, taken, l.data()), mesh_);
    return l;
  }
  /** One linear solve of the last run: the solver that produced the solution
   *  (HOC_SOLVED_BY_*), why the first choice did not (HOC_FALLBACK_*, NONE if
   *  it did) and the Krylov iterations run. */
  struct Solve {
    HocSolvedBy solved_by;
    HocFallbackReason fallback;
    std::size_t iterations;
    const char *solver_name() const { return hoc_solved_by_string(solved_by); }
    const char *fallback_name() const { return hoc_fallback_reason_string(fallback); }
  };
  /** The linear solves of the last run, in order. */
  std::vector<Solve> solves() const {
    std::size_t n = 0, fallbacks = 0;
    check(hoc_mesh_solve_count(mesh_, &n, &fallbacks), mesh_);
    std::vector<HocSolvedBy> by(n);
    std::vector<HocFallbackReason> why(n);
    std::vector<std::size_t> its(n);
    check(hoc_mesh_get_solves(mesh_, n, by.data(), why.data(), its.data()), mesh_);
    std::vector<Solve> s(n);
    for (std::size_t i = 0; i < n; ++i) s[i] = Solve{by[i], why[i], its[i]};
    return s;
  }
  /** Linear solves of the last run that fell back from the first choice of solver. */
  std::size_t solver_fallbacks() const {
    std::size_t n = 0, fallbacks = 0;
    check(hoc_mesh_solve_count(mesh_, &n, &fallbacks), mesh_);
    return fallbacks;
  }
  /** node_count()*dim coordinates, interleaved, for connectivity in `ordering`: the
   *  mesh's own node set for NATIVE, the equispaced one for GMSH and VTK (see
   *  hoc_mesh_get_nodes). Use the same ordering for nodes() and cells(). */
  std::vector<double> nodes(HocNodeOrdering ordering = HOC_ORDERING_NATIVE) const {
    std::size_t n = node_count();
    std::vector<double> x(n * static_cast<std::size_t>(dim_));
    check(hoc_mesh_get_nodes(mesh_, ordering, n, x.data()), mesh_);
    return x;
  }
  /** n_cells*nodes_per_cell node ids in the given ordering. */
  std::vector<int64_t> cells(HocNodeOrdering ordering = HOC_ORDERING_NATIVE) const {
    auto c = cell_count();
    std::vector<int64_t> ids(c.first * c.second);
    check(hoc_mesh_get_cells(mesh_, ordering, ids.size(), ids.data()), mesh_);
    return ids;
  }
  /** For each current cell, the index of the input cell it is. */
  std::vector<int64_t> input_cells() const {
    std::vector<int64_t> ids(cell_count().first);
    check(hoc_mesh_get_input_cells(mesh_, ids.size(), ids.data()), mesh_);
    return ids;
  }
  /** Each node's index in the whole mesh and its owner process (hoc_mesh_get_global_nodes). */
  struct GlobalNodes {
    std::vector<int64_t> ids;
    std::vector<int> owners;
  };
  GlobalNodes global_nodes() const {
    GlobalNodes g{std::vector<int64_t>(node_count()), std::vector<int>(node_count())};
    check(hoc_mesh_get_global_nodes(mesh_, g.ids.size(), g.ids.data(), g.owners.data()), mesh_);
    return g;
  }
  /** Writes .msh or .vtu by extension. */
  void write(const std::string &path) const { check(hoc_mesh_write(mesh_, path.c_str()), mesh_); }

 private:
  /** Takes ownership of a handle made by hoc_mesh_create_distributed. */
  Mesh(HocMesh *mesh, int dim) : mesh_(mesh), dim_(dim), callbacks_(new detail::Callbacks) {}
  /** size / per, or Error if size is not a multiple of per. */
  static std::size_t count(std::size_t size, int per, const char *what) {
    if (per <= 0) return 0;  // a bad dim: hoc_mesh_create says so
    std::size_t p = static_cast<std::size_t>(per);
    if (size % p != 0)
      throw Error(HOC_ERROR_INVALID_ARGUMENT, std::string(what) + ": " + std::to_string(size) +
                                                  " values is not a multiple of " + std::to_string(p));
    return size / p;
  }
  /** Error unless `items` holds per values for each of the `n` tags. */
  static void same_count(std::size_t items, std::size_t n, int per, const char *what, const char *tags) {
    if (items != n * static_cast<std::size_t>(per))
      throw Error(HOC_ERROR_INVALID_ARGUMENT, std::string(what) + ": " + std::to_string(items) + " values for " +
                                                  std::to_string(n) + " " + tags + " (" + std::to_string(per) +
                                                  " per tag expected)");
  }
  void ensure_callbacks() {
    if (!callbacks_) callbacks_.reset(new detail::Callbacks);
  }
  HocMesh *mesh_ = nullptr;
  int dim_ = 0;
  std::unique_ptr<detail::Callbacks> callbacks_;
};

}  // namespace hocurve

#endif  // HOCURVE_HPP
