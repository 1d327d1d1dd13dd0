/* Checks shared by t300-curve-sphere and t301-curve-torus: curve a fixture mesh
 * at order p through the C ABI and verify the result independently. */
#ifndef HOC_CURVE_CHECKS_H
#define HOC_CURVE_CHECKS_H

#include "fixtures.h"
#include "test_common.h"

#include <stdint.h>
#include <time.h>

typedef double (*DistFn)(const double *p);

typedef struct Triple {
  int64_t v[3];
  int32_t tag;
} Triple;

static inline int cmp_triple(const void *a, const void *b) {
  const Triple *x = (const Triple *)a, *y = (const Triple *)b;
  for (int k = 0; k < 3; ++k)
    if (x->v[k] != y->v[k]) return x->v[k] < y->v[k] ? -1 : 1;
  return 0;
}
static inline void sort3(int64_t *v) {
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2 - i; ++j)
      if (v[j] > v[j + 1]) {
        int64_t t = v[j];
        v[j] = v[j + 1];
        v[j + 1] = t;
      }
}

static inline double det3(const double *a, const double *b, const double *c) {
  return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
         a[2] * (b[0] * c[1] - b[1] * c[0]);
}

/* Barycentric coordinates of x in tet (v0..v3). */
static inline void barycentric(const double *v0, const double *v1, const double *v2, const double *v3,
                        const double *x, double *lam) {
  double e1[3], e2[3], e3[3], r[3];
  for (int k = 0; k < 3; ++k) {
    e1[k] = v1[k] - v0[k];
    e2[k] = v2[k] - v0[k];
    e3[k] = v3[k] - v0[k];
    r[k] = x[k] - v0[k];
  }
  double d = det3(e1, e2, e3);
  lam[1] = det3(r, e2, e3) / d;
  lam[2] = det3(e1, r, e3) / d;
  lam[3] = det3(e1, e2, r) / d;
  lam[0] = 1.0 - lam[1] - lam[2] - lam[3];
}

static inline HocMesh *create_fixture_mesh(const FixtureMesh *m, HocProjectFn proj, void *user) {
  HocMesh *mesh = NULL;
  CHECK_OK(NULL, hoc_mesh_create(3, m->n_vertices, m->coords, m->n_cells, m->cells, &mesh));
  CHECK(mesh != NULL, "create gave no handle");
  CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, m->n_facets, m->facets, m->facet_tags));
  CHECK_OK(mesh, hoc_mesh_set_projector(mesh, proj, user));
  return mesh;
}

/* Whether the sorted faces a and b share two vertices (an edge). */
static inline int share_edge(const int64_t *a, const int64_t *b) {
  int n = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) n += a[i] == b[j];
  return n >= 2;
}

/* Marks nodes (of the current straight-sided mesh) lying on a boundary face with tag `tag`.
 * The library may have removed boundary caps (hoc_mesh_set_remove_caps), which turns two
 * fixture facets into two new boundary faces: those are found as faces of one cell only that
 * are not fixture facets, and take the tag of a fixture facet they share an edge with.
 * *n_flipped receives their count. */
