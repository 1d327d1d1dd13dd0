/* Handles are independent: two handles curved at the same time from two
 * pthreads give bitwise the same nodes as the same two runs one after the
 * other. Each handle also uses its own pool of 2 threads. */
#include "fixtures.h"
#include "test_common.h"

#include <pthread.h>

static FixtureMesh fx;

typedef struct Job {
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
  if (st == HOC_OK) st = hoc_mesh_set_threads(mesh, 2);
  if (st == HOC_OK) st = hoc_mesh_set_order(mesh, job->order, HOC_SPACING_OPTIMAL);
  if (st == HOC_OK) st = hoc_mesh_run_increments(mesh, 1);
  if (st == HOC_OK) st = hoc_mesh_node_count(mesh, &job->n);
  if (st == HOC_OK) {
    job->x = (double *)malloc(sizeof(double) * 3 * job->n);
    st = hoc_mesh_get_nodes(mesh, job->n, job->x);
  }
  if (st != HOC_OK) fprintf(stderr, "order %d: %s: %s\n", job->order, hoc_status_string(st), hoc_mesh_last_error(mesh));
  hoc_mesh_destroy(&mesh);
  job->status = st;
  return NULL;
}

int main(int argc, char **argv) {
  int p1 = argc > 1 ? atoi(argv[1]) : 3, p2 = argc > 2 ? atoi(argv[2]) : 4;
  CHECK(fixture_tetgen_sphere_box(2, 2, 0.5, &fx) == 0, "TetGen failed");
  Job seq[2] = {{p1, 0, NULL, 0}, {p2, 0, NULL, 0}};
  Job par[2] = {{p1, 0, NULL, 0}, {p2, 0, NULL, 0}};
  curve(&seq[0]);
  curve(&seq[1]);
  pthread_t t[2];
  for (int i = 0; i < 2; ++i) CHECK(pthread_create(&t[i], NULL, curve, &par[i]) == 0, "pthread_create");
  for (int i = 0; i < 2; ++i) CHECK(pthread_join(t[i], NULL) == 0, "pthread_join");
  for (int i = 0; i < 2; ++i) {
    CHECK(seq[i].status == HOC_OK && par[i].status == HOC_OK, "a run failed");
    CHECK(seq[i].n == par[i].n, "node counts differ");
    CHECK(memcmp(seq[i].x, par[i].x, sizeof(double) * 3 * seq[i].n) == 0,
          "p=%d: concurrent run differs from the sequential one", seq[i].order);
    printf("p=%d: %zu nodes bitwise equal, concurrent vs sequential\n", seq[i].order, seq[i].n);
    free(seq[i].x);
    free(par[i].x);
  }
  fixture_mesh_free(&fx);
  return 0;
}
