/* The external linear-solver hook: a Jacobi-preconditioned CG written here
 * curves the TetGen sphere cavity at p = 2..P (P = argv[1], default 3; argv[2]
 * TetGen's max volume, argv[3] icosphere subdivisions) to the nodes of the
 * built-in solver (1e-7 of the shortest edge), called once per increment, with
 * no invalid cell; every system it receives is a full symmetric CSR matrix
 * with sorted columns. A callback that fails or writes NaN gives
 * HOC_ERROR_SOLVER and leaves the nodes bitwise unchanged; with static
 * condensation the callback receives 3 unknowns fewer per tet at p = 4 and the
 * nodes are the same; NULL restores the
 * built-in solver; a NULL handle gives HOC_ERROR_NULL_POINTER. */
#include "curve_checks.h"

#define INCREMENTS 3

typedef struct Cg {
  int calls;
  int64_t last_n;
  int fail_on_call; /* 0: never; k: return 3 on the k-th call */
  int nan_on_call;  /* 0: never; k: write NaN on the k-th call */
  double *work;     /* 4 n doubles */
  int64_t work_n;
  int max_iterations;
} Cg;

static double dot(int64_t n, const double *u, const double *v) {
  double s = 0.0;
  for (int64_t i = 0; i < n; ++i) s += u[i] * v[i];
  return s;
}

static void matvec(int64_t n, const int64_t *rp, const int64_t *ci, const double *a, const double *x, double *y) {
  for (int64_t i = 0; i < n; ++i) {
    double s = 0.0;
    for (int64_t k = rp[i]; k < rp[i + 1]; ++k) s += a[k] * x[ci[k]];
    y[i] = s;
  }
}

/* Value of entry (i, j), or NAN if it is not stored (binary search in row i). */
static double entry(const int64_t *rp, const int64_t *ci, const double *a, int64_t i, int64_t j) {
  int64_t lo = rp[i], hi = rp[i + 1];
  while (lo < hi) {
    int64_t mid = lo + (hi - lo) / 2;
    if (ci[mid] < j)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo < rp[i + 1] && ci[lo] == j ? a[lo] : NAN;
}

/* Jacobi-preconditioned CG to ||r|| <= 1e-13 ||b||, from the initial guess in x. */
static int cg_solve(void *user, int64_t n, const int64_t *rp, const int64_t *ci, const double *a,
                    const double *b, double *x) {
  Cg *cg = (Cg *)user;
  ++cg->calls;
  cg->last_n = n;
  if (cg->fail_on_call == cg->calls) return 3;
  /* The contract: row_ptr from 0, sorted in-range columns, symmetric values, a diagonal. */
  if (n <= 0 || rp[0] != 0) return 10;
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t k = rp[i]; k < rp[i + 1]; ++k) {
      if (ci[k] < 0 || ci[k] >= n || (k > rp[i] && ci[k] <= ci[k - 1])) return 11;
      if (entry(rp, ci, a, ci[k], i) != a[k]) return 12;
    }
    if (!(entry(rp, ci, a, i, i) > 0)) return 13;
  }
  if (cg->work_n != n) {
    free(cg->work);
    cg->work = (double *)malloc(sizeof(double) * 4 * (size_t)n);
    cg->work_n = n;
  }
  double *r = cg->work, *z = r + n, *p = z + n, *ap = p + n;
  matvec(n, rp, ci, a, x, ap);
  for (int64_t i = 0; i < n; ++i) {
    r[i] = b[i] - ap[i];
    z[i] = r[i] / entry(rp, ci, a, i, i);
    p[i] = z[i];
  }
  double rz = dot(n, r, z), tol = 1e-13 * sqrt(dot(n, b, b));
  int it = 0;
  for (; it < 20 * n && sqrt(dot(n, r, r)) > tol; ++it) {
    matvec(n, rp, ci, a, p, ap);
    double alpha = rz / dot(n, p, ap);
    for (int64_t i = 0; i < n; ++i) {
      x[i] += alpha * p[i];
      r[i] -= alpha * ap[i];
      z[i] = r[i] / entry(rp, ci, a, i, i);
    }
    double rz_new = dot(n, r, z);
    for (int64_t i = 0; i < n; ++i) p[i] = z[i] + rz_new / rz * p[i];
    rz = rz_new;
  }
  if (it > cg->max_iterations) cg->max_iterations = it;
  if (sqrt(dot(n, r, r)) > tol) return 20;
  if (cg->nan_on_call == cg->calls) x[n / 2] = NAN;
  return 0;
}

