/* The C ABI's contract with a host:
 * - the header declares only prefixed names: a host's own ElementQuality and
 *   MaterialModel (declared before the include) do not clash;
 * - hoc_mesh_get_nodes gives, for each ordering, the node set its cells mean:
 *   equispaced for gmsh and VTK, the mesh's own (warp & blend) for native;
 * - one call at a time per handle: a call from inside a callback, or from a
 *   second thread while a run holds the handle, gets HOC_ERROR_BUSY, changes
 *   nothing, and hoc_mesh_last_error says why;
 * - a tag can be held straight (hoc_mesh_set_straight_tags): its facets keep
 *   their straight nodes and the projector is never asked about it;
 * - HocQuality carries the largest projection distance of the last run. */
typedef int ElementQuality; /* a host's own names */
typedef double MaterialModel;

#include "fixtures.h"
#include "test_common.h"

#include <pthread.h>

static FixtureMesh fx;

static HocMesh *sphere_box(int order) {
  HocMesh *mesh = NULL;
  CHECK_OK(NULL, hoc_mesh_create(3, fx.n_vertices, fx.coords, fx.n_cells, fx.cells, &mesh));
  CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, fx.n_facets, fx.facets, fx.facet_tags));
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, order, HOC_SPACING_OPTIMAL));
  return mesh;
}

/* Straight p = 3 mesh: each edge node is a vertex combination (1-t) a + t b;
 * gmsh's and VTK's t are 1/3 and 2/3, the native (Gauss-Lobatto) ones are not. */
static void node_sets(void) {
  HocMesh *mesh = sphere_box(3);
  size_t n = 0, nc = 0, npc = 0;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n));
  CHECK_OK(mesh, hoc_mesh_cell_count(mesh, &nc, &npc));
  CHECK(npc == 20, "p = 3 tets have 20 nodes, got %zu", npc);
  double *x = malloc(sizeof(double) * 3 * n);
  int64_t *c = malloc(sizeof(int64_t) * nc * npc);
  const HocNodeOrdering orderings[3] = {HOC_ORDERING_GMSH, HOC_ORDERING_VTK, HOC_ORDERING_NATIVE};
  for (int o = 0; o < 3; ++o) {
    CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, orderings[o], n, x));
    CHECK_OK(mesh, hoc_mesh_get_cells(mesh, orderings[o], nc * npc, c));
    /* Both gmsh and VTK list the two nodes of edge (v0, v1) right after the
     * four vertices, from v0 to v1; so does the native order. */
    double worst_third = 0.0;
    for (size_t k = 0; k < nc; ++k) {
      const int64_t *cell = c + k * npc;
      const double *a = x + 3 * cell[0], *b = x + 3 * cell[1], *e = x + 3 * cell[4];
      double len = 0.0, t = 0.0;
      for (int d = 0; d < 3; ++d) {
        len += (b[d] - a[d]) * (b[d] - a[d]);
        t += (e[d] - a[d]) * (b[d] - a[d]);
      }
      t /= len;
      worst_third = fmax(worst_third, fabs(t - 1.0 / 3.0));
    }
    if (orderings[o] == HOC_ORDERING_NATIVE)
      CHECK(worst_third > 0.05, "native edge nodes should be Gauss-Lobatto, not thirds (%.3g)", worst_third);
    else
      CHECK(worst_third < 1e-12, "ordering %d: edge nodes %.3g away from the thirds", orderings[o], worst_third);
  }
  CHECK(hoc_mesh_get_nodes(mesh, (HocNodeOrdering)7, n, x) == HOC_ERROR_INVALID_ARGUMENT, "unknown ordering");
  free(x);
  free(c);
  hoc_mesh_destroy(&mesh);
  printf("node sets: gmsh and VTK equispaced, native Gauss-Lobatto\n");
}

/* ---- one call at a time ---- */

typedef struct Reentry {
  HocMesh *mesh;
  HocStatus inner;  /* status of the call made from inside the projector */
  char message[256];
} Reentry;

