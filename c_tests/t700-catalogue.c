/* Bad-input catalogue of the C ABI. Each case gives the library one
 * malformed input or call sequence and checks three things:
 *   - the exact status code;
 *   - a substring of hoc_mesh_last_error (the handle's, or the thread's when
 *     there is no handle);
 *   - that nothing changed: a failed hoc_mesh_create returns no handle and
 *     leaves the caller's arrays as they were; a failed call on a handle
 *     leaves its counts, nodes (bitwise), connectivity and input-cell map as
 *     they were.
 * The meshes are small (a unit square, a unit cube of 6 tets) so that the
 * test runs in well under a second, also under valgrind and the sanitizers.
 * The .msh reader's and the CLI's catalogue is tests/catalogue.rs. */
#include "test_common.h"

#include <stdint.h>

static int n_cases = 0;

static const char *message(const HocMesh *mesh) {
  const char *m = hoc_mesh_last_error(mesh);
  return m ? m : "(null)";
}

/* ---- what a handle looks like from outside ---- */
typedef struct State {
  size_t nn, nc, npc;
  double *x;
  int64_t *cells, *input;
} State;

static State state(const HocMesh *mesh, int dim) {
  State s;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &s.nn));
  CHECK_OK(mesh, hoc_mesh_cell_count(mesh, &s.nc, &s.npc));
  s.x = (double *)malloc(sizeof(double) * dim * s.nn);
  s.cells = (int64_t *)malloc(sizeof(int64_t) * s.nc * s.npc);
  s.input = (int64_t *)malloc(sizeof(int64_t) * s.nc);
  CHECK(s.x && s.cells && s.input, "out of memory");
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, s.nn, s.x));
  CHECK_OK(mesh, hoc_mesh_get_cells(mesh, HOC_ORDERING_NATIVE, s.nc * s.npc, s.cells));
  CHECK_OK(mesh, hoc_mesh_get_input_cells(mesh, s.nc, s.input));
  return s;
}

static void state_free(State *s) {
  free(s->x);
  free(s->cells);
  free(s->input);
}

static int state_equal(const State *a, const State *b, int dim) {
  return a->nn == b->nn && a->nc == b->nc && a->npc == b->npc &&
         memcmp(a->x, b->x, sizeof(double) * dim * a->nn) == 0 &&
         memcmp(a->cells, b->cells, sizeof(int64_t) * a->nc * a->npc) == 0 &&
         memcmp(a->input, b->input, sizeof(int64_t) * a->nc) == 0;
}

/* Status and message of one case; `mesh` is the handle whose message to read
 * (NULL: the thread's). */
static void verdict(int line, const char *what, HocStatus got, HocStatus want, const HocMesh *mesh,
                    const char *substring) {
  const char *m = message(mesh);
  if (got != want || strstr(m, substring) == NULL || (want != HOC_OK && !*m) || (want == HOC_OK && *m)) {
    fprintf(stderr, "t700:%d: %s: got status %d (%s), message \"%s\"; expected %d (%s) with \"%s\"\n", line, what,
            got, hoc_status_string(got), m, want, hoc_status_string(want), substring);
    exit(1);
  }
  printf("ok %2d %-56s %d %-22s \"%s\"\n", ++n_cases, what, got, hoc_status_string(got), m);
}

/* A call on a live handle: expected status and message, and the handle's state
 * unchanged. */
#define ON_HANDLE(what, mesh, dim, call, want, substring)                                       \
  do {                                                                                          \
    State before_ = state(mesh, dim);                                                           \
    HocStatus st_ = (call);                                                                     \
    verdict(__LINE__, what, st_, want, mesh, substring);                                        \
    State after_ = state(mesh, dim);                                                            \
    CHECK(state_equal(&before_, &after_, dim), "%s: the mesh changed (%zu -> %zu nodes)", what, \
          before_.nn, after_.nn);                                                               \
    state_free(&before_);                                                                       \
    state_free(&after_);                                                                        \
  } while (0)

/* A create that must fail: status, the thread's message, no handle, and the
 * caller's arrays untouched (compared with copies made before the call). */