static double shortest_edge(const FixtureMesh *m) {
  static const int E[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  double h = INFINITY;
  for (size_t c = 0; c < m->n_cells; ++c)
    for (int e = 0; e < 6; ++e) {
      const double *a = m->coords + 3 * m->cells[4 * c + E[e][0]], *b = m->coords + 3 * m->cells[4 * c + E[e][1]];
      double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
      h = fmin(h, norm3(d));
    }
  return h;
}

/* Curves at order p, with static condensation on or off; with cg != NULL through
 * the external solver. Returns the nodes (malloc'd) and the cell count. */
static double *curve(const FixtureMesh *m, int p, Cg *cg, int condense, size_t *n_nodes, size_t *n_cells) {
  HocMesh *mesh = create_fixture_mesh(m, sphere_box_projector, NULL);
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, p, HOC_SPACING_OPTIMAL));
  CHECK_OK(mesh, hoc_mesh_set_static_condensation(mesh, condense));
  if (cg) CHECK_OK(mesh, hoc_mesh_set_linear_solver(mesh, cg_solve, cg));
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, INCREMENTS));
  HocQuality q;
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
  CHECK(q.n_invalid == 0, "p=%d (%s): %zu invalid cells", p, cg ? "external" : "built-in", q.n_invalid);
  /* Each solve is reported, with the solver that produced it: no fallback here. */
  size_t n_solves = 0, n_fallbacks = 0;
  CHECK_OK(mesh, hoc_mesh_solve_count(mesh, &n_solves, &n_fallbacks));
  CHECK(n_solves == INCREMENTS && n_fallbacks == 0, "p=%d: %zu solves, %zu fallbacks", p, n_solves, n_fallbacks);
  HocSolvedBy by[INCREMENTS];
  HocFallbackReason why[INCREMENTS];
  CHECK_OK(mesh, hoc_mesh_get_solves(mesh, n_solves, by, why, NULL));
  for (size_t i = 0; i < n_solves; ++i) {
    const char *name = hoc_solved_by_string(by[i]);
    CHECK(cg ? by[i] == HOC_SOLVED_BY_EXTERNAL && strcmp(name, "external") == 0
             : by[i] == HOC_SOLVED_BY_DIRECT || by[i] == HOC_SOLVED_BY_PCG,
          "p=%d: solve %zu by %s", p, i, name);
    CHECK(why[i] == HOC_FALLBACK_NONE, "p=%d: solve %zu fell back (%s)", p, i, hoc_fallback_reason_string(why[i]));
  }
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, n_nodes));
  size_t npc = 0;
  CHECK_OK(mesh, hoc_mesh_cell_count(mesh, n_cells, &npc));
  double *x = (double *)malloc(sizeof(double) * 3 * *n_nodes);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, *n_nodes, x));
  CHECK_OK(NULL, hoc_mesh_destroy(&mesh));
  return x;
}

/* A failing or NaN-writing callback: HOC_ERROR_SOLVER, a message naming the
 * external solver (and `expect`), nodes bitwise as after the earlier run. */
static void check_failure(HocMesh *mesh, size_t n_nodes, const double *before, Cg *cg, const char *expect) {
  cg->calls = 0;
  CHECK_OK(mesh, hoc_mesh_set_linear_solver(mesh, cg_solve, cg));
  HocStatus st = hoc_mesh_run_increments(mesh, INCREMENTS);
  const char *msg = hoc_mesh_last_error(mesh);
  printf("failing callback (fail on call %d, NaN on call %d): status %d, \"%s\"\n", cg->fail_on_call,
         cg->nan_on_call, st, msg);
  CHECK(st == HOC_ERROR_SOLVER, "status %d, expected HOC_ERROR_SOLVER", st);
  CHECK(strstr(msg, "external linear solver") && strstr(msg, expect), "message: %s", msg);
  double *x = (double *)malloc(sizeof(double) * 3 * n_nodes);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x));
  CHECK(memcmp(x, before, sizeof(double) * 3 * n_nodes) == 0, "a failed run changed the nodes");
  free(x);
}