static inline size_t mark_surface_nodes(const FixtureMesh *m, int32_t tag, size_t n_cells, size_t npc,
                                 const int64_t *cells, const double *x, size_t n_nodes,
                                 unsigned char *on, size_t *n_boundary) {
  Triple *t = (Triple *)malloc(sizeof(Triple) * (m->n_facets ? m->n_facets : 1));
  for (size_t f = 0; f < m->n_facets; ++f) {
    for (int k = 0; k < 3; ++k) t[f].v[k] = m->facets[3 * f + k];
    sort3(t[f].v);
    t[f].tag = m->facet_tags[f];
  }
  qsort(t, m->n_facets, sizeof(Triple), cmp_triple);
  /* Every face of every cell, sorted, to tell boundary faces (seen once). */
  Triple *all = (Triple *)malloc(sizeof(Triple) * 4 * (n_cells ? n_cells : 1));
  for (size_t c = 0; c < n_cells; ++c)
    for (int omit = 0; omit < 4; ++omit) {
      Triple *k = &all[4 * c + omit];
      int j = 0;
      for (int i = 0; i < 4; ++i)
        if (i != omit) k->v[j++] = cells[c * npc + i];
      sort3(k->v);
    }
  qsort(all, 4 * n_cells, sizeof(Triple), cmp_triple);
  memset(on, 0, n_nodes);
  *n_boundary = 0;
  for (size_t c = 0; c < n_cells; ++c) {
    const int64_t *cell = cells + c * npc;
    for (int omit = 0; omit < 4; ++omit) {
      Triple key;
      int j = 0;
      for (int k = 0; k < 4; ++k)
        if (k != omit) key.v[j++] = cell[k];
      sort3(key.v);
      Triple *hit = (Triple *)bsearch(&key, t, m->n_facets, sizeof(Triple), cmp_triple);
      int32_t face_tag = hit ? hit->tag : -1;
      ++*n_boundary; /* a fixture facet, or (below) a face of this cell only */
      if (!hit) {
        --*n_boundary;
        Triple *same = (Triple *)bsearch(&key, all, 4 * n_cells, sizeof(Triple), cmp_triple);
        size_t k0 = (size_t)(same - all), count = 0;
        while (k0 > 0 && cmp_triple(&all[k0 - 1], &key) == 0) --k0;
        while (k0 + count < 4 * n_cells && cmp_triple(&all[k0 + count], &key) == 0) ++count;
        if (count != 1) continue; /* interior face */
        ++*n_boundary;
        for (size_t f = 0; f < m->n_facets && face_tag < 0; ++f)
          if (share_edge(t[f].v, key.v)) face_tag = t[f].tag;
      }
      if (face_tag != tag) continue;
      for (size_t a = 0; a < npc; ++a) {
        double lam[4];
        barycentric(x + 3 * cell[0], x + 3 * cell[1], x + 3 * cell[2], x + 3 * cell[3],
                    x + 3 * cell[a], lam);
        if (fabs(lam[omit]) < 1e-9) on[cell[a]] = 1;
      }
    }
  }
  free(all);
  free(t);
  size_t count = 0;
  for (size_t i = 0; i < n_nodes; ++i) count += on[i];
  return count;
}

/* Solver settings of a run; a negative value keeps the library's default. */
typedef struct RunSettings {
  int formulation; /* HOC_FORMULATION_* */
  int material;    /* HOC_MATERIAL_*, with E = 1, nu = 0.3 */
  int increments;
  /* Inverted cells are acceptable if the library reports them: n_invalid is then
   * only required to equal the number of cells with Q3 <= 0, and printed. */
  int allow_invalid;
  /* Keep the boundary caps (hoc_mesh_set_remove_caps(mesh, 0)). */
  int keep_caps;
} RunSettings;
static const RunSettings DEFAULT_RUN = {-1, -1, 1, 0, 0};

/* Curves at order p (optimal spacing) and checks: no invalid cell, every node on a
 * `tag` facet is on the surface to 1e-10, boundary vertices did not move. */
