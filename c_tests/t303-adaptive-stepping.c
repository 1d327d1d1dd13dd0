/* Adaptive load stepping through the C ABI: a coarse TetGen box with a
 * spherical cavity (icosphere of argv[2] subdivisions, max volume argv[1])
 * curved at p = 4 with ILE in one increment, first with adaptive stepping off,
 * then on: the increments taken, the load fractions and the step backs are
 * read back and printed; with adaptive stepping no cell is certified invalid.
 * At p = 3 the same mesh keeps 18 tets inverted whatever the step: without
 * the optimisation stage, adaptive stepping fails at its split limit with
 * HOC_ERROR_INVALID_ELEMENT and the mesh unchanged; with it (the default),
 * the run goes on and must end certified valid, or fail the same clean way.
 * Also the setter's and getters' argument checks. */
#include "curve_checks.h"

static void run(const FixtureMesh *m, int p, int enabled, HocQuality *q, size_t *taken, size_t *backs) {
  size_t calls = 0;
  HocMesh *mesh = create_fixture_mesh(m, sphere_box_projector, &calls);
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, p, HOC_SPACING_OPTIMAL));
  CHECK_OK(mesh, hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1.0, 0.45));
  CHECK_OK(mesh, hoc_mesh_set_adaptive_stepping(mesh, enabled, 6));
  CHECK_OK(mesh, hoc_mesh_increment_count(mesh, taken, backs));
  CHECK(*taken == 0 && *backs == 0, "counts before a run: %zu, %zu", *taken, *backs);
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
  CHECK_OK(mesh, hoc_mesh_quality(mesh, q));
  CHECK_OK(mesh, hoc_mesh_increment_count(mesh, taken, backs));
  CHECK(*taken >= 1, "no increment taken");
  CHECK(enabled == 1 || (*taken == 1 && *backs == 0), "adaptive off split the step");
  double *loads = (double *)malloc(sizeof(double) * *taken);
  CHECK(hoc_mesh_get_load_fractions(mesh, *taken + 1, loads) == HOC_ERROR_BUFFER_SIZE, "wrong count accepted");
  CHECK_OK(mesh, hoc_mesh_get_load_fractions(mesh, *taken, loads));
  printf("adaptive %s: %zu increment(s) at load", enabled ? "on" : "off", *taken);
  for (size_t i = 0; i < *taken; ++i) {
    printf(" %g", loads[i]);
    CHECK(loads[i] > (i ? loads[i - 1] : 0.0) && loads[i] <= 1.0, "load fractions not increasing");
  }
  CHECK(loads[*taken - 1] == 1.0, "the last load fraction is %g", loads[*taken - 1]);
  double *at = (double *)malloc(sizeof(double) * (*backs + 1));
  double *step = (double *)malloc(sizeof(double) * (*backs + 1));
  int *reason = (int *)malloc(sizeof(int) * (*backs + 1));
  int64_t *cell = (int64_t *)malloc(sizeof(int64_t) * (*backs + 1));
  CHECK_OK(mesh, hoc_mesh_get_step_backs(mesh, *backs, at, step, reason, cell));
  CHECK_OK(mesh, hoc_mesh_get_step_backs(mesh, *backs, NULL, NULL, NULL, NULL));
  for (size_t i = 0; i < *backs; ++i) {
    printf("%s%g (step %g, reason %d, cell %lld)", i ? ", " : "; stepped back at ", at[i], step[i], reason[i],
           (long long)cell[i]);
    CHECK(reason[i] >= HOC_STEP_BACK_SAMPLED_INVALID && reason[i] <= HOC_STEP_BACK_RESTARTED, "reason %d", reason[i]);
  }
  printf("\n  min Q3 %.4f, invalid %zu, certified min Q3 %.4f, certified invalid %zu, uncertain %zu\n", q->min_q3,
         q->n_invalid, q->certified_min_q3, q->n_certified_invalid, q->n_uncertain);
  free(loads);
  free(at);
  free(step);
  free(reason);
  free(cell);
  CHECK(hoc_mesh_set_adaptive_stepping(mesh, 2, 6) == HOC_ERROR_INVALID_ARGUMENT, "enabled = 2 accepted");
  CHECK(hoc_mesh_set_adaptive_stepping(mesh, 1, 31) == HOC_ERROR_INVALID_ARGUMENT, "max_splits = 31 accepted");
  CHECK(hoc_mesh_set_adaptive_stepping(mesh, 1, -1) == HOC_ERROR_INVALID_ARGUMENT, "max_splits = -1 accepted");
  CHECK(hoc_mesh_set_adaptive_stepping(NULL, 1, 6) == HOC_ERROR_NULL_POINTER, "NULL handle accepted");
  CHECK_OK(mesh, hoc_mesh_set_adaptive_stepping(mesh, -1, 0));
  hoc_mesh_destroy(&mesh);
}