static void create_fails_(int line, const char *what, int dim, size_t nv, const double *x, size_t x_len, size_t nc,
                          const int64_t *c, size_t c_len, HocStatus want, const char *substring) {
  double *x0 = (double *)malloc(sizeof(double) * (x_len + 1));
  int64_t *c0 = (int64_t *)malloc(sizeof(int64_t) * (c_len + 1));
  if (x) memcpy(x0, x, sizeof(double) * x_len);
  if (c) memcpy(c0, c, sizeof(int64_t) * c_len);
  HocMesh *mesh = (HocMesh *)&line; /* a failed create must set it to NULL */
  HocStatus st = hoc_mesh_create(dim, nv, x, nc, c, &mesh);
  verdict(line, what, st, want, NULL, substring);
  CHECK(mesh == NULL, "%s: a failed create left a handle", what);
  CHECK(!x || memcmp(x0, x, sizeof(double) * x_len) == 0, "%s: coords changed", what);
  CHECK(!c || memcmp(c0, c, sizeof(int64_t) * c_len) == 0, "%s: cells changed", what);
  free(x0);
  free(c0);
}
#define CREATE_FAILS(what, dim, nv, x, nc, c, want, substring)                                              \
  create_fails_(__LINE__, what, dim, nv, x, sizeof(x) / sizeof(double), nc, c, sizeof(c) / sizeof(int64_t), \
                want, substring)

/* ---- meshes ---- */
static const double sq[] = {0, 0, 1, 0, 1, 1, 0, 1};
static const int64_t sq_cells[] = {0, 1, 2, 0, 2, 3};
static const int64_t sq_edges[] = {0, 1, 1, 2, 2, 3, 3, 0};
static const int32_t sq_tags[] = {1, 1, 1, 1};

/* Unit cube, vertex i at (i & 1, i >> 1 & 1, i >> 2 & 1), 6 tets around the diagonal 0-7. */
static double cube[24];
static const int64_t cube_cells[] = {0, 1, 3, 7, 0, 1, 5, 7, 0, 2, 3, 7, 0, 2, 6, 7, 0, 4, 5, 7, 0, 4, 6, 7};
static int64_t cube_facets[3 * 12];
static int32_t cube_tags[12]; /* 1..6: the cube face (2 * axis + side + 1) */
static size_t cube_n_facets = 0;

static int same_face(const int64_t *a, const int64_t *b) {
  int n = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) n += a[i] == b[j];
  return n == 3;
}

static void make_cube(void) {
  for (int i = 0; i < 8; ++i) {
    cube[3 * i] = i & 1;
    cube[3 * i + 1] = (i >> 1) & 1;
    cube[3 * i + 2] = (i >> 2) & 1;
  }
  /* Boundary facets: faces of exactly one tet. */
  for (int c = 0; c < 6; ++c)
    for (int omit = 0; omit < 4; ++omit) {
      int64_t f[3];
      for (int k = 0, j = 0; k < 4; ++k)
        if (k != omit) f[j++] = cube_cells[4 * c + k];
      int count = 0;
      for (int c2 = 0; c2 < 6; ++c2)
        for (int o2 = 0; o2 < 4; ++o2) {
          int64_t g[3];
          for (int k = 0, j = 0; k < 4; ++k)
            if (k != o2) g[j++] = cube_cells[4 * c2 + k];
          count += same_face(f, g);
        }
      if (count != 1) continue;
      memcpy(cube_facets + 3 * cube_n_facets, f, sizeof f);
      for (int axis = 0; axis < 3; ++axis) {
        double v0 = cube[3 * f[0] + axis];
        if (cube[3 * f[1] + axis] == v0 && cube[3 * f[2] + axis] == v0) cube_tags[cube_n_facets] = 2 * axis + (int)v0 + 1;
      }
      ++cube_n_facets;
    }
  CHECK(cube_n_facets == 12, "the cube has %zu boundary triangles", cube_n_facets);
}

/* An interior face of the cube (a face of two tets). */
static const int64_t cube_interior_face[] = {0, 1, 7};

/* ---- projectors: user_data is unused unless said ---- */
/* The faces of a cube 2% larger (a dilation about the centre), so that a run
 * moves the nodes and solves; tags other than 1..6 are not known (return 3, as
 * a CAD kernel would). */