static inline void curve_and_check_with(const char *name, const FixtureMesh *m, HocProjectFn proj,
                                        int32_t tag, DistFn dist, int p, RunSettings rs) {
  size_t calls = 0;
  HocMesh *mesh = create_fixture_mesh(m, proj, &calls);
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, p, HOC_SPACING_OPTIMAL));
  if (rs.material >= 0) CHECK_OK(mesh, hoc_mesh_set_material(mesh, (HocMaterial)rs.material, 1.0, 0.3));
  if (rs.formulation >= 0) CHECK_OK(mesh, hoc_mesh_set_formulation(mesh, (HocFormulation)rs.formulation));
  /* Every cell as given: no caps removed, no repair (which would flip the kept caps). */
  if (rs.keep_caps) {
    CHECK_OK(mesh, hoc_mesh_set_remove_caps(mesh, 0));
    CHECK_OK(mesh, hoc_mesh_set_repair(mesh, 0));
  }
  /* Invalid cells reported rather than rescued: adaptive stepping would fail at
   * its limit on cells that no step keeps valid (kept caps). */
  if (rs.allow_invalid) CHECK_OK(mesh, hoc_mesh_set_adaptive_stepping(mesh, 0, 6));
  size_t n_nodes = 0, n_cells = 0, npc = 0;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n_nodes));
  CHECK_OK(mesh, hoc_mesh_cell_count(mesh, &n_cells, &npc));
  CHECK(n_cells <= m->n_cells, "cell count %zu, more than the %zu given", n_cells, m->n_cells);
  CHECK(npc == (size_t)((p + 1) * (p + 2) * (p + 3) / 6), "nodes per cell %zu at p=%d", npc, p);
  /* The cells are the input cells in order, less the boundary caps removed. */
  int64_t *input_cells = (int64_t *)malloc(sizeof(int64_t) * (n_cells ? n_cells : 1));
  CHECK_OK(mesh, hoc_mesh_get_input_cells(mesh, n_cells, input_cells));
  for (size_t c = 0; c < n_cells; ++c) {
    CHECK(input_cells[c] >= 0 && (size_t)input_cells[c] < m->n_cells, "input cell %lld", (long long)input_cells[c]);
    CHECK(c == 0 || input_cells[c] > input_cells[c - 1], "input cells are not increasing at %zu", c);
  }
  free(input_cells);
  size_t removed_caps = m->n_cells - n_cells;
  double *x0 = (double *)malloc(sizeof(double) * 3 * n_nodes);
  double *x = (double *)malloc(sizeof(double) * 3 * n_nodes);
  int64_t *cells = (int64_t *)malloc(sizeof(int64_t) * n_cells * npc);
  unsigned char *on = (unsigned char *)malloc(n_nodes);
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x0));
  CHECK_OK(mesh, hoc_mesh_get_cells(mesh, HOC_ORDERING_NATIVE, n_cells * npc, cells));
  for (size_t v = 0; v < m->n_vertices; ++v)
    for (int k = 0; k < 3; ++k)
      CHECK(x0[3 * v + k] == m->coords[3 * v + k], "node %zu is not vertex %zu before the run", v, v);
  size_t n_boundary = 0;
  size_t n_on = mark_surface_nodes(m, tag, n_cells, npc, cells, x0, n_nodes, on, &n_boundary);
  /* Removing a cap replaces two boundary faces by two. */
  CHECK(n_boundary == m->n_facets, "%zu boundary faces, %zu given (%zu caps removed)", n_boundary, m->n_facets,
        removed_caps);
  double before = 0.0;
  for (size_t i = 0; i < n_nodes; ++i)
    if (on[i]) before = fmax(before, dist(x0 + 3 * i));

  clock_t t0 = clock();
  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, rs.increments > 0 ? rs.increments : 1));
  double secs = (double)(clock() - t0) / CLOCKS_PER_SEC;
  CHECK(calls > 0, "the projector was never called");

  HocQuality q;
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
  CHECK(q.n_cells == n_cells, "quality counts %zu cells", q.n_cells);
  /* The certified bound holds over whole elements, so it can only be below the sampled one. */
  CHECK(q.certified_min_q3 <= q.min_q3 + 1e-12, "p=%d: certified min Q3 %g above sampled %g", p,
        q.certified_min_q3, q.min_q3);
  CHECK(q.n_certified_invalid + q.n_uncertain >= q.n_invalid, "p=%d: %zu certified invalid, %zu uncertain < %zu sampled",
        p, q.n_certified_invalid, q.n_uncertain, q.n_invalid);
  /* The optimisation stage reports what it did and agrees with the quality. */
  HocOptimization o;
  CHECK_OK(mesh, hoc_mesh_optimization(mesh, &o));
  CHECK(o.invalid_after <= o.invalid_before, "p=%d: optimisation %zu -> %zu invalid cells", p, o.invalid_before,
        o.invalid_after);
  CHECK(fabs(o.min_q3_after - q.min_q3) < 1e-12, "p=%d: optimisation reports min Q3 %g, quality %g", p,
        o.min_q3_after, q.min_q3);
  CHECK(o.ran ? (o.invalid_before > 0 || o.min_q3_after >= o.min_q3_before) : o.cells_touched == 0,
        "p=%d: optimisation min Q3 %g -> %g", p, o.min_q3_before, o.min_q3_after);
  CHECK(o.elastic_load > 0 && o.elastic_load <= 1 && (o.elastic_stopped || o.elastic_load == 1),
        "p=%d: elastic stage reached load %g (stopped %d)", p, o.elastic_load, o.elastic_stopped);
  if (!rs.allow_invalid) {
    CHECK(q.n_invalid == 0, "p=%d: %zu invalid cells (min Q3 %g)", p, q.n_invalid, q.min_q3);
    CHECK(q.n_certified_invalid == 0 && q.n_uncertain == 0, "p=%d: certified: %zu invalid, %zu uncertain", p,
          q.n_certified_invalid, q.n_uncertain);
    CHECK(q.certified_min_q3 > 0, "p=%d: certified min Q3 %g", p, q.certified_min_q3);
    CHECK(q.min_q3 > 0 && q.min_q3 <= 1, "p=%d: min Q3 %g", p, q.min_q3);
  } else {
    CHECK(q.min_q3 <= 1, "p=%d: min Q3 %g", p, q.min_q3);
    CHECK((q.n_invalid == 0) == (q.min_q3 > 0), "p=%d: %zu invalid cells, but min Q3 %g", p, q.n_invalid,
          q.min_q3);
  }

  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x));
  double after = 0.0, vmove = 0.0;
  for (size_t i = 0; i < n_nodes; ++i)
    if (on[i]) {
      after = fmax(after, dist(x + 3 * i));
      if (i < m->n_vertices)
        for (int k = 0; k < 3; ++k) vmove = fmax(vmove, fabs(x[3 * i + k] - x0[3 * i + k]));
    }
  CHECK(after < 1e-10, "p=%d: a surface node is %g off the surface", p, after);
  CHECK(vmove < 1e-14, "p=%d: a surface vertex moved by %g", p, vmove);
  /* Quality per cell agrees with the summary. */
  double *q3 = (double *)malloc(sizeof(double) * n_cells);
  CHECK_OK(mesh, hoc_mesh_cell_quality(mesh, 3, n_cells, q3));
  double qmin = 1.0;
  size_t q3_nonpositive = 0;
  for (size_t c = 0; c < n_cells; ++c) {
    qmin = fmin(qmin, q3[c]);
    q3_nonpositive += !(q3[c] > 0);
  }
  CHECK(qmin == q.min_q3, "min of cell Q3 %g != summary %g", qmin, q.min_q3);
  CHECK(q3_nonpositive == q.n_invalid, "p=%d: %zu cells with Q3 <= 0, but n_invalid = %zu", p,
        q3_nonpositive, q.n_invalid);
  printf("%s p=%d (formulation %d, material %d, %d increment(s)): %zu cells (%zu reported invalid), "
         "%zu caps removed, %zu nodes, %zu on the surface (off by %.2e straight, %.2e curved), min Q1 %.3f Q2 %.3f "
         "Q3 %.3f (certified >= %.3f) mean Q3 %.3f, %.2f s CPU\n",
         name, p, rs.formulation, rs.material, rs.increments, n_cells, q.n_invalid, removed_caps, n_nodes, n_on, before, after, q.min_q1, q.min_q2, q.min_q3, q.certified_min_q3, q.mean_q3,
         secs);
  free(q3);
  free(on);
  free(cells);
  free(x);
  free(x0);
  CHECK_OK(NULL, hoc_mesh_destroy(&mesh));
  CHECK(mesh == NULL, "destroy did not clear the handle");
}