int main(int argc, char **argv) {
  double max_volume = argc > 1 ? atof(argv[1]) : 8.0;
  int subdivisions = argc > 2 ? atoi(argv[2]) : 0;
  int p = argc > 3 ? atoi(argv[3]) : 4;
  FixtureMesh m;
  CHECK(fixture_tetgen_sphere_box(subdivisions, 1, max_volume, &m) == 0, "TetGen failed");
  printf("TetGen sphere cavity: %zu vertices, %zu tets, %zu boundary triangles\n", m.n_vertices, m.n_cells,
         m.n_facets);
  HocQuality plain, adaptive;
  size_t taken, backs;
  run(&m, p, 0, &plain, &taken, &backs);
  run(&m, p, 1, &adaptive, &taken, &backs);
  CHECK(adaptive.n_certified_invalid == 0 && adaptive.n_invalid == 0, "adaptive stepping left %zu invalid cells",
        adaptive.n_certified_invalid);

  /* The split limit: a clear error, the mesh as before the run. */
  size_t calls = 0;
  HocMesh *mesh = create_fixture_mesh(&m, sphere_box_projector, &calls);
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 3, HOC_SPACING_OPTIMAL));
  CHECK_OK(mesh, hoc_mesh_set_adaptive_stepping(mesh, 1, 3));
  CHECK_OK(mesh, hoc_mesh_set_optimize(mesh, 0));
  size_t n_nodes = 0;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n_nodes));
  double *x0 = (double *)malloc(sizeof(double) * 3 * n_nodes);
  double *x1 = (double *)malloc(sizeof(double) * 3 * n_nodes);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x0));
  HocStatus st = hoc_mesh_run_increments(mesh, 1);
  const char *msg = hoc_mesh_last_error(mesh);
  printf("p = 3, max_splits 3: status %d: %s\n", st, msg);
  CHECK(st == HOC_ERROR_INVALID_ELEMENT, "status %d", st);
  CHECK(strstr(msg, "limit") != NULL, "the message does not name the limit: %s", msg);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x1));
  CHECK(memcmp(x0, x1, sizeof(double) * 3 * n_nodes) == 0, "the failed run changed the mesh");
  CHECK_OK(mesh, hoc_mesh_increment_count(mesh, &taken, &backs));
  CHECK(taken == 0 && backs == 0, "a failed run left counts %zu, %zu", taken, backs);

  /* The same run with the optimisation stage on. */
  CHECK_OK(mesh, hoc_mesh_set_optimize(mesh, 1));
  st = hoc_mesh_run_increments(mesh, 1);
  if (st == HOC_OK) {
    HocQuality q;
    HocOptimization o;
    CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
    CHECK_OK(mesh, hoc_mesh_optimization(mesh, &o));
    printf("p = 3, optimisation on: elastic stage stopped at load %g; %zu invalid cells -> %zu in %.2f s "
           "(%zu cells touched); min Q3 %g, certified %g\n",
           o.elastic_load, o.invalid_before, o.invalid_after, o.seconds, o.cells_touched, q.min_q3,
           q.certified_min_q3);
    CHECK(o.elastic_stopped && o.ran, "the elastic stage should have stopped (%d) and the optimisation run (%d)",
          o.elastic_stopped, o.ran);
    CHECK(q.n_certified_invalid == 0 && q.n_uncertain == 0 && q.certified_min_q3 > 0,
          "a successful run left %zu invalid, %zu uncertain cells", q.n_certified_invalid, q.n_uncertain);
  } else {
    msg = hoc_mesh_last_error(mesh);
    printf("p = 3, optimisation on: status %d: %s\n", st, msg);
    CHECK(st == HOC_ERROR_INVALID_ELEMENT, "status %d", st);
    CHECK(strstr(msg, "optimisation") != NULL, "the message does not name the optimisation: %s", msg);
    CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x1));
    CHECK(memcmp(x0, x1, sizeof(double) * 3 * n_nodes) == 0, "the failed run changed the mesh");
  }
  free(x0);
  free(x1);
  hoc_mesh_destroy(&mesh);
  fixture_mesh_free(&m);
  return 0;
}
