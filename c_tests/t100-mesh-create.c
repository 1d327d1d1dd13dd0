/* Mesh handles: create/destroy, NULL handling, and a catalogue of bad inputs.
 * Every bad input must give the expected non-OK status and a
 * non-empty last-error message, never a crash, and after every failed run the
 * nodes are bitwise what they were before the run. */
#include "fixtures.h"
#include "test_common.h"

#include <stdint.h>

static int n_cases = 0;

/* Message for a failure: the handle's, or for a failed create (no handle) the
 * thread's, which hoc_mesh_last_error(NULL) returns. */
static const char *message(const HocMesh *mesh) {
  const char *m = hoc_mesh_last_error(mesh);
  return m ? m : "";
}

/* st must be one of the expected statuses (list ends with HOC_OK) and come with a message. */
static void expect_(int line, const char *what, HocStatus st, const HocMesh *mesh, const HocStatus *allowed) {
  int ok = 0;
  for (const HocStatus *a = allowed; *a != HOC_OK; ++a) ok |= st == *a;
  /* Without a handle (a failed create, a NULL handle) the message is the calling
   * thread's, from hoc_mesh_last_error(NULL): required all the same. */
  const char *m = message(mesh);
  if (!ok || !*m) {
    fprintf(stderr, "t100:%d: %s: got %d (%s), message \"%s\"; expected", line, what, st,
            hoc_status_string(st), m);
    for (const HocStatus *a = allowed; *a != HOC_OK; ++a) fprintf(stderr, " %d", *a);
    fprintf(stderr, " with a message\n");
    exit(1);
  }
  printf("ok %-58s %-2d %-24s \"%s\"\n", what, st, hoc_status_string(st), m);
  ++n_cases;
}
#define EXPECT(what, call, mesh, ...)                                  \
  do {                                                                 \
    const HocStatus allowed_[] = {__VA_ARGS__, HOC_OK};                \
    HocStatus st__ = (call);                                           \
    expect_(__LINE__, what, st__, mesh, allowed_);                     \
  } while (0)

#define NULLP HOC_ERROR_NULL_POINTER
#define BADARG HOC_ERROR_INVALID_ARGUMENT
#define BADMESH HOC_ERROR_INVALID_MESH

/* ---- a 2D square of 2 triangles ---- */
static const double sq[] = {0, 0, 1, 0, 1, 1, 0, 1};
static const int64_t sq_cells[] = {0, 1, 2, 0, 2, 3};

static void create_fails(const char *what, int dim, size_t nv, const double *x, size_t nc,
                         const int64_t *c, HocStatus a, HocStatus b) {
  HocMesh *mesh = (HocMesh *)0x1; /* must be overwritten or left alone, never used */
  HocMesh *sentinel = mesh;
  HocStatus st = hoc_mesh_create(dim, nv, x, nc, c, &mesh);
  CHECK(st != HOC_OK, "%s: create succeeded", what);
  CHECK(mesh == NULL || mesh == sentinel, "%s: failed create returned a handle", what);
  EXPECT(what, st, NULL, a, b);
}

/* ---- the 3D fixture used for runs ---- */
static FixtureMesh fx;

static HocMesh *fixture_handle(HocProjectFn proj, void *user) {
  HocMesh *mesh = NULL;
  CHECK_OK(NULL, hoc_mesh_create(3, fx.n_vertices, fx.coords, fx.n_cells, fx.cells, &mesh));
  CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, fx.n_facets, fx.facets, fx.facet_tags));
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj, user));
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 3, HOC_SPACING_OPTIMAL));
  return mesh;
}

typedef struct Snapshot {
  size_t n;
  double *x;
} Snapshot;

static Snapshot snapshot(const HocMesh *mesh) {
  Snapshot s;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &s.n));
  s.x = (double *)malloc(sizeof(double) * 3 * s.n);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, s.n, s.x));
  return s;
}
static void check_unchanged(const char *what, const HocMesh *mesh, Snapshot *before) {
  Snapshot now = snapshot(mesh);
  CHECK(now.n == before->n, "%s: node count %zu -> %zu after a failed run", what, before->n, now.n);
  CHECK(memcmp(now.x, before->x, sizeof(double) * 3 * now.n) == 0,
        "%s: nodes changed by a failed run", what);
  free(now.x);
}