static inline void curve_and_check(const char *name, const FixtureMesh *m, HocProjectFn proj, int32_t tag,
                                   DistFn dist, int p) {
  curve_and_check_with(name, m, proj, tag, dist, p, DEFAULT_RUN);
}

/* Quadratic tet in gmsh order: vertices 0..3, edges 01, 12, 20, 30, 32, 31. */
static const int GMSH_TET10_EDGES[6][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 0}, {3, 2}, {3, 1}};
/* VTK_QUADRATIC_TETRA / VTK_LAGRANGE_TETRAHEDRON p=2: edges 01, 12, 02, 03, 13, 23. */
static const int VTK_TET10_EDGES[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};

/* Checks a p=2 equispaced straight mesh in an ordering: edge nodes at the midpoints. */
static inline void check_p2_ordering(const char *name, size_t n_cells, const int64_t *cells, const double *x,
                              const int edges[6][2]) {
  double worst = 0.0;
  for (size_t c = 0; c < n_cells; ++c) {
    const int64_t *cell = cells + 10 * c;
    for (int e = 0; e < 6; ++e)
      for (int k = 0; k < 3; ++k) {
        double mid = 0.5 * (x[3 * cell[edges[e][0]] + k] + x[3 * cell[edges[e][1]] + k]);
        worst = fmax(worst, fabs(mid - x[3 * cell[4 + e] + k]));
      }
  }
  CHECK(worst < 1e-12, "%s p=2 ordering: an edge node is %g from its edge's midpoint", name, worst);
}