static int proj_cube(void *u, int d, int t, size_t n, const double *in, double *out) {
  (void)u;
  if (d != 2 || t < 1 || t > 6) return 3;
  for (size_t i = 0; i < 3 * n; ++i) out[i] = 0.5 + 1.02 * (in[i] - 0.5);
  return 0;
}
static int proj_error(void *u, int d, int t, size_t n, const double *in, double *out) {
  (void)u; (void)d; (void)t; (void)n; (void)in; (void)out;
  return 7;
}
static int proj_nan(void *u, int d, int t, size_t n, const double *in, double *out) {
  int st = proj_cube(u, d, t, n, in, out);
  out[3 * (n / 2) + 1] = NAN;
  return st;
}
static int proj_far(void *u, int d, int t, size_t n, const double *in, double *out) {
  (void)u; (void)d; (void)t;
  for (size_t i = 0; i < 3 * n; ++i) out[i] = in[i] + 1e6;
  return 0;
}
static int proj_huge(void *u, int d, int t, size_t n, const double *in, double *out) {
  (void)u; (void)d; (void)t; (void)in;
  for (size_t i = 0; i < 3 * n; ++i) out[i] = 1e308;
  return 0;
}
static int solver_fails(void *u, int64_t n, const int64_t *rp, const int64_t *ci, const double *v, const double *b,
                        double *x) {
  (void)u; (void)n; (void)rp; (void)ci; (void)v; (void)b; (void)x;
  return -4;
}
static int solver_nan(void *u, int64_t n, const int64_t *rp, const int64_t *ci, const double *v, const double *b,
                      double *x) {
  (void)u; (void)rp; (void)ci; (void)v; (void)b;
  for (int64_t i = 0; i < n; ++i) x[i] = NAN;
  return 0;
}
static int progress_cancel(void *u, int stage, int step, int total) {
  (void)u; (void)step; (void)total;
  return stage == 2; /* at the first increment */
}

/* A cube handle with its boundary tagged, the identity projector, p = 2. */
static HocMesh *cube_handle(void) {
  HocMesh *mesh = NULL;
  CHECK_OK(NULL, hoc_mesh_create(3, 8, cube, 6, cube_cells, &mesh));
  CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, cube_n_facets, cube_facets, cube_tags));
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_cube, NULL));
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 2, HOC_SPACING_OPTIMAL));
  CHECK_OK(mesh, hoc_mesh_set_threads(mesh, 1));
  return mesh;
}