/* A failed run: expected status, message, nodes bitwise as before. */
static void run_fails(const char *what, HocMesh *mesh, int increments, HocStatus a, HocStatus b, HocStatus c) {
  Snapshot before = snapshot(mesh);
  EXPECT(what, hoc_mesh_run_increments(mesh, increments), mesh, a, b, c);
  check_unchanged(what, mesh, &before);
  free(before.x);
}

/* ---- projectors and progress callbacks that misbehave ---- */
static int proj_error(void *u, int d, int t, size_t n, const double *in, double *out) {
  (void)u; (void)d; (void)t; (void)n; (void)in; (void)out;
  return 7;
}
static int proj_nan(void *u, int d, int t, size_t n, const double *in, double *out) {
  int st = sphere_box_projector(u, d, t, n, in, out);
  out[3 * (n / 2) + 1] = NAN;
  return st;
}
static int proj_inf(void *u, int d, int t, size_t n, const double *in, double *out) {
  int st = sphere_box_projector(u, d, t, n, in, out);
  out[0] = INFINITY;
  return st;
}
static int proj_far(void *u, int d, int t, size_t n, const double *in, double *out) {
  int st = sphere_box_projector(u, d, t, n, in, out);
  if (t == 1) out[3 * (n / 2)] += 1e3;
  return st;
}
static int cancel_stage = -1;
static int progress_cancel(void *u, int stage, int step, int total) {
  (void)step; (void)total;
  if (u) ++*(int *)u;
  return stage == cancel_stage;
}