/* Independent check of validity at p=2: det J of the quadratic map at the 35
 * points of the degree-4 barycentric lattice (vertices included) of every cell,
 * compared with the library's verdict: hoc_mesh_quality must count at least the
 * cells found here with det J <= 0, and none if none is found here. With
 * require_valid, a cell with det J <= 0 also fails the test. Returns the number
 * of cells found with det J <= 0. */
static inline size_t jacobian_check_p2(const char *name, const FixtureMesh *m, HocProjectFn proj,
                                       int require_valid) {
  HocMesh *mesh = create_fixture_mesh(m, proj, NULL);
  CHECK_OK(mesh, hoc_mesh_set_order(mesh, 2, HOC_SPACING_EQUISPACED));
  size_t n_nodes = 0, n_cells = 0, npc = 0;
  CHECK_OK(mesh, hoc_mesh_node_count(mesh, &n_nodes));
  CHECK_OK(mesh, hoc_mesh_cell_count(mesh, &n_cells, &npc));
  CHECK(npc == 10, "p=2 tet has %zu nodes", npc);
  double *x = (double *)malloc(sizeof(double) * 3 * n_nodes);
  int64_t *cells = (int64_t *)malloc(sizeof(int64_t) * n_cells * 10);
  /* Before the run: the orderings put edge nodes where gmsh and VTK expect them. */
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x));
  CHECK_OK(mesh, hoc_mesh_get_cells(mesh, HOC_ORDERING_VTK, n_cells * 10, cells));
  check_p2_ordering("vtk", n_cells, cells, x, VTK_TET10_EDGES);
  CHECK_OK(mesh, hoc_mesh_get_cells(mesh, HOC_ORDERING_GMSH, n_cells * 10, cells));
  check_p2_ordering("gmsh", n_cells, cells, x, GMSH_TET10_EDGES);

  CHECK_OK(mesh, hoc_mesh_run_increments(mesh, 1));
  CHECK_OK(mesh, hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x));
  CHECK_OK(mesh, hoc_mesh_get_cells(mesh, HOC_ORDERING_GMSH, n_cells * 10, cells));
  static const double dL[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  double *q3 = (double *)malloc(sizeof(double) * n_cells);
  CHECK_OK(mesh, hoc_mesh_cell_quality(mesh, 3, n_cells, q3));
  HocQuality q;
  CHECK_OK(mesh, hoc_mesh_quality(mesh, &q));
  double worst = 1.0;
  size_t points = 0, n_bad = 0, n_bad_lib_q3 = 0;
  for (size_t c = 0; c < n_cells; ++c) {
    const int64_t *cell = cells + 10 * c;
    double jmin = INFINITY, jmax = 0.0, Lmin[4] = {0};
    for (int i = 0; i <= 4; ++i)
      for (int j = 0; i + j <= 4; ++j)
        for (int k = 0; i + j + k <= 4; ++k) {
          double L[4] = {(4 - i - j - k) / 4.0, i / 4.0, j / 4.0, k / 4.0};
          double dN[10][4] = {{0}}; /* dN/dL_l */
          for (int v = 0; v < 4; ++v) dN[v][v] = 4 * L[v] - 1;
          for (int ed = 0; ed < 6; ++ed) {
            int a = GMSH_TET10_EDGES[ed][0], b = GMSH_TET10_EDGES[ed][1];
            dN[4 + ed][a] = 4 * L[b];
            dN[4 + ed][b] = 4 * L[a];
          }
          double J[3][3] = {{0}}; /* J[r][s] = dx_r / dxi_s */
          for (int nd = 0; nd < 10; ++nd)
            for (int s = 0; s < 3; ++s) {
              double g = 0;
              for (int l = 0; l < 4; ++l) g += dN[nd][l] * dL[l][s];
              for (int r = 0; r < 3; ++r) J[r][s] += x[3 * cell[nd] + r] * g;
            }
          double cols[3][3];
          for (int s = 0; s < 3; ++s)
            for (int r = 0; r < 3; ++r) cols[s][r] = J[r][s];
          double d = det3(cols[0], cols[1], cols[2]);
          if (d < jmin) {
            jmin = d;
            memcpy(Lmin, L, sizeof L);
          }
          jmax = fmax(jmax, fabs(d));
          ++points;
        }
    if (!(jmin > 0)) {
      ++n_bad;
      n_bad_lib_q3 += !(q3[c] > 0);
      fprintf(require_valid ? stderr : stdout,
              "%s p=2: cell %zu has det J = %g (max |det J| %g) at barycentric (%g %g %g %g); "
              "the library's Q3 for the cell is %g\n",
              name, c, jmin, jmax, Lmin[0], Lmin[1], Lmin[2], Lmin[3], q3[c]);
    }
    worst = fmin(worst, jmin / jmax);
  }
  printf("%s p=2 independent check: %zu of %zu cells with det J <= 0 at some of the %zu lattice "
         "points (35 per cell), min det J / max det J per cell = %.3f; the library reports %zu "
         "invalid cells (min Q3 %g), and Q3 <= 0 for %zu of the %zu; gmsh and vtk edge nodes at "
         "midpoints\n",
         name, n_bad, n_cells, points, worst, q.n_invalid, q.min_q3, n_bad_lib_q3, n_bad);
  CHECK(q.n_invalid >= n_bad,
        "%s p=2: the library reports %zu invalid cells, the independent check finds %zu", name,
        q.n_invalid, n_bad);
  CHECK(n_bad > 0 || q.n_invalid == 0,
        "%s p=2: the library reports %zu invalid cells, the independent check finds none", name,
        q.n_invalid);
  CHECK(!require_valid || n_bad == 0, "%s p=2: %zu cells with det J <= 0", name, n_bad);
  free(q3);
  free(cells);
  free(x);
  CHECK_OK(NULL, hoc_mesh_destroy(&mesh));
  return n_bad;
}

#endif
