/* Handles are independent and runs are deterministic: two handles curved at
 * the same time from two pthreads give bitwise the same nodes as the same two
 * runs one after the other, with a pool of 1 thread per handle and with 2
 * (assembly is cell-coloured, without atomic adds); and 1 and 2 threads per
 * handle give bitwise the same nodes too. */
#include "fixtures.h"
#include "test_common.h"

#include <pthread.h>

static FixtureMesh fx;

typedef struct Job {
  int threads;
  int order;
  size_t n;
  double *x;
  HocStatus status;
} Job;

static void *curve(void *arg) {
  Job *job = (Job *)arg;
  HocMesh *mesh = NULL;
  job->x = NULL;
  HocStatus st = hoc_mesh_create(3, fx.n_vertices, fx.coords, fx.n_cells, fx.cells, &mesh);
  if (st == HOC_OK) st = hoc_mesh_set_boundary(mesh, fx.n_facets, fx.facets, fx.facet_tags);
  if (st == HOC_OK) st = hoc_mesh_set_projector(mesh, sphere_box_projector, NULL);
  if (st == HOC_OK) st = hoc_mesh_set_threads(mesh, job->threads);
  if (st == HOC_OK) st = hoc_mesh_set_order(mesh, job->order, HOC_SPACING_OPTIMAL);
  if (st == HOC_OK) st = hoc_mesh_run_increments(mesh, 1);
  if (st == HOC_OK) st = hoc_mesh_node_count(mesh, &job->n);
  if (st == HOC_OK) {
    job->x = (double *)malloc(sizeof(double) * 3 * job->n);
    st = hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, job->n, job->x);
  }
  if (st != HOC_OK) fprintf(stderr, "order %d: %s: %s\n", job->order, hoc_status_string(st), hoc_mesh_last_error(mesh));
  hoc_mesh_destroy(&mesh);
  job->status = st;
  return NULL;
}

/* Sequential runs, then the same runs concurrently: bitwise equal. Keeps the
 * sequential nodes in ref[] (the caller frees them). */
static void compare(int threads, int p1, int p2, Job ref[2]) {
  Job seq[2] = {{threads, p1, 0, NULL, 0}, {threads, p2, 0, NULL, 0}};
  Job par[2] = {{threads, p1, 0, NULL, 0}, {threads, p2, 0, NULL, 0}};
  curve(&seq[0]);
  curve(&seq[1]);
  pthread_t t[2];
  for (int i = 0; i < 2; ++i) CHECK(pthread_create(&t[i], NULL, curve, &par[i]) == 0, "pthread_create");
  for (int i = 0; i < 2; ++i) CHECK(pthread_join(t[i], NULL) == 0, "pthread_join");
  double worst = 0.0;
  for (int i = 0; i < 2; ++i) {
    CHECK(seq[i].status == HOC_OK && par[i].status == HOC_OK, "a run failed");
    CHECK(seq[i].n == par[i].n, "node counts differ");
    size_t differ = 0;
    for (size_t k = 0; k < 3 * seq[i].n; ++k) {
      differ += seq[i].x[k] != par[i].x[k];
      worst = fmax(worst, fabs(seq[i].x[k] - par[i].x[k]));
    }
    printf("p=%d, %d thread(s) per handle: %zu nodes, %zu of %zu coordinates differ (max %.1e), "
           "concurrent vs sequential\n",
           seq[i].order, threads, seq[i].n, differ, 3 * seq[i].n, worst);
    CHECK(differ == 0, "p=%d, %d thread(s) per handle: %zu coordinates differ (max %g), concurrent vs sequential",
          seq[i].order, threads, differ, worst);
    ref[i] = seq[i];
    free(par[i].x);
  }
}

int main(int argc, char **argv) {
  int p1 = argc > 1 ? atoi(argv[1]) : 3, p2 = argc > 2 ? atoi(argv[2]) : 4;
  int subdivisions = argc > 3 ? atoi(argv[3]) : 2; /* of the icosphere */
  CHECK(fixture_tetgen_sphere_box(subdivisions, 2, subdivisions > 1 ? 0.5 : 2.0, &fx) == 0, "TetGen failed");
  Job one[2], two[2];
  compare(1, p1, p2, one);
  compare(2, p1, p2, two);
  for (int i = 0; i < 2; ++i) {
    CHECK(one[i].n == two[i].n, "node counts differ between 1 and 2 threads");
    size_t differ = 0;
    double worst = 0.0;
    for (size_t k = 0; k < 3 * one[i].n; ++k) {
      differ += one[i].x[k] != two[i].x[k];
      worst = fmax(worst, fabs(one[i].x[k] - two[i].x[k]));
    }
    printf("p=%d: %zu of %zu coordinates differ (max %.1e), 1 vs 2 threads per handle\n", one[i].order,
           differ, 3 * one[i].n, worst);
    CHECK(differ == 0, "p=%d: 1 and 2 threads per handle differ in %zu coordinates (max %g)", one[i].order,
          differ, worst);
    free(one[i].x);
    free(two[i].x);
  }
  fixture_mesh_free(&fx);
  return 0;
}