int main(void) {
  make_cube();
  const size_t big = (size_t)1 << 40;

  /* ==== hoc_mesh_create ==== */
  verdict(__LINE__, "create: out NULL", hoc_mesh_create(2, 4, sq, 2, sq_cells, NULL), HOC_ERROR_NULL_POINTER, NULL,
          "out is NULL");
  create_fails_(__LINE__, "create: coords NULL", 2, 4, NULL, 0, 2, sq_cells, 6, HOC_ERROR_NULL_POINTER,
                "coords is NULL");
  create_fails_(__LINE__, "create: cells NULL", 2, 4, sq, 8, 2, NULL, 0, HOC_ERROR_NULL_POINTER, "cells is NULL");
  CREATE_FAILS("create: dim 1", 1, 4, sq, 2, sq_cells, HOC_ERROR_INVALID_ARGUMENT, "dim must be 2 or 3");
  CREATE_FAILS("create: dim 4", 4, 2, sq, 1, sq_cells, HOC_ERROR_INVALID_ARGUMENT, "dim must be 2 or 3");
  CREATE_FAILS("create: zero cells", 2, 4, sq, 0, sq_cells, HOC_ERROR_INVALID_MESH, "no cells");
  CREATE_FAILS("create: zero vertices", 2, 0, sq, 2, sq_cells, HOC_ERROR_INVALID_MESH, "there are 0 vertices");
  CREATE_FAILS("create: 2^40 vertices (small buffer)", 2, big, sq, 2, sq_cells, HOC_ERROR_INVALID_ARGUMENT,
               "n_vertices = 1099511627776 is too large");
  CREATE_FAILS("create: SIZE_MAX cells (small buffer)", 2, 4, sq, SIZE_MAX, sq_cells, HOC_ERROR_INVALID_ARGUMENT,
               "n_cells = ");
  CREATE_FAILS("create: SIZE_MAX/3 cells (size overflows)", 3, 8, cube, SIZE_MAX / 3, cube_cells,
               HOC_ERROR_INVALID_ARGUMENT, "too large");
  {
    const double x_nan[] = {0, 0, 1, NAN, 1, 1, 0, 1};
    const double x_inf[] = {0, 0, 1, 0, -INFINITY, 1, 0, 1};
    const double x_huge[] = {0, 0, 1e300, 0, 1e300, 1e300, 0, 1e300};
    const double x_tiny[] = {0, 0, 1e-300, 0, 1e-300, 1e-300, 0, 1e-300};
    CREATE_FAILS("create: NaN coordinate", 2, 4, x_nan, 2, sq_cells, HOC_ERROR_INVALID_MESH,
                 "vertex 1 has a non-finite coordinate");
    CREATE_FAILS("create: -inf coordinate", 2, 4, x_inf, 2, sq_cells, HOC_ERROR_INVALID_MESH,
                 "vertex 2 has a non-finite coordinate");
    CREATE_FAILS("create: 1e300 coordinates (measure overflows)", 2, 4, x_huge, 2, sq_cells,
                 HOC_ERROR_INVALID_MESH, "too large");
    CREATE_FAILS("create: 1e-300 coordinates (measure underflows)", 2, 4, x_tiny, 2, sq_cells,
                 HOC_ERROR_INVALID_MESH, "degenerate");
  }
  {
    const int64_t out_of_range[] = {0, 1, 2, 0, 2, 4};
    const int64_t negative[] = {0, 1, 2, 0, 2, -1};
    const int64_t int_min[] = {0, 1, 2, 0, 2, INT64_MIN};
    const int64_t repeated[] = {0, 1, 2, 0, 2, 2};
    const int64_t duplicate[] = {0, 1, 2, 0, 2, 3, 2, 0, 1};
    const int64_t flat_cells[] = {0, 1, 2};
    const double flat[] = {0, 0, 1, 1, 2, 2};
    CREATE_FAILS("create: vertex index out of range", 2, 4, sq, 2, out_of_range, HOC_ERROR_INVALID_MESH,
                 "cell 1 refers to vertex 4, but there are 4 vertices");
    CREATE_FAILS("create: negative vertex index", 2, 4, sq, 2, negative, HOC_ERROR_INVALID_MESH,
                 "cells[5] = -1 is negative");
    CREATE_FAILS("create: INT64_MIN vertex index", 2, 4, sq, 2, int_min, HOC_ERROR_INVALID_MESH, "is negative");
    CREATE_FAILS("create: vertex repeated in a cell", 2, 4, sq, 2, repeated, HOC_ERROR_INVALID_MESH,
                 "cell 1 repeats a vertex");
    CREATE_FAILS("create: duplicate cell (permuted)", 2, 4, sq, 3, duplicate, HOC_ERROR_INVALID_MESH,
                 "cells 0 and 2 have the same vertices");
    CREATE_FAILS("create: degenerate (collinear) triangle", 2, 3, flat, 1, flat_cells, HOC_ERROR_INVALID_MESH,
                 "degenerate");
  }
  {
    /* Three tets on one face (0, 1, 2): a non-manifold mesh. */
    const double x[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.2, 0.2, 1, 0.3, 0.3, -1, 1, 1, 0.5};
    const int64_t c[] = {0, 1, 2, 3, 0, 1, 2, 4, 0, 1, 2, 5};
    CREATE_FAILS("create: face shared by three tets (non-manifold)", 3, 6, x, 3, c, HOC_ERROR_INVALID_MESH,
                 "not manifold");
    /* Three triangles on one edge (0, 1) in 2D. */
    const double y[] = {0, 0, 1, 0, 0.5, 1, 0.5, -1, 0.3, 2};
    const int64_t t[] = {0, 1, 2, 0, 1, 3, 0, 1, 4};
    CREATE_FAILS("create: edge shared by three triangles (non-manifold)", 2, 5, y, 3, t, HOC_ERROR_INVALID_MESH,
                 "not manifold");
  }
  {
    /* Inverted cells are not an error: they are reoriented, the vertices kept. */
    const int64_t cw[] = {0, 2, 1, 0, 3, 2};
    HocMesh *m = NULL;
    verdict(__LINE__, "create: clockwise triangles (accepted, reoriented)", hoc_mesh_create(2, 4, sq, 2, cw, &m),
            HOC_OK, NULL, "");
    State s = state(m, 2);
    CHECK(s.nn == 4 && s.nc == 2 && memcmp(s.x, sq, sizeof sq) == 0, "inverted triangles: vertices changed");
    for (int k = 0; k < 6; k += 3) {
      const double *a = sq + 2 * s.cells[k], *b = sq + 2 * s.cells[k + 1], *c = sq + 2 * s.cells[k + 2];
      double area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
      CHECK(area2 > 0, "cell %d is still clockwise", k / 3);
    }
    state_free(&s);
    CHECK_OK(m, hoc_mesh_destroy(&m));
  }

  /* ==== boundary description (3D cube) ==== */
  HocMesh *mesh = NULL;
  CHECK_OK(NULL, hoc_mesh_create(3, 8, cube, 6, cube_cells, &mesh));
  {
    int32_t tag = 1;
    int64_t f2[6];
    int32_t t2[2] = {1, 2};
    ON_HANDLE("set_boundary: facets NULL", mesh, 3, hoc_mesh_set_boundary(mesh, 1, NULL, &tag),
              HOC_ERROR_NULL_POINTER, "facets is NULL");
    ON_HANDLE("set_boundary: entity_tags NULL", mesh, 3, hoc_mesh_set_boundary(mesh, 1, cube_facets, NULL),
              HOC_ERROR_NULL_POINTER, "entity_tags is NULL");
    ON_HANDLE("set_boundary: 2^40 facets (small buffer)", mesh, 3,
              hoc_mesh_set_boundary(mesh, big, cube_facets, cube_tags), HOC_ERROR_INVALID_ARGUMENT,
              "n_facets = 1099511627776 is too large");
    ON_HANDLE("set_boundary: interior face", mesh, 3, hoc_mesh_set_boundary(mesh, 1, cube_interior_face, &tag),
              HOC_ERROR_INVALID_MESH, "is not a boundary facet");
    memcpy(f2, cube_facets, 3 * sizeof(int64_t));
    f2[3] = cube_facets[2]; /* the same triangle, its vertices rotated */
    f2[4] = cube_facets[0];
    f2[5] = cube_facets[1];
    ON_HANDLE("set_boundary: facet tagged twice", mesh, 3, hoc_mesh_set_boundary(mesh, 2, f2, t2),
              HOC_ERROR_INVALID_MESH, "tagged twice");
    int64_t oor[3] = {0, 1, 8};
    ON_HANDLE("set_boundary: vertex index out of range", mesh, 3, hoc_mesh_set_boundary(mesh, 1, oor, &tag),
              HOC_ERROR_INVALID_MESH, "refers to vertex 8, but there are 8 vertices");
    int64_t neg[3] = {0, 1, -3};
    ON_HANDLE("set_boundary: negative vertex index", mesh, 3, hoc_mesh_set_boundary(mesh, 1, neg, &tag),
              HOC_ERROR_INVALID_MESH, "facets[2] = -3 is negative");
    int64_t edge_inside[2] = {0, 7}; /* the cube's diagonal: inside */
    ON_HANDLE("set_feature_edges: interior edge", mesh, 3, hoc_mesh_set_feature_edges(mesh, 1, edge_inside, &tag),
              HOC_ERROR_INVALID_MESH, "is not an edge of the boundary");
    ON_HANDLE("set_feature_edges: 2^40 edges (small buffer)", mesh, 3,
              hoc_mesh_set_feature_edges(mesh, big, edge_inside, &tag), HOC_ERROR_INVALID_ARGUMENT,
              "n_edges = 1099511627776 is too large");
  }
  {
    /* 2D: a boundary edge tagged twice, and an interior edge. */
    HocMesh *m2 = NULL;
    CHECK_OK(NULL, hoc_mesh_create(2, 4, sq, 2, sq_cells, &m2));
    const int64_t twice[] = {0, 1, 1, 0};
    const int32_t tt[] = {1, 1};
    ON_HANDLE("set_boundary 2D: edge tagged twice", m2, 2, hoc_mesh_set_boundary(m2, 2, twice, tt),
              HOC_ERROR_INVALID_MESH, "tagged twice");
    const int64_t diag[] = {0, 2};
    ON_HANDLE("set_boundary 2D: interior edge (diagonal)", m2, 2, hoc_mesh_set_boundary(m2, 1, diag, tt),
              HOC_ERROR_INVALID_MESH, "is not a boundary facet");
    ON_HANDLE("set_feature_edges 2D: feature edges are 3D only", m2, 2,
              hoc_mesh_set_feature_edges(m2, 1, sq_edges, sq_tags), HOC_ERROR_INVALID_MESH, "3D");
    CHECK_OK(m2, hoc_mesh_destroy(&m2));
  }

  /* ==== settings: orders and enums ==== */
  ON_HANDLE("set_order: 0", mesh, 3, hoc_mesh_set_order(mesh, 0, HOC_SPACING_OPTIMAL), HOC_ERROR_INVALID_ARGUMENT,
            "order");
  ON_HANDLE("set_order: 11", mesh, 3, hoc_mesh_set_order(mesh, 11, HOC_SPACING_OPTIMAL), HOC_ERROR_INVALID_ARGUMENT,
            "order");
  ON_HANDLE("set_order: INT_MIN", mesh, 3, hoc_mesh_set_order(mesh, INT32_MIN, HOC_SPACING_OPTIMAL),
            HOC_ERROR_INVALID_ARGUMENT, "order must be between 1 and 10");
  ON_HANDLE("set_order: spacing 2", mesh, 3, hoc_mesh_set_order(mesh, 2, (HocNodeSpacing)2),
            HOC_ERROR_INVALID_ARGUMENT, "unknown node spacing 2");
  ON_HANDLE("set_formulation: 5", mesh, 3, hoc_mesh_set_formulation(mesh, (HocFormulation)5),
            HOC_ERROR_INVALID_ARGUMENT, "unknown formulation 5");
  ON_HANDLE("set_formulation: -1", mesh, 3, hoc_mesh_set_formulation(mesh, (HocFormulation)-1),
            HOC_ERROR_INVALID_ARGUMENT, "unknown formulation -1");
  ON_HANDLE("set_material: model 6", mesh, 3, hoc_mesh_set_material(mesh, (HocMaterial)6, 1.0, 0.3),
            HOC_ERROR_INVALID_ARGUMENT, "unknown material 6");
  ON_HANDLE("set_material: E = inf", mesh, 3, hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, INFINITY, 0.3),
            HOC_ERROR_INVALID_ARGUMENT, "Young's modulus must be positive and finite");
  ON_HANDLE("set_material: nu = NaN", mesh, 3, hoc_mesh_set_material(mesh, HOC_MATERIAL_NEO_HOOKEAN, 1.0, NAN),
            HOC_ERROR_INVALID_ARGUMENT, "Poisson's ratio must be in [0, 0.5)");
  ON_HANDLE("set_newton: tolerance NaN", mesh, 3, hoc_mesh_set_newton(mesh, NAN, 10), HOC_ERROR_INVALID_ARGUMENT,
            "Newton tolerance must be positive");
  ON_HANDLE("set_threads: -1", mesh, 3, hoc_mesh_set_threads(mesh, -1), HOC_ERROR_INVALID_ARGUMENT,
            "n_threads must be >= 0");
  ON_HANDLE("set_threads: 4097", mesh, 3, hoc_mesh_set_threads(mesh, 4097), HOC_ERROR_INVALID_ARGUMENT,
            "threads must be at most 4096");
  ON_HANDLE("set_remove_caps: 2", mesh, 3, hoc_mesh_set_remove_caps(mesh, 2), HOC_ERROR_INVALID_ARGUMENT,
            "remove must be 0 or 1");
  ON_HANDLE("set_retry: 2", mesh, 3, hoc_mesh_set_retry(mesh, 2), HOC_ERROR_INVALID_ARGUMENT,
            "enabled must be 0 or 1");
  ON_HANDLE("set_static_condensation: -1", mesh, 3, hoc_mesh_set_static_condensation(mesh, -1),
            HOC_ERROR_INVALID_ARGUMENT, "enabled must be 0 or 1");
  ON_HANDLE("set_optimize: 2", mesh, 3, hoc_mesh_set_optimize(mesh, 2), HOC_ERROR_INVALID_ARGUMENT,
            "enabled must be 0 or 1");
  ON_HANDLE("set_tangent_first: 2", mesh, 3, hoc_mesh_set_tangent_first(mesh, 2), HOC_ERROR_INVALID_ARGUMENT,
            "enabled must be 0 or 1");
  ON_HANDLE("optimization: NULL out", mesh, 3, hoc_mesh_optimization(mesh, NULL), HOC_ERROR_NULL_POINTER,
            "out is NULL");
  {
    const double fib[3 * 7] = {0};
    ON_HANDLE("set_fibres: 2^40 cells (small buffer)", mesh, 3, hoc_mesh_set_fibres(mesh, big, fib),
              HOC_ERROR_BUFFER_SIZE, "n_cells = 1099511627776, but the mesh was created with 6 cells");
    ON_HANDLE("set_fibres: 7 for 6 cells", mesh, 3, hoc_mesh_set_fibres(mesh, 7, fib), HOC_ERROR_BUFFER_SIZE,
              "created with 6 cells");
    ON_HANDLE("set_fibres: zero vectors", mesh, 3, hoc_mesh_set_fibres(mesh, 6, fib), HOC_ERROR_INVALID_ARGUMENT,
              "fibre direction of cell 0 is zero or not finite");
  }
  CHECK_OK(mesh, hoc_mesh_destroy(&mesh));

  /* ==== runs that fail: the mesh (here already curved once) stays as it was ==== */
  mesh = cube_handle();
  {
    State straight = state(mesh, 3);
    CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
    State curved = state(mesh, 3);
    CHECK(!state_equal(&straight, &curved, 3), "the good run moved nothing");
    state_free(&straight);
    state_free(&curved);
  }
  ON_HANDLE("run: 0 increments", mesh, 3, hoc_mesh_run_increments(mesh, 0), HOC_ERROR_INVALID_ARGUMENT, "increment");
  ON_HANDLE("run: INT_MIN increments", mesh, 3, hoc_mesh_run_increments(mesh, INT32_MIN), HOC_ERROR_INVALID_ARGUMENT,
            "increment");
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, NULL, NULL));
  ON_HANDLE("run: tagged boundary, no projector", mesh, 3, hoc_mesh_run_increments(mesh, 1),
            HOC_ERROR_INVALID_ARGUMENT, "no projector is set");
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_cube, NULL));
  {
    int32_t unknown[12];
    for (int k = 0; k < 12; ++k) unknown[k] = cube_tags[k] == 6 ? 99 : cube_tags[k];
    CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, cube_n_facets, cube_facets, unknown));
    ON_HANDLE("run: entity tag the projector does not know", mesh, 3, hoc_mesh_run_increments(mesh, 1),
              HOC_ERROR_PROJECTION, "tag 99): the projection callback returned 3");
    CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, cube_n_facets, cube_facets, cube_tags));
  }
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_error, NULL));
  ON_HANDLE("run: projector returns an error", mesh, 3, hoc_mesh_run_increments(mesh, 1), HOC_ERROR_PROJECTION,
            "the projection callback returned 7");
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_nan, NULL));
  ON_HANDLE("run: projector returns NaN", mesh, 3, hoc_mesh_run_increments(mesh, 1), HOC_ERROR_PROJECTION,
            "non-finite point");
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_far, NULL));
  ON_HANDLE("run: projector moves points by 1e6", mesh, 3, hoc_mesh_run_increments(mesh, 1), HOC_ERROR_PROJECTION,
            "more than the size of its elements");
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_huge, NULL));
  ON_HANDLE("run: projector returns 1e308", mesh, 3, hoc_mesh_run_increments(mesh, 1), HOC_ERROR_PROJECTION,
            "more than the size of its elements");
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj_cube, NULL));
  CHECK_OK(mesh, hoc_mesh_set_linear_solver(mesh, solver_fails, NULL));
  ON_HANDLE("run: external solver returns -4", mesh, 3, hoc_mesh_run_increments(mesh, 1), HOC_ERROR_SOLVER, "-4");
  CHECK_OK(mesh, hoc_mesh_set_linear_solver(mesh, solver_nan, NULL));
  ON_HANDLE("run: external solver returns NaN", mesh, 3, hoc_mesh_run_increments(mesh, 1), HOC_ERROR_SOLVER,
            "external");
  CHECK_OK(mesh, hoc_mesh_set_linear_solver(mesh, NULL, NULL));
  CHECK_OK(mesh, hoc_mesh_set_progress(mesh, progress_cancel, NULL));
  ON_HANDLE("run: progress callback cancels", mesh, 3, hoc_mesh_run_increments(mesh, 2), HOC_ERROR_CANCELLED,
            "cancelled by the progress callback");
  CHECK_OK(mesh, hoc_mesh_set_progress(mesh, NULL, NULL));
  CHECK_OK(mesh, hoc_mesh_set_formulation(mesh, HOC_FORMULATION_CIL));
  ON_HANDLE("run: CIL with a linear elastic material", mesh, 3, hoc_mesh_run_increments(mesh, 1),
            HOC_ERROR_INVALID_ARGUMENT, "formulation cil needs a hyperelastic material");
  CHECK_OK(mesh, hoc_mesh_set_formulation(mesh, HOC_FORMULATION_ILE));
  ON_HANDLE("write: missing directory", mesh, 3, hoc_mesh_write(mesh, "/nonexistent-hocurve-dir/out.msh"),
            HOC_ERROR_IO, "cannot write /nonexistent-hocurve-dir/out.msh");
  ON_HANDLE("write: unknown extension", mesh, 3, hoc_mesh_write(mesh, "out.xyz"), HOC_ERROR_INVALID_ARGUMENT,
            "must end in .msh or .vtu");
  ON_HANDLE("write: empty path", mesh, 3, hoc_mesh_write(mesh, ""), HOC_ERROR_INVALID_ARGUMENT,
            "must end in .msh or .vtu");

  /* ==== calls in the wrong order ==== */
  {
    /* Buffer sizes taken before set_order, used after it. */
    size_t nn = 0, nc = 0, npc = 0;
    CHECK_OK(mesh, hoc_mesh_set_order(mesh, 1, HOC_SPACING_OPTIMAL));
    CHECK_OK(mesh, hoc_mesh_node_count(mesh, &nn));
    CHECK_OK(mesh, hoc_mesh_cell_count(mesh, &nc, &npc));
    CHECK(nn == 8 && npc == 4, "p = 1: %zu nodes, %zu per cell", nn, npc);
    CHECK_OK(mesh, hoc_mesh_set_order(mesh, 3, HOC_SPACING_OPTIMAL));
    double x[3 * 8];
    int64_t c[6 * 4];
    ON_HANDLE("get_nodes: count from before set_order", mesh, 3, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, nn, x),
              HOC_ERROR_BUFFER_SIZE, "n_nodes = 8, but the mesh has 64");
    ON_HANDLE("get_cells: length from before set_order", mesh, 3,
              hoc_mesh_get_cells(mesh, HOC_ORDERING_GMSH, nc * npc, c), HOC_ERROR_BUFFER_SIZE,
              "len = 24, but the connectivity has 120");
    ON_HANDLE("get_cells: ordering 3", mesh, 3, hoc_mesh_get_cells(mesh, (HocNodeOrdering)3, nc * npc, c),
              HOC_ERROR_INVALID_ARGUMENT, "unknown node ordering 3");
    ON_HANDLE("cell_quality: measure 4", mesh, 3, hoc_mesh_cell_quality(mesh, 4, nc, x), HOC_ERROR_INVALID_ARGUMENT,
              "quality measure must be 1, 2 or 3, got 4");
    /* Order 1 is a valid order: a run curves nothing and succeeds. */
    CHECK_OK(mesh, hoc_mesh_set_order(mesh, 1, HOC_SPACING_OPTIMAL));
    ON_HANDLE("run at order 1 (accepted, nothing moves)", mesh, 3, hoc_mesh_run_increments(mesh, 1), HOC_OK, "");
  }
  CHECK_OK(mesh, hoc_mesh_destroy(&mesh));
  /* A destroyed handle is NULL: every call on it says so. */
  verdict(__LINE__, "run: on a destroyed (NULLed) handle", hoc_mesh_run_increments(mesh, 1), HOC_ERROR_NULL_POINTER,
          NULL, "mesh is NULL");
  verdict(__LINE__, "set_boundary: on a destroyed (NULLed) handle",
          hoc_mesh_set_boundary(mesh, cube_n_facets, cube_facets, cube_tags), HOC_ERROR_NULL_POINTER, NULL,
          "mesh is NULL");
  CHECK(hoc_mesh_destroy(&mesh) == HOC_OK && mesh == NULL, "destroying a NULLed handle failed");
  /* The thread's message ("mesh is NULL" now) is cleared by the next call
   * without a handle that succeeds, a create. */
  CHECK_OK(NULL, hoc_mesh_create(2, 4, sq, 2, sq_cells, &mesh));
  CHECK(strcmp(hoc_mesh_last_error(NULL), "") == 0, "a successful create left the thread message \"%s\"",
        hoc_mesh_last_error(NULL));
  CHECK_OK(mesh, hoc_mesh_destroy(&mesh));

  printf("%d cases: each with its status, message and the mesh unchanged\n", n_cases);
  CHECK(n_cases >= 25, "only %d cases", n_cases);
  return 0;
}