static int reentrant_projector(void *user, int dim, int tag, size_t n, const double *in, double *out) {
  Reentry *r = (Reentry *)user;
  size_t count = 0;
  r->inner = hoc_mesh_node_count(r->mesh, &count);
  snprintf(r->message, sizeof r->message, "%s", hoc_mesh_last_error(r->mesh));
  return sphere_box_projector(NULL, dim, tag, n, in, out);
}

static void call_from_callback(void) {
  Reentry r = {sphere_box(2), HOC_OK, ""};
  CHECK_OK(r.mesh, hoc_mesh_set_projector(r.mesh, reentrant_projector, &r));
  CHECK_OK(r.mesh, hoc_mesh_run_increments(r.mesh, 1));
  CHECK(r.inner == HOC_ERROR_BUSY, "a call from inside the projector returned %d, not HOC_ERROR_BUSY", r.inner);
  CHECK(strstr(r.message, "busy") != NULL, "its message: \"%s\"", r.message);
  /* The run itself is not disturbed, and its own message is empty. */
  CHECK(strcmp(hoc_mesh_last_error(r.mesh), "") == 0, "after the run: \"%s\"", hoc_mesh_last_error(r.mesh));
  hoc_mesh_destroy(&r.mesh);
  printf("a call from inside a callback: HOC_ERROR_BUSY (%s)\n", r.message);
}

typedef struct Gate {
  pthread_mutex_t lock;
  pthread_cond_t cond;
  int running, released;
} Gate;

/* Progress callback of the run: signal that the run holds the handle, then
 * wait until the other thread has tried its call. */
static int hold(void *user, int stage, int step, int total) {
  (void)stage, (void)step, (void)total;
  Gate *g = (Gate *)user;
  pthread_mutex_lock(&g->lock);
  g->running = 1;
  pthread_cond_broadcast(&g->cond);
  while (!g->released) pthread_cond_wait(&g->cond, &g->lock);
  pthread_mutex_unlock(&g->lock);
  return 0;
}

typedef struct Runner {
  HocMesh *mesh;
  HocStatus status;
} Runner;

static void *run(void *arg) {
  Runner *r = (Runner *)arg;
  r->status = hoc_mesh_run_increments(r->mesh, 1);
  return NULL;
}

static void call_from_two_threads(void) {
  Gate g = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0, 0};
  Runner r = {sphere_box(2), -1};
  CHECK_OK(r.mesh, hoc_mesh_set_projector(r.mesh, sphere_box_projector, NULL));
  CHECK_OK(r.mesh, hoc_mesh_set_progress(r.mesh, hold, &g));
  pthread_t t;
  CHECK(pthread_create(&t, NULL, run, &r) == 0, "pthread_create");
  pthread_mutex_lock(&g.lock);
  while (!g.running) pthread_cond_wait(&g.cond, &g.lock);
  pthread_mutex_unlock(&g.lock);
  /* The run holds the handle: every call from here is refused, unchanged. */
  HocStatus set = hoc_mesh_set_order(r.mesh, 4, HOC_SPACING_OPTIMAL);
  char message[256];
  snprintf(message, sizeof message, "%s", hoc_mesh_last_error(r.mesh));
  HocMesh *copy = r.mesh;
  HocStatus destroy = hoc_mesh_destroy(&copy);
  pthread_mutex_lock(&g.lock);
  g.released = 1;
  pthread_cond_broadcast(&g.cond);
  pthread_mutex_unlock(&g.lock);
  CHECK(pthread_join(t, NULL) == 0, "pthread_join");
  CHECK(set == HOC_ERROR_BUSY, "set_order during a run on another thread returned %d", set);
  CHECK(strstr(message, "busy") != NULL, "its message: \"%s\"", message);
  CHECK(destroy == HOC_ERROR_BUSY && copy == r.mesh, "destroy during a run returned %d", destroy);
  CHECK(r.status == HOC_OK, "the run failed: %d %s", r.status, hoc_mesh_last_error(r.mesh));
  /* This thread's refusal is still what it reads, until its next call. */
  CHECK(strstr(hoc_mesh_last_error(r.mesh), "busy") != NULL, "after the run: \"%s\"", hoc_mesh_last_error(r.mesh));
  size_t n = 0, nc = 0, npc = 0;
  CHECK_OK(r.mesh, hoc_mesh_node_count(r.mesh, &n));
  CHECK_OK(r.mesh, hoc_mesh_cell_count(r.mesh, &nc, &npc));
  CHECK(npc == 10, "the refused set_order changed the order: %zu nodes per cell", npc);
  CHECK(strcmp(hoc_mesh_last_error(r.mesh), "") == 0, "after a call that worked: \"%s\"", hoc_mesh_last_error(r.mesh));
  hoc_mesh_destroy(&r.mesh);
  printf("a call from a second thread during a run: HOC_ERROR_BUSY, nothing changed\n");
}