int main(void) {
  /* ---- NULL handling, destroy ---- */
  CHECK_OK(NULL, hoc_mesh_destroy(NULL));
  HocMesh *none = NULL;
  CHECK_OK(NULL, hoc_mesh_destroy(&none));
  CHECK(hoc_mesh_last_error(NULL) != NULL, "last_error(NULL) is NULL");

  HocMesh *mesh = NULL;
  CHECK_OK(NULL, hoc_mesh_create(2, 4, sq, 2, sq_cells, &mesh));
  CHECK(mesh != NULL, "no handle");
  CHECK(strcmp(hoc_mesh_last_error(mesh), "") == 0, "fresh handle has an error: %s", hoc_mesh_last_error(mesh));
  size_t n = 0, nc = 0, npc = 0;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n));
  CHECK(n == 4, "p=1 square has %zu nodes", n);
  CHECK_OK(mesh, hoc_mesh_cell_count(mesh, &nc, &npc));
  CHECK(nc == 2 && npc == 3, "cell count %zu x %zu", nc, npc);
  double x[8];
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, 4, x));
  CHECK(memcmp(x, sq, sizeof x) == 0, "nodes are not the vertices");
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 4, HOC_SPACING_EQUISPACED));
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n));
  CHECK(n == 25, "p=4 square has %zu nodes, expected 25", n); /* 5 x 5 lattice */
  CHECK_OK(mesh, hoc_mesh_cell_count(mesh, &nc, &npc));
  CHECK(npc == 15, "p=4 triangle has %zu nodes", npc);

  /* ---- every function with a NULL handle or NULL output ---- */
  HocQuality q;
  HocTimings tm;
  double d;
  int64_t i64 = 0, ids[3] = {0, 1, 2};
  int32_t i32 = 1;
  EXPECT("create: out NULL", hoc_mesh_create(2, 4, sq, 2, sq_cells, NULL), NULL, NULLP);
  create_fails("create: coords NULL", 2, 4, NULL, 2, sq_cells, NULLP, NULLP);
  create_fails("create: cells NULL", 2, 4, sq, 2, NULL, NULLP, NULLP);
  EXPECT("set_boundary: NULL handle", hoc_mesh_set_boundary(NULL, 0, ids, &i32), NULL, NULLP);
  EXPECT("set_feature_edges: NULL handle", hoc_mesh_set_feature_edges(NULL, 0, ids, &i32), NULL, NULLP);
  EXPECT("set_projector: NULL handle", hoc_mesh_set_projector(NULL, sphere_box_projector, NULL), NULL, NULLP);
  EXPECT("set_progress: NULL handle", hoc_mesh_set_progress(NULL, progress_cancel, NULL), NULL, NULLP);
  EXPECT("set_threads: NULL handle", hoc_mesh_set_threads(NULL, 1), NULL, NULLP);
  EXPECT("set_remove_caps: NULL handle", hoc_mesh_set_remove_caps(NULL, 1), NULL, NULLP);
  EXPECT("set_retry: NULL handle", hoc_mesh_set_retry(NULL, 1), NULL, NULLP);
  EXPECT("set_tangent_first: NULL handle", hoc_mesh_set_tangent_first(NULL, 1), NULL, NULLP);
  {
    int kept = -1;
    EXPECT("retry: NULL handle", hoc_mesh_retry(NULL, &kept, NULL, 0, NULL), NULL, NULLP);
    EXPECT("retry: caps_kept NULL", hoc_mesh_retry(mesh, NULL, NULL, 0, NULL), mesh, NULLP);
    /* Before any run: not retried, an empty message of length 0. */
    char msg[4] = "xyz";
    size_t len = 99;
    CHECK_OK(mesh, hoc_mesh_retry(mesh, &kept, &len, sizeof msg, msg));
    CHECK(kept == 0 && len == 0 && msg[0] == '\0', "retry before a run: kept %d, len %zu, msg '%s'", kept, len, msg);
  }
  EXPECT("get_input_cells: NULL handle", hoc_mesh_get_input_cells(NULL, 0, NULL), NULL, NULLP);
  EXPECT("set_order: NULL handle", hoc_mesh_set_order(NULL, 2, HOC_SPACING_OPTIMAL), NULL, NULLP);
  EXPECT("set_material: NULL handle", hoc_mesh_set_material(NULL, HOC_MATERIAL_LINEAR_ELASTIC, 1, 0.3), NULL, NULLP);
  EXPECT("set_formulation: NULL handle", hoc_mesh_set_formulation(NULL, HOC_FORMULATION_LINEAR), NULL, NULLP);
  EXPECT("set_newton: NULL handle", hoc_mesh_set_newton(NULL, 1e-6, 10), NULL, NULLP);
  EXPECT("set_fibres: NULL handle", hoc_mesh_set_fibres(NULL, 0, NULL), NULL, NULLP);
  EXPECT("run_increments: NULL handle", hoc_mesh_run_increments(NULL, 1), NULL, NULLP);
  EXPECT("quality: NULL handle", hoc_mesh_quality(NULL, &q), NULL, NULLP);
  EXPECT("timings: NULL handle", hoc_mesh_timings(NULL, &tm), NULL, NULLP);
  EXPECT("cell_quality: NULL handle", hoc_mesh_cell_quality(NULL, 3, 2, x), NULL, NULLP);
  EXPECT("node_count: NULL handle", hoc_mesh_node_count(NULL, &n), NULL, NULLP);
  EXPECT("cell_count: NULL handle", hoc_mesh_cell_count(NULL, &nc, &npc), NULL, NULLP);
  EXPECT("get_nodes: NULL handle", hoc_mesh_get_nodes(NULL, HOC_ORDERING_NATIVE, 4, x), NULL, NULLP);
  EXPECT("get_cells: NULL handle", hoc_mesh_get_cells(NULL, HOC_ORDERING_NATIVE, 1, &i64), NULL, NULLP);
  EXPECT("write: NULL handle", hoc_mesh_write(NULL, "x.msh"), NULL, NULLP);
  EXPECT("quality: out NULL", hoc_mesh_quality(mesh, NULL), mesh, NULLP);
  EXPECT("timings: out NULL", hoc_mesh_timings(mesh, NULL), mesh, NULLP);
  EXPECT("cell_quality: out NULL", hoc_mesh_cell_quality(mesh, 3, 2, NULL), mesh, NULLP);
  EXPECT("node_count: out NULL", hoc_mesh_node_count(mesh, NULL), mesh, NULLP);
  EXPECT("cell_count: out NULL", hoc_mesh_cell_count(mesh, NULL, &npc), mesh, NULLP);
  EXPECT("cell_count: nodes_per_cell NULL", hoc_mesh_cell_count(mesh, &nc, NULL), mesh, NULLP);
  EXPECT("get_nodes: coords NULL", hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, 25, NULL), mesh, NULLP);
  EXPECT("get_cells: cells NULL", hoc_mesh_get_cells(mesh, HOC_ORDERING_NATIVE, 30, NULL), mesh, NULLP);
  EXPECT("write: path NULL", hoc_mesh_write(mesh, NULL), mesh, NULLP);
  EXPECT("set_boundary: facets NULL", hoc_mesh_set_boundary(mesh, 1, NULL, &i32), mesh, NULLP);
  EXPECT("set_boundary: tags NULL", hoc_mesh_set_boundary(mesh, 1, ids, NULL), mesh, NULLP);

  /* ---- buffer sizes and enum values on a valid handle ---- */
  double big[2 * 25];
  int64_t cbuf[30];
  EXPECT("get_nodes: n_nodes too small", hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, 24, big), mesh, HOC_ERROR_BUFFER_SIZE);
  EXPECT("get_nodes: n_nodes too large", hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, 26, big), mesh, HOC_ERROR_BUFFER_SIZE);
  EXPECT("get_cells: len too small", hoc_mesh_get_cells(mesh, HOC_ORDERING_NATIVE, 29, cbuf), mesh, HOC_ERROR_BUFFER_SIZE);
  EXPECT("cell_quality: n wrong", hoc_mesh_cell_quality(mesh, 3, 1, &d), mesh, HOC_ERROR_BUFFER_SIZE);
  EXPECT("cell_quality: measure 0", hoc_mesh_cell_quality(mesh, 0, 2, x), mesh, BADARG);
  EXPECT("cell_quality: measure 4", hoc_mesh_cell_quality(mesh, 4, 2, x), mesh, BADARG);
  EXPECT("get_cells: ordering 42", hoc_mesh_get_cells(mesh, (HocNodeOrdering)42, 30, cbuf), mesh, BADARG);
  EXPECT("set_order: 0", hoc_mesh_set_order(mesh, 0, HOC_SPACING_OPTIMAL), mesh, BADARG);
  EXPECT("set_order: 11", hoc_mesh_set_order(mesh, 11, HOC_SPACING_OPTIMAL), mesh, BADARG);
  EXPECT("set_order: -1", hoc_mesh_set_order(mesh, -1, HOC_SPACING_OPTIMAL), mesh, BADARG);
  EXPECT("set_order: spacing 42", hoc_mesh_set_order(mesh, 2, (HocNodeSpacing)42), mesh, BADARG);
  EXPECT("set_material: nu = 0.5", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1, 0.5), mesh, BADARG);
  EXPECT("set_material: nu = 0.7", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1, 0.7), mesh, BADARG);
  EXPECT("set_material: nu = -0.1", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1, -0.1), mesh, BADARG);
  EXPECT("set_material: nu NaN", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1, NAN), mesh, BADARG);
  EXPECT("set_material: E = 0", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 0, 0.3), mesh, BADARG);
  EXPECT("set_material: E = -1", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, -1, 0.3), mesh, BADARG);
  EXPECT("set_material: E NaN", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, NAN, 0.3), mesh, BADARG);
  EXPECT("set_material: E inf", hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, INFINITY, 0.3), mesh, BADARG);
  EXPECT("set_material: model 42", hoc_mesh_set_material(mesh, (HocMaterial)42, 1, 0.3), mesh, BADARG);
  EXPECT("set_material: model -1", hoc_mesh_set_material(mesh, (HocMaterial)-1, 1, 0.3), mesh, BADARG);
  EXPECT("set_formulation: 42", hoc_mesh_set_formulation(mesh, (HocFormulation)42), mesh, BADARG);
  EXPECT("set_formulation: -1", hoc_mesh_set_formulation(mesh, (HocFormulation)-1), mesh, BADARG);
  EXPECT("set_newton: max_iterations -1", hoc_mesh_set_newton(mesh, 1e-6, -1), mesh, BADARG);
  {
    const double fib[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}; /* the square has 2 cells */
    EXPECT("set_fibres: n_cells 1 (mesh has 2)", hoc_mesh_set_fibres(mesh, 1, fib), mesh, HOC_ERROR_BUFFER_SIZE);
    EXPECT("set_fibres: n_cells 3 (mesh has 2)", hoc_mesh_set_fibres(mesh, 3, fib), mesh, HOC_ERROR_BUFFER_SIZE);
    CHECK_OK(mesh, hoc_mesh_set_fibres(mesh, 2, fib));
    CHECK_OK(mesh, hoc_mesh_set_fibres(mesh, 0, NULL));
    CHECK_OK(mesh, hoc_mesh_set_newton(mesh, 1e-8, 50));
  }
  EXPECT("set_threads: -1", hoc_mesh_set_threads(mesh, -1), mesh, BADARG);
  EXPECT("set_remove_caps: 2", hoc_mesh_set_remove_caps(mesh, 2), mesh, BADARG);
  EXPECT("write: unknown extension", hoc_mesh_write(mesh, "out.xyz"), mesh, BADARG, HOC_ERROR_IO);
  EXPECT("write: missing directory", hoc_mesh_write(mesh, "/nonexistent-dir/out.msh"), mesh, HOC_ERROR_IO);
  /* A good call after a failed one: the handle is still usable, and the settings survived. */
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n));
  CHECK(n == 25, "a failed set_order changed the order: %zu nodes", n);
  CHECK_OK(mesh, hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1.0, 0.3));
  CHECK_OK(mesh, hoc_mesh_set_formulation(mesh, HOC_FORMULATION_ILE));
  CHECK_OK(mesh, hoc_mesh_set_formulation(mesh, HOC_FORMULATION_LINEAR));
  CHECK_OK(mesh, hoc_mesh_destroy(&mesh));
  CHECK(mesh == NULL, "destroy did not clear the handle");

  /* ---- bad meshes at create ---- */
  const double sq_nan[] = {0, 0, 1, NAN, 1, 1, 0, 1};
  const double sq_inf[] = {0, 0, 1, 0, INFINITY, 1, 0, 1};
  const int64_t out_of_range[] = {0, 1, 2, 0, 2, 4};
  const int64_t negative[] = {0, 1, 2, 0, 2, -1};
  const int64_t repeated[] = {0, 1, 2, 0, 2, 2};
  const double line[] = {0, 0, 1, 0, 2, 0, 0, 1};
  const int64_t collinear[] = {0, 1, 2, 0, 2, 3};
  create_fails("create: dim 1", 1, 4, sq, 2, sq_cells, BADARG, BADARG);
  create_fails("create: dim 4", 4, 2, sq, 1, sq_cells, BADARG, BADARG);
  create_fails("create: zero cells", 2, 4, sq, 0, sq_cells, BADARG, BADMESH);
  create_fails("create: zero vertices", 2, 0, sq, 2, sq_cells, BADARG, BADMESH);
  create_fails("create: vertex id out of range", 2, 4, sq, 2, out_of_range, BADARG, BADMESH);
  create_fails("create: negative vertex id", 2, 4, sq, 2, negative, BADARG, BADMESH);
  create_fails("create: repeated vertex in a cell", 2, 4, sq, 2, repeated, BADARG, BADMESH);
  create_fails("create: NaN coordinate", 2, 4, sq_nan, 2, sq_cells, BADARG, BADMESH);
  create_fails("create: infinite coordinate", 2, 4, sq_inf, 2, sq_cells, BADARG, BADMESH);
  create_fails("create: degenerate triangle", 2, 4, line, 2, collinear, BADARG, BADMESH);
  {
    const double tet[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}; /* flat */
    const int64_t c[] = {0, 1, 2, 3};
    create_fails("create: degenerate (flat) tet", 3, 4, tet, 1, c, BADARG, BADMESH);
  }
  {
    /* Inverted cells are accepted and reoriented: a clockwise triangle and a left-handed tet. */
    const int64_t cw[] = {0, 2, 1, 0, 3, 2};
    CHECK_OK(NULL, hoc_mesh_create(2, 4, sq, 2, cw, &mesh));
    CHECK_OK(mesh, hoc_mesh_set_order(mesh, 3, HOC_SPACING_OPTIMAL));
    CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
    CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
    CHECK(q.n_invalid == 0 && q.min_q3 > 0.999, "clockwise triangles: %zu invalid, min Q3 %g", q.n_invalid, q.min_q3);
    CHECK_OK(mesh, hoc_mesh_destroy(&mesh));
    const double tet[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    const int64_t left[] = {0, 2, 1, 3};
    CHECK_OK(NULL, hoc_mesh_create(3, 4, tet, 1, left, &mesh));
    CHECK_OK(mesh, hoc_mesh_set_order(mesh, 2, HOC_SPACING_OPTIMAL));
    CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
    CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
    CHECK(q.n_invalid == 0 && q.min_q3 > 0.999, "inverted tet: %zu invalid, min Q3 %g", q.n_invalid, q.min_q3);
    int64_t cc[10];
    CHECK_OK(mesh, hoc_mesh_get_cells(mesh, HOC_ORDERING_NATIVE, 10, cc));
    CHECK(cc[0] != cc[1] && cc[0] < 4 && cc[1] < 4 && cc[2] < 4 && cc[3] < 4,
          "the first 4 nodes of a cell are not its vertices");
    CHECK_OK(mesh, hoc_mesh_destroy(&mesh));
    printf("ok %-58s accepted, reoriented, valid after a run\n", "create: inverted triangle and tet");
    n_cases += 2;
  }

  /* ---- boundary facets and feature edges ---- */
  CHECK(fixture_tetgen_sphere_box(1, 1, 2.0, &fx) == 0, "TetGen failed");
  printf("fixture: %zu vertices, %zu tets, %zu boundary triangles\n", fx.n_vertices, fx.n_cells, fx.n_facets);
  size_t calls = 0;
  mesh = fixture_handle(sphere_box_projector, &calls);
  {
    /* An interior face: a face of a tet that is not a boundary triangle. */
    int64_t interior[3] = {-1, -1, -1};
    for (size_t c = 0; c < fx.n_cells && interior[0] < 0; ++c)
      for (int omit = 0; omit < 4 && interior[0] < 0; ++omit) {
        int64_t f[3];
        int j = 0;
        for (int k = 0; k < 4; ++k)
          if (k != omit) f[j++] = fx.cells[4 * c + k];
        int on_boundary = 0;
        for (size_t b = 0; b < fx.n_facets && !on_boundary; ++b) {
          int same = 0;
          for (int a = 0; a < 3; ++a)
            for (int e = 0; e < 3; ++e) same += f[a] == fx.facets[3 * b + e];
          on_boundary = same == 3;
        }
        if (!on_boundary) memcpy(interior, f, sizeof f);
      }
    CHECK(interior[0] >= 0, "no interior face");
    int32_t tag = 1;
    Snapshot before = snapshot(mesh);
    HocStatus st = hoc_mesh_set_boundary(mesh, 1, interior, &tag);
    if (st == HOC_OK) st = hoc_mesh_run_increments(mesh, 1); /* caught at the run at the latest */
    EXPECT("set_boundary: facet not on the boundary", st, mesh, BADMESH, BADARG);
    check_unchanged("set_boundary: facet not on the boundary", mesh, &before);
    free(before.x);
    int64_t not_a_face[3] = {fx.facets[0], fx.facets[1], (int64_t)fx.n_vertices};
    EXPECT("set_boundary: vertex id out of range", hoc_mesh_set_boundary(mesh, 1, not_a_face, &tag), mesh, BADMESH, BADARG);
    int64_t rep[3] = {fx.facets[0], fx.facets[0], fx.facets[1]};
    st = hoc_mesh_set_boundary(mesh, 1, rep, &tag);
    if (st == HOC_OK) st = hoc_mesh_run_increments(mesh, 1);
    EXPECT("set_boundary: repeated vertex", st, mesh, BADMESH, BADARG);
    int64_t edge[2] = {interior[0], (int64_t)fx.n_vertices + 5};
    st = hoc_mesh_set_feature_edges(mesh, 1, edge, &tag);
    if (st == HOC_OK) st = hoc_mesh_run_increments(mesh, 1);
    EXPECT("set_feature_edges: vertex id out of range", st, mesh, BADMESH, BADARG);
    EXPECT("set_feature_edges: edges NULL", hoc_mesh_set_feature_edges(mesh, 1, NULL, &tag), mesh, NULLP);
    CHECK_OK(mesh, hoc_mesh_set_feature_edges(mesh, 0, NULL, NULL));
    CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, fx.n_facets, fx.facets, fx.facet_tags));
  }

  /* ---- runs that fail: status, message, nodes bitwise unchanged ---- */
  run_fails("run: 0 increments", mesh, 0, BADARG, BADARG, BADARG);
  run_fails("run: -1 increments", mesh, -1, BADARG, BADARG, BADARG);
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_error, NULL));
  run_fails("run: projector returns an error", mesh, 1, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION);
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_nan, NULL));
  run_fails("run: projector returns NaN", mesh, 1, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION);
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_inf, NULL));
  run_fails("run: projector returns inf", mesh, 1, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION);
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_far, NULL));
  run_fails("run: projector returns a point 1e3 away", mesh, 1, HOC_ERROR_PROJECTION, HOC_ERROR_INVALID_ELEMENT, HOC_ERROR_SOLVER);
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, NULL, NULL));
  run_fails("run: tagged boundary but no projector", mesh, 1, BADARG, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION);
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, sphere_box_projector, &calls));
  for (cancel_stage = 0; cancel_stage <= 3; ++cancel_stage) {
    int progress_calls = 0;
    char what[64];
    snprintf(what, sizeof what, "run: progress cancels at stage %d", cancel_stage);
    CHECK_OK(mesh, hoc_mesh_set_progress(mesh, progress_cancel, &progress_calls));
    run_fails(what, mesh, 1, HOC_ERROR_CANCELLED, HOC_ERROR_CANCELLED, HOC_ERROR_CANCELLED);
    CHECK(progress_calls > 0, "progress never called");
  }
  cancel_stage = -1;

  /* A good run after all that, then a failed run keeps the curved nodes. */
  int progress_calls = 0;
  CHECK_OK(mesh, hoc_mesh_set_progress(mesh, progress_cancel, &progress_calls));
  Snapshot straight = snapshot(mesh);
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
  CHECK(progress_calls >= 4, "progress called %d times in a run", progress_calls);
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
  CHECK(q.n_invalid == 0, "the fixture curved at p=3 has %zu invalid cells", q.n_invalid);
  Snapshot curved = snapshot(mesh);
  CHECK(memcmp(curved.x, straight.x, sizeof(double) * 3 * curved.n) != 0, "the run moved nothing");
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_error, NULL));
  run_fails("run after a good run: projector error", mesh, 1, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION, HOC_ERROR_PROJECTION);
  check_unchanged("the curved result survives a failed run", mesh, &curved);
  HocQuality q2;
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q2));
  CHECK(memcmp(&q, &q2, sizeof q) == 0 || (q.min_q3 == q2.min_q3 && q.n_invalid == q2.n_invalid),
        "quality changed by a failed run");
  /* Changing the order discards the curved result. */
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 2, HOC_SPACING_OPTIMAL));
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 3, HOC_SPACING_OPTIMAL));
  check_unchanged("set_order after a run gives the straight mesh", mesh, &straight);
  free(straight.x);
  free(curved.x);
  /* Last, so that a failure here leaves every case above checked. */
  /* Formulations IIL/CIL/NONLINEAR need a hyperelastic material: caught at the run. */
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, sphere_box_projector, NULL));
  CHECK_OK(mesh, hoc_mesh_set_progress(mesh, NULL, NULL));
  CHECK_OK(mesh, hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1.0, 0.3));
  CHECK_OK(mesh, hoc_mesh_set_formulation(mesh, HOC_FORMULATION_CIL));
  run_fails("run: CIL with a linear elastic material", mesh, 1, BADARG, BADARG, BADARG);
  CHECK_OK(mesh, hoc_mesh_set_formulation(mesh, HOC_FORMULATION_NONLINEAR));
  run_fails("run: NONLINEAR with a linear elastic material", mesh, 1, BADARG, BADARG, BADARG);
  EXPECT("set_newton: tolerance 0", hoc_mesh_set_newton(mesh, 0.0, 10), mesh, BADARG);
  EXPECT("set_newton: tolerance -1", hoc_mesh_set_newton(mesh, -1.0, 10), mesh, BADARG);
  EXPECT("set_newton: tolerance NaN", hoc_mesh_set_newton(mesh, NAN, 10), mesh, BADARG);
  EXPECT("set_newton: max_iterations 0", hoc_mesh_set_newton(mesh, 1e-6, 0), mesh, BADARG);
  CHECK_OK(mesh, hoc_mesh_destroy(&mesh));
  fixture_mesh_free(&fx);
  printf("%d bad inputs rejected with a status and a message\n", n_cases);
  return 0;
}