int main(int argc, char **argv) {
  int max_order = argc > 1 ? atoi(argv[1]) : 3;
  double max_volume = argc > 2 ? atof(argv[2]) : 0.2;
  int subdivisions = argc > 3 ? atoi(argv[3]) : 2;
  FixtureMesh m;
  CHECK(fixture_tetgen_sphere_box(subdivisions, 4, max_volume, &m) == 0, "TetGen failed");
  double h = shortest_edge(&m);
  printf("TetGen sphere cavity: %zu vertices, %zu tets, shortest edge %.3g\n", m.n_vertices, m.n_cells, h);

  for (int p = 2; p <= max_order; ++p) {
    Cg cg = {0};
    size_t n1 = 0, n2 = 0, cells = 0;
    double *xe = curve(&m, p, &cg, 1, &n1, &cells);
    double *xd = curve(&m, p, NULL, 1, &n2, &cells);
    CHECK(n1 == n2, "node counts %zu and %zu", n1, n2);
    double diff = 0.0;
    for (size_t i = 0; i < 3 * n1; ++i) diff = fmax(diff, fabs(xe[i] - xd[i]));
    printf("p=%d: %zu nodes, %lld unknowns, %d calls, at most %d CG iterations, max |x_cg - x_direct| = "
           "%.2e (%.2e of the shortest edge)\n",
           p, n1, (long long)cg.last_n, cg.calls, cg.max_iterations, diff, diff / h);
    CHECK(cg.calls == INCREMENTS, "p=%d: %d calls for %d increments", p, cg.calls, INCREMENTS);
    /* The built-in reference is the direct solver up to 5,000 unknowns at
     * p = 2 and 3 (15,000 at p = 4, 25,000 above) and PCG (relative
     * residual 1e-5, nodes within ~1e-6 h) for larger systems. */
    const long long direct_max = p <= 3 ? 5000 : p == 4 ? 15000 : 25000;
    CHECK(diff <= (cg.last_n > direct_max ? 2e-5 : 1e-7) * h, "p=%d: nodes differ by %g", p, diff);
    free(cg.work);
    free(xe);
    free(xd);
  }

  /* Static condensation (default on) hands the external solver the Schur
   * complement on the vertex, edge and face nodes: at p = 4, 3 unknowns fewer
   * per tet (its one interior node), and the same nodes to round-off. */
  if (max_order >= 3) {
    FixtureMesh coarse; /* a coarser cavity: Jacobi CG at p = 4 is slow */
    CHECK(fixture_tetgen_sphere_box(1, 4, 50.0, &coarse) == 0, "TetGen failed");
    double hc = shortest_edge(&coarse);
    Cg on = {0}, off = {0};
    size_t n_on = 0, n_off = 0, cells = 0;
    double *x_on = curve(&coarse, 4, &on, 1, &n_on, &cells);
    double *x_off = curve(&coarse, 4, &off, 0, &n_off, &cells);
    double diff = 0.0;
    for (size_t i = 0; i < 3 * n_on; ++i) diff = fmax(diff, fabs(x_on[i] - x_off[i]));
    printf("p=4: %lld unknowns condensed, %lld not (%zu tets), max |x_on - x_off| = %.2e (%.2e h)\n",
           (long long)on.last_n, (long long)off.last_n, cells, diff, diff / hc);
    CHECK(off.last_n - on.last_n == (int64_t)(3 * cells), "p=4: %lld - %lld unknowns for %zu tets",
          (long long)off.last_n, (long long)on.last_n, cells);
    CHECK(diff <= 1e-9 * hc, "p=4: condensation changed the nodes by %g", diff);
    fixture_mesh_free(&coarse);
    free(on.work);
    free(off.work);
    free(x_on);
    free(x_off);
  }

  /* Failures leave the curved mesh of the previous (built-in) run as it was. */
  HocMesh *mesh = create_fixture_mesh(&m, sphere_box_projector, NULL);
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 2, HOC_SPACING_OPTIMAL));
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
  size_t n_nodes = 0;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n_nodes));
  double *before = (double *)malloc(sizeof(double) * 3 * n_nodes);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, before));
  Cg failing = {0};
  failing.fail_on_call = 2;
  check_failure(mesh, n_nodes, before, &failing, "status 3");
  CHECK(failing.calls == 2, "the run went on after the callback failed (%d calls)", failing.calls);
  Cg nan = {0};
  nan.nan_on_call = 1;
  check_failure(mesh, n_nodes, before, &nan, "non-finite");
  CHECK(nan.calls == 1, "the run went on after a NaN solution (%d calls)", nan.calls);
  free(failing.work);
  free(nan.work);

  /* NULL restores the built-in solver: the run succeeds without calling the callback. */
  CHECK_OK(mesh, hoc_mesh_set_linear_solver(mesh, NULL, NULL));
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
  CHECK(nan.calls == 1, "the callback was called after it was removed");
  double *after = (double *)malloc(sizeof(double) * 3 * n_nodes);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, after));
  CHECK(memcmp(after, before, sizeof(double) * 3 * n_nodes) == 0, "the built-in solver gave other nodes");
  free(after);
  free(before);
  CHECK_OK(NULL, hoc_mesh_destroy(&mesh));

  HocStatus st = hoc_mesh_set_linear_solver(NULL, cg_solve, NULL);
  CHECK(st == HOC_ERROR_NULL_POINTER, "NULL handle gave status %d", st);
  printf("hoc_mesh_set_linear_solver(NULL, ...): %s\n", hoc_mesh_last_error(NULL));
  fixture_mesh_free(&m);
  return 0;
}