/* ---- straight tags and the projection distance ---- */

typedef struct Calls {
  size_t sphere, box;
} Calls;

static int counting_projector(void *user, int dim, int tag, size_t n, const double *in, double *out) {
  Calls *c = (Calls *)user;
  if (tag == FIXTURE_SPHERE_TAG) c->sphere += n;
  if (tag == FIXTURE_BOX_TAG) c->box += n;
  return sphere_box_projector(NULL, dim, tag, n, in, out);
}

static void straight_tags(void) {
  HocMesh *mesh = sphere_box(3);
  HocQuality q;
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
  CHECK(q.max_projection_distance == 0.0, "before a run: %g", q.max_projection_distance);
  size_t n = 0;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n));
  double *straight = malloc(sizeof(double) * 3 * n), *curved = malloc(sizeof(double) * 3 * n);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n, straight));

  const int32_t sphere = FIXTURE_SPHERE_TAG, nope = 99;
  CHECK(hoc_mesh_set_straight_tags(mesh, 2, 1, &nope) == HOC_ERROR_INVALID_ARGUMENT, "a tag no facet has");
  CHECK(hoc_mesh_set_straight_tags(mesh, 0, 1, &sphere) == HOC_ERROR_INVALID_ARGUMENT, "entity_dim 0");
  CHECK_OK(mesh, hoc_mesh_set_straight_tags(mesh, 2, 1, &sphere));
  Calls calls = {0, 0};
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, counting_projector, &calls));
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
  CHECK(calls.sphere == 0, "the projector was asked %zu sphere points", calls.sphere);
  CHECK(calls.box > 0, "the box was not projected");
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n, curved));
  /* The box is flat and the sphere held straight: nothing moves. */
  double moved = 0.0;
  for (size_t k = 0; k < 3 * n; ++k) moved = fmax(moved, fabs(curved[k] - straight[k]));
  CHECK(moved < 1e-12, "a node moved by %g with the sphere held straight", moved);
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
  CHECK(q.max_projection_distance < 1e-12, "box nodes are on the box: %g", q.max_projection_distance);

  /* An empty list curves the sphere again. */
  CHECK_OK(mesh, hoc_mesh_set_straight_tags(mesh, 2, 0, NULL));
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
  CHECK(calls.sphere > 0, "the sphere was not projected");
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
  /* Straight p = 3 nodes on the icosphere's facets lie inside the sphere, at
   * most the sagitta of its longest edge away. */
  CHECK(q.max_projection_distance > 1e-4 && q.max_projection_distance < 0.2 * FIXTURE_SPHERE_RADIUS,
        "max projection distance %g", q.max_projection_distance);
  printf("straight tags: sphere held (0 projections), then curved; max projection distance %.3g\n",
         q.max_projection_distance);
  free(straight);
  free(curved);
  hoc_mesh_destroy(&mesh);
}

int main(void) {
  CHECK(fixture_tetgen_sphere_box(1, 2, 1.0, &fx) == 0, "TetGen failed");
  node_sets();
  call_from_callback();
  call_from_two_threads();
  straight_tags();
  fixture_mesh_free(&fx);
  return 0;
}
